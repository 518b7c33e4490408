"""KUKA arms from their published kinematics: the compliance paper's KR 270 R2700.

PROBLEM   The compliance-error paper milled with a KUKA KR 270, and a KUKA cell runs KRL: its
          E6POS points carry Status and Turn, which only mean something on the arm's own axes
          (A1-A6, KUKA's zeros and directions).
STRATEGY  The chain is ROS-Industrial's ``kuka_kr270_support/urdf/kr270r2700_macro.xacro``
          (github.com/ros-industrial/kuka_experimental, commit 06b4e52): only its joint
          origins, axes, limits and speed limits are used (its meshes are not; cylinders and
          boxes draw the links):

              A1 about -z at 0.675 m above the base,
              A2 about y, 0.350 m ahead of A1 (zero: the rocker, i.e. upper arm, horizontal),
              A3 about y, 1.150 m along the upper arm,
              A4 about -x, 1.200 m along the forearm and 0.041 m below its line,
              A5 about y at the wrist root point, A6 about -x 0.240 m ahead (the flange),
              tool0 (KUKA's $FLANGE) rotated +90 deg about y: z out of the flange, x down.

          Those signs and zeros are KUKA's: the package's RSI driver (``kuka_rsi_hw_interface``)
          converts the controller's axis values to joint values with deg -> rad only, so the
          model's joints are A1-A6 as the pendant shows them (home A2 = -90, A3 = +90: upper
          arm up, forearm level; positive A1 turns the arm clockwise seen from above). Limits
          and speeds (A1 +-170, A2 -195/+40, A3 -115/+150, A4 +-185, A5 +-120, A6 +-350 deg;
          105, 101, 107, 122, 113, 175 deg/s) are the package's.
SOLUTION  ``KUKA_ARMS`` (name -> ``KukaArmSpec``), ``urdf_text``, ``urdf_path`` and the
          Status/Turn of a joint solution (``status_bits``, ``turn_bits``), as KUKA defines
          them (the controller's axis values are the model's joints in degrees:
          ``builtin.controller_axes_deg``):

- Status bit 0: the wrist root point (intersection of the wrist axes), expressed in the A1
  coordinate system (``$ROBROOT`` turned with A1), has a negative x: the overhead area (1),
  else the basic area (0) (KUKA System Software expert programming, "Status", quoted in
  robot-forum.com thread 7173);
- bit 1: A3 >= phi (1), with phi the A3 angle at which the wrist root point lies on the line
  through A2 and A3, which depends on the arm's A3-A4 offset (here -1.96 deg); the ISG
  kernel documentation words it as "the wrist in front of the straight line through axes A2
  and A3" (isg-stuttgart.de, kernel "Status & Turn (IS, IT)");
- bit 2: A5 <= 0 (1), else 0 (KSS 8 Status table);
- Turn: bit i - 1 set when axis Ai < 0 deg (A1 -> 1, ..., A6 -> 32) (same sources).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._urdf import FLANGE_FRAME, arm_urdf, box, cached_urdf, cylinder, spec_by_name, visual

KUKA_ORANGE_RGBA = "1 0.35 0 1"
GRAPHITE_RGBA = "0.25 0.25 0.25 1"


@dataclass(frozen=True)
class KukaArmSpec:
    """Kinematics of one KUKA arm (metres, degrees), see the module docstring for the chain.

    Attributes:
        name: Key used everywhere a robot is chosen (``"kr270"``).
        title: KUKA's product name.
        base_height_m: A2's height above the base (A1's frame).
        shoulder_x_m: A2 ahead of A1.
        upper_arm_m: A2 to A3 along the upper arm (x at A2 = 0).
        forearm_m: A3 to the wrist root point along the forearm.
        elbow_offset_m: The wrist root point's offset from the forearm's line, along z at the
            zero pose (negative: below).
        flange_m: Wrist root point to the flange.
        lower_deg, upper_deg: (6,) axis ranges.
        velocity_deg_s: (6,) axis speed limits.
        link_radius_m: Half-thickness of the drawn links (display only).
    """

    name: str
    title: str
    base_height_m: float
    shoulder_x_m: float
    upper_arm_m: float
    forearm_m: float
    elbow_offset_m: float
    flange_m: float
    lower_deg: tuple[float, ...]
    upper_deg: tuple[float, ...]
    velocity_deg_s: tuple[float, ...]
    link_radius_m: float

    @property
    def status_phi_deg(self) -> float:
        """phi of Status bit 1: the A3 angle putting the wrist root point on the A2-A3 line."""
        return math.degrees(math.atan2(self.elbow_offset_m, self.forearm_m))


KR270 = KukaArmSpec(
    name="kr270",
    title="KUKA KR 270 R2700",
    base_height_m=0.675,
    shoulder_x_m=0.350,
    upper_arm_m=1.150,
    forearm_m=1.200,
    elbow_offset_m=-0.041,
    flange_m=0.240,
    lower_deg=(-170.0, -195.0, -115.0, -185.0, -120.0, -350.0),
    upper_deg=(170.0, 40.0, 150.0, 185.0, 120.0, 350.0),
    velocity_deg_s=(105.0, 101.0, 107.0, 122.0, 113.0, 175.0),
    link_radius_m=0.13,
)

KUKA_ARMS: dict[str, KukaArmSpec] = {arm.name: arm for arm in (KR270,)}
# (origin in the parent link, axis) of A1..A6, as the xacro gives them
_AXES = ("0 0 -1", "0 1 0", "0 1 0", "-1 0 0", "0 1 0", "-1 0 0")


def arm_spec(name: str) -> KukaArmSpec:
    """The ``KukaArmSpec`` of a KUKA arm by name."""
    return spec_by_name(KUKA_ARMS, name, "KUKA")


def _origins(spec: KukaArmSpec) -> list[tuple[float, float, float]]:
    return [
        (0.0, 0.0, spec.base_height_m),
        (spec.shoulder_x_m, 0.0, 0.0),
        (spec.upper_arm_m, 0.0, 0.0),
        (spec.forearm_m, 0.0, spec.elbow_offset_m),
        (0.0, 0.0, 0.0),
        (spec.flange_m, 0.0, 0.0),
    ]


def urdf_text(spec: KukaArmSpec) -> str:
    """A URDF of the arm: links ``base_link``, ``link_1`` .. ``link_6``, ``tool0``; joints
    ``joint_a1`` .. ``joint_a6`` (revolute, limits in rad and rad/s), as ROS-Industrial names
    them; cylinders and boxes for the links."""
    r = spec.link_radius_m
    half_pi = math.pi / 2
    along_x = (0.0, half_pi, 0.0)
    along_y = (half_pi, 0.0, 0.0)
    h, sx = spec.base_height_m, spec.shoulder_x_m
    links = {
        "base_link": visual(
            cylinder(1.5 * r, 0.45 * h), (0.0, 0.0, 0.225 * h), (0.0, 0.0, 0.0), GRAPHITE_RGBA
        ),
        "link_1": visual(
            box((sx + 2 * r, 2.2 * r, 0.55 * h)),
            (sx / 2, 0.0, -0.275 * h + r),
            (0.0, 0.0, 0.0),
            KUKA_ORANGE_RGBA,
        ),
        "link_2": visual(
            box((spec.upper_arm_m, 1.2 * r, 1.6 * r)),
            (spec.upper_arm_m / 2, 0.0, 0.0),
            (0.0, 0.0, 0.0),
            KUKA_ORANGE_RGBA,
        )
        + visual(cylinder(r, 2.4 * r), (0.0, 0.0, 0.0), along_y, KUKA_ORANGE_RGBA),
        "link_3": visual(cylinder(0.9 * r, 2.0 * r), (0.0, 0.0, 0.0), along_y, KUKA_ORANGE_RGBA)
        + visual(
            cylinder(0.55 * r, spec.forearm_m - r),
            ((spec.forearm_m - r) / 2, 0.0, spec.elbow_offset_m),
            along_x,
            KUKA_ORANGE_RGBA,
        ),
        "link_4": visual(cylinder(0.5 * r, 1.2 * r), (0.0, 0.0, 0.0), along_y, KUKA_ORANGE_RGBA),
        "link_5": visual(
            cylinder(0.35 * r, spec.flange_m),
            (spec.flange_m / 2, 0.0, 0.0),
            along_x,
            KUKA_ORANGE_RGBA,
        ),
        "link_6": visual(cylinder(0.5 * r, 0.03), (-0.015, 0.0, 0.0), along_x, GRAPHITE_RGBA),
        FLANGE_FRAME: "",
    }
    return arm_urdf(spec, "kuka.py", links, "joint_a", _origins(spec), _AXES, (0.0, 0.0, 0.0))


def urdf_path(name: str) -> Path:
    """The arm's URDF as a file (written at first use; the name holds a hash of the content)."""
    return cached_urdf(name, urdf_text(arm_spec(name)))


def wrist_root_point_a1(spec: KukaArmSpec, joints_rad: np.ndarray) -> np.ndarray:
    """(x, z) [m] of the wrist root point in the A1 coordinate system (A1's frame at the base,
    turned with A1; z up from the base). Shape (2,)."""
    q = np.asarray(joints_rad, dtype=float)
    a2, a23 = q[1], q[1] + q[2]
    fx, fz = spec.forearm_m, spec.elbow_offset_m
    # R_y(t) (x, 0, z) = (x cos t + z sin t, 0, -x sin t + z cos t)
    x = (
        spec.shoulder_x_m
        + spec.upper_arm_m * math.cos(a2)
        + fx * math.cos(a23)
        + fz * math.sin(a23)
    )
    z = (
        spec.base_height_m
        - spec.upper_arm_m * math.sin(a2)
        - fx * math.sin(a23)
        + fz * math.cos(a23)
    )
    return np.array([x, z])


def status_bits(spec: KukaArmSpec, joints_rad: np.ndarray) -> int:
    """KUKA's Status of a joint solution (see the module docstring): bit 0 overhead area,
    bit 1 A3 >= phi, bit 2 A5 <= 0."""
    q = np.asarray(joints_rad, dtype=float)
    overhead = wrist_root_point_a1(spec, q)[0] < 0.0
    a3_beyond_phi = math.degrees(q[2]) >= spec.status_phi_deg
    a5_not_positive = q[4] <= 0.0
    return int(overhead) + 2 * int(a3_beyond_phi) + 4 * int(a5_not_positive)


def turn_bits(joints_rad: np.ndarray) -> int:
    """KUKA's Turn: bit i - 1 set when axis Ai < 0 deg (A1 -> 1, A2 -> 2, ..., A6 -> 32)."""
    q = np.asarray(joints_rad, dtype=float)
    return int(sum(1 << i for i in range(6) if q[i] < 0.0))
