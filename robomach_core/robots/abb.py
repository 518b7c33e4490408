"""ABB arms from their published kinematics: IRB 4400/60, IRB 2400/16 and IRB 6640-185/2.80.

PROBLEM   example-robot-data ships no ABB arm, yet the chapter's deburring cell is an IRB 4400
          and the export is RAPID, whose confdata only means something on the arm's own axes.
STRATEGY  Every ABB 6-axis arm here has the same serial structure (ABB's axis zeros: upper arm
          vertical, forearm horizontal, wrist straight ahead; tool0 x down, z forward):

              axis 1 about z at height ``base_height``,
              axis 2 about y at (``shoulder_x``, ``shoulder_z``) from axis 1,
              axis 3 about y ``upper_arm`` above axis 2,
              axis 4 about x ``elbow_offset`` above axis 3,
              axis 5 about y ``forearm`` ahead of axis 4 (the wrist centre),
              axis 6 about x at the wrist centre, tool0 ``flange`` ahead, rotated +90 deg about y.

          The numbers are the joint origins, axes and limits of ROS-Industrial's support
          packages (github.com/ros-industrial/abb: ``abb_irb4400_support/urdf/
          irb4400_macro.xacro``, ``abb_irb2400_support/urdf/irb2400_macro.xacro`` and
          ``abb_irb6640_support/urdf/irb6640_185_280_macro.xacro``), whose joint zeros and
          positive directions are the controller's (its abb_driver passes joint angles through
          unchanged, but for the coupled axis 3 below), and whose limits follow ABB's product
          specifications (IRB 4400: axis 1 +-165, 2 -70/+96, 3 -60/+65, 4 +-200, 5 +-120,
          6 +-400 deg; IRB 2400: 1 +-180, 2 -100/+110, 3 -60/+65, 4 +-200, 5 +-120, 6 +-400 deg;
          IRB 6640: 1 +-170, 2 -65/+85, 3 -180/+70, 4 +-300, 5 +-120, 6 +-360 deg). The IRB
          2400's axis 4 sits 0.258 m along the forearm from axis 3 (it turns about the
          forearm, so only the 0.755 m to the wrist centre counts). Their meshes are not used:
          boxes and cylinders draw the links.
SOLUTION  ``ABB_ARMS`` (name -> ``ArmSpec``), ``urdf_text(spec)`` (a URDF that pinocchio and
          yourdfpy load), ``urdf_path(name)`` (that URDF written once into a cache folder) and
          ``controller_axes_deg`` (the joint values the ABB controller shows).

The IRB 4400 and IRB 2400 are parallel-bar arms: the controller measures axis 3 from the
horizontal, so ABB's axis 3 = q2 + q3 of this serial model (abb_driver's ``J23_coupled``); the
zeros agree. ABB's axis-3 range applies to that controller value, which makes it a combined
limit on axes 2 and 3 of the serial model (``ArmSpec.axis3_from_horizontal_deg``, enforced by
``Robot`` and supervision); the serial elbow angle q3 keeps the range ROS-Industrial gives its
joint_3. ABB does not publish the parallelogram's own coupled bounds (its MOC.cfg), so this
range on the serial joint stands for them.

No IRB 6400 is built: its kinematics are not published in ROS-Industrial's packages (the
former ``abb_common`` "irb6400" model was an IRB 6640 and was replaced by
``abb_irb6640_support``), and the chapter's DH table did not survive in our copy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._urdf import FLANGE_FRAME, arm_urdf, cached_urdf, spec_by_name
from ._urdf import box as _box
from ._urdf import cylinder as _cylinder
from ._urdf import visual as _visual

ABB_ORANGE_RGBA = "1 0.43 0 1"
GRAPHITE_RGBA = "0.3 0.3 0.3 1"


@dataclass(frozen=True)
class ArmSpec:
    """Kinematics of one ABB arm (metres, degrees), see the module docstring for the chain.

    Attributes:
        name: Key used everywhere a robot is chosen (``"irb4400"``).
        title: ABB's product name.
        base_height_m: Height of axis 1's frame above the base (the floor).
        shoulder_m: (x, z) of axis 2 from axis 1's frame.
        upper_arm_m: Axis 2 to axis 3 (the lower arm, in ABB's words).
        elbow_offset_m: Axis 3 to the forearm's axis 4, along z at the zero pose.
        forearm_m: Axis 3 to the wrist centre (axis 5) along x at the zero pose.
        flange_m: Wrist centre to the mounting flange (tool0).
        lower_deg, upper_deg: (6,) axis working ranges.
        velocity_deg_s: (6,) axis speed limits.
        j23_coupled: The controller's axis 3 is measured from the horizontal (parallel bar).
        link_radius_m: Half-thickness of the drawn links (display and collision only).
        axis3_from_horizontal_deg: On a parallel-bar arm, ABB's axis-3 range, which applies to
            the controller's axis 3 = q2 + q3 (the combined axis-2/3 limit); None otherwise.
    """

    name: str
    title: str
    base_height_m: float
    shoulder_m: tuple[float, float]
    upper_arm_m: float
    elbow_offset_m: float
    forearm_m: float
    flange_m: float
    lower_deg: tuple[float, ...]
    upper_deg: tuple[float, ...]
    velocity_deg_s: tuple[float, ...]
    j23_coupled: bool
    link_radius_m: float
    axis3_from_horizontal_deg: tuple[float, float] | None = None


IRB4400 = ArmSpec(
    name="irb4400",
    title="ABB IRB 4400/60",
    base_height_m=0.0,
    shoulder_m=(0.200, 0.680),
    upper_arm_m=0.890,
    elbow_offset_m=0.150,
    forearm_m=0.880,
    flange_m=0.140,
    lower_deg=(-165.0, -70.0, -60.0, -200.0, -120.0, -400.0),
    upper_deg=(165.0, 96.0, 65.0, 200.0, 120.0, 400.0),
    velocity_deg_s=(150.0, 120.0, 120.0, 225.0, 135.4, 330.0),
    j23_coupled=True,
    link_radius_m=0.09,
    axis3_from_horizontal_deg=(-60.0, 65.0),
)

# The Lund papers' arm (S4CPlus): IRB 2400/16, 1.55 m reach.
IRB2400 = ArmSpec(
    name="irb2400",
    title="ABB IRB 2400/16",
    base_height_m=0.0,
    shoulder_m=(0.100, 0.615),
    upper_arm_m=0.705,
    elbow_offset_m=0.135,
    forearm_m=0.755,
    flange_m=0.085,
    lower_deg=(-180.0, -100.0, -60.0, -200.0, -120.0, -400.0),
    upper_deg=(180.0, 110.0, 65.0, 200.0, 120.0, 400.0),
    velocity_deg_s=(150.0, 150.0, 150.0, 360.0, 360.0, 450.0),
    j23_coupled=True,
    link_radius_m=0.06,
    axis3_from_horizontal_deg=(-60.0, 65.0),
)

IRB6640 = ArmSpec(
    name="irb6640",
    title="ABB IRB 6640-185/2.80",
    base_height_m=0.780,
    shoulder_m=(0.320, 0.0),
    upper_arm_m=1.075,
    elbow_offset_m=0.200,
    forearm_m=1.392,
    flange_m=0.200,
    lower_deg=(-170.0, -65.0, -180.0, -300.0, -120.0, -360.0),
    upper_deg=(170.0, 85.0, 70.0, 300.0, 120.0, 360.0),
    velocity_deg_s=(100.0, 90.0, 90.0, 170.0, 140.0, 190.0),
    j23_coupled=False,
    link_radius_m=0.13,
)

ABB_ARMS: dict[str, ArmSpec] = {arm.name: arm for arm in (IRB4400, IRB2400, IRB6640)}


def arm_spec(name: str) -> ArmSpec:
    """The ``ArmSpec`` of an ABB arm by name."""
    return spec_by_name(ABB_ARMS, name, "ABB")


def urdf_text(spec: ArmSpec) -> str:
    """A URDF of the arm: the kinematic chain of the module docstring, boxes and cylinders.

    Links ``base_link``, ``link_1`` .. ``link_6``, ``tool0``; joints ``joint_1`` .. ``joint_6``
    (revolute, limits in rad and rad/s), as ROS-Industrial names them.
    """
    r = spec.link_radius_m
    sx, sz = spec.shoulder_m
    half_pi = math.pi / 2
    along_x = (0.0, half_pi, 0.0)  # a cylinder's axis is its z: turn it onto x
    along_y = (half_pi, 0.0, 0.0)
    links = {
        "base_link": _visual(
            _cylinder(1.6 * r, max(spec.base_height_m, 0.2)),
            (0.0, 0.0, max(spec.base_height_m, 0.2) / 2),
            (0.0, 0.0, 0.0),
            GRAPHITE_RGBA,
        ),
        "link_1": _visual(
            _box((sx + 2 * r, 2.4 * r, max(sz, 2 * r))),
            (sx / 2, 0.0, max(sz, 2 * r) / 2),
            (0.0, 0.0, 0.0),
            ABB_ORANGE_RGBA,
        ),
        "link_2": _visual(
            _box((1.4 * r, 1.4 * r, spec.upper_arm_m)),
            (0.0, 0.0, spec.upper_arm_m / 2),
            (0.0, 0.0, 0.0),
            ABB_ORANGE_RGBA,
        )
        + _visual(_cylinder(r, 2.2 * r), (0.0, 0.0, 0.0), along_y, ABB_ORANGE_RGBA),
        "link_3": _visual(
            _box((2 * r, 1.6 * r, spec.elbow_offset_m + r)),
            (0.0, 0.0, (spec.elbow_offset_m + r) / 2 - r / 2),
            (0.0, 0.0, 0.0),
            ABB_ORANGE_RGBA,
        ),
        "link_4": _visual(
            _cylinder(0.6 * r, spec.forearm_m - r),
            ((spec.forearm_m - r) / 2, 0.0, 0.0),
            along_x,
            ABB_ORANGE_RGBA,
        ),
        "link_5": _visual(_cylinder(0.6 * r, 1.3 * r), (0.0, 0.0, 0.0), along_y, ABB_ORANGE_RGBA),
        "link_6": _visual(
            _cylinder(0.4 * r, spec.flange_m),
            (spec.flange_m / 2, 0.0, 0.0),
            along_x,
            GRAPHITE_RGBA,
        ),
        FLANGE_FRAME: "",
    }
    origins = [
        (0.0, 0.0, spec.base_height_m),
        (sx, 0.0, sz),
        (0.0, 0.0, spec.upper_arm_m),
        (0.0, 0.0, spec.elbow_offset_m),
        (spec.forearm_m, 0.0, 0.0),
        (0.0, 0.0, 0.0),
    ]
    axes = ("0 0 1", "0 1 0", "0 1 0", "1 0 0", "0 1 0", "1 0 0")
    return arm_urdf(spec, "abb.py", links, "joint_", origins, axes, (spec.flange_m, 0.0, 0.0))


def urdf_path(name: str) -> Path:
    """The arm's URDF as a file (written at first use; the name holds a hash of the content)."""
    return cached_urdf(name, urdf_text(arm_spec(name)))


def controller_axes_deg(name: str, joints_rad: np.ndarray) -> np.ndarray:
    """The axis values [deg] the ABB controller shows for model joints ``joints_rad`` (6,).

    Equal to the model's joints except on parallel-bar arms (``j23_coupled``), whose axis 3 is
    the forearm's angle from the horizontal: axis 3 = q2 + q3.
    """
    q = np.degrees(np.asarray(joints_rad, dtype=float)).copy()
    if arm_spec(name).j23_coupled:
        q[..., 2] += q[..., 1]
    return q
