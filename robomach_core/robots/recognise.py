"""Which built-in arm an uploaded URDF is, by its kinematics.

PROBLEM   A UR5 uploaded as a URDF (say, copied out of example-robot-data) is a UR: its
          controller runs URScript, and the built-in UR5's placement, home and stiffness fit it.
          File names and ``<robot name>`` say nothing reliable.
STRATEGY  Two serial arms move alike when their six joint axes are the same lines in the base
          frame at the same joint values. A joint axis is the line (d, m = p x d): direction d
          and moment m for any point p on it, so where a URDF puts a joint's frame along its
          axis does not matter. Compare the lines at the zero pose and at seeded random poses
          inside both arms' limits with every built-in arm; a match within 1 mm and 1 mrad at
          every pose is that arm. The tool flange (tool0) is not compared: its placement
          differs between URDF conventions and the program's TCP is the tool's.
SOLUTION  ``recognise_arm(model) -> name | None``.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

TOLERANCE_M = 1e-3
TOLERANCE_RAD = 1e-3
POSES = 6  # random poses besides the zero pose


def axis_lines(model: pin.Model, data: pin.Data, q: np.ndarray) -> np.ndarray:
    """(6, 6) rows (d, p x d) of the six joint axes in the base frame at joints ``q``."""
    pin.forwardKinematics(model, data, q)
    rows = []
    for j in range(1, 7):
        S = np.asarray(data.joints[j].S).reshape(6, -1)[:, 0]
        w = S[3:] / np.linalg.norm(S[3:])
        M = data.oMi[j]
        d = M.rotation @ w
        rows.append(np.concatenate([d, np.cross(M.translation, d)]))
    return np.array(rows)


def same_kinematics(a: pin.Model, b: pin.Model, *, seed: int = 0) -> bool:
    """True when the two 6-joint serial models have the same axis lines at the zero pose and
    at ``POSES`` random poses inside both models' limits."""
    if a.nq != 6 or b.nq != 6:
        return False
    lower = np.maximum(a.lowerPositionLimit, b.lowerPositionLimit)
    upper = np.minimum(a.upperPositionLimit, b.upperPositionLimit)
    if np.any(lower > upper):
        return False
    rng = np.random.default_rng(seed)
    poses = [np.clip(np.zeros(6), lower, upper)]
    poses += [rng.uniform(lower, upper) for _ in range(POSES)]
    da, db = a.createData(), b.createData()
    for q in poses:
        la, lb = axis_lines(a, da, q), axis_lines(b, db, q)
        if np.abs(la[:, :3] - lb[:, :3]).max() > TOLERANCE_RAD:
            return False
        if np.abs(la[:, 3:] - lb[:, 3:]).max() > TOLERANCE_M:
            return False
    return True


def recognise_arm(model: pin.Model) -> str | None:
    """The built-in arm (``robot.ROBOT_NAMES``) with the same kinematics, or None."""
    from ..cell import robot as robot_module

    for name in robot_module.ROBOT_NAMES:
        if same_kinematics(model, robot_module.Robot(name).model):
            return name
    return None
