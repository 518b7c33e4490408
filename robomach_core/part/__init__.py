"""The part: the workpiece's geometry and where it sits, what the cell really holds, and the
queries and checks of its mesh.

``workpiece`` builds the built-in parts (the water pump, the block, the S-groove) from their
planar ``contour`` and reads the user's mesh files through ``mesh_check``; ``real_part`` puts a
fixture error and casting deviations between the CAD and the part in the cell; ``mesh_query``
answers closest-point and ray queries on a mesh and ``bvh`` builds coal's hierarchy of it.
"""

from .bvh import bvh_from_mesh as bvh_from_mesh
from .contour import Arc as Arc
from .contour import Contour as Contour
from .contour import Line as Line
from .real_part import PartDeviation as PartDeviation
from .real_part import real_workpiece as real_workpiece
from .workpiece import MAX_MESH_BYTES as MAX_MESH_BYTES
from .workpiece import MAX_MESH_TRIANGLES as MAX_MESH_TRIANGLES
from .workpiece import MESH_SUFFIXES as MESH_SUFFIXES
from .workpiece import WORKPIECE_NAMES as WORKPIECE_NAMES
from .workpiece import Workpiece as Workpiece
from .workpiece import builtin_workpiece as builtin_workpiece
from .workpiece import count_mesh_triangles as count_mesh_triangles
from .workpiece import default_T_base_wobj as default_T_base_wobj
from .workpiece import mesh_from_bytes as mesh_from_bytes
from .workpiece import water_pump_wall as water_pump_wall

__all__ = [
    "MAX_MESH_BYTES",
    "MAX_MESH_TRIANGLES",
    "MESH_SUFFIXES",
    "WORKPIECE_NAMES",
    "Arc",
    "Contour",
    "Line",
    "PartDeviation",
    "Workpiece",
    "builtin_workpiece",
    "bvh_from_mesh",
    "count_mesh_triangles",
    "default_T_base_wobj",
    "mesh_from_bytes",
    "real_workpiece",
    "water_pump_wall",
]
