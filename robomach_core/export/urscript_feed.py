"""CMRR on a UR arm: the force-driven feed loop a URScript program runs itself.

PROBLEM   A UR controller has no FC SpeedChange: nothing in it scales the programmed speed from
          the measured force, and a program that says "the cell must provide a feed override"
          over a plain list of movel commands does not do what the simulation did.
STRATEGY  The program moves the tool along the path itself, one control period at a time (the
          UR's own streaming pattern): read the wrench at the TCP (``get_tcp_force``, the
          e-Series' built-in sensor, zeroed at rest), low-pass it with the simulation's filter,
          run the chosen controller's law on it and the actual TCP speed, advance the path
          parameter by ratio x programmed speed (ramped at the path acceleration, one move
          ahead) and ``servoj`` to the pose there (``interpolate_pose`` between the targets,
          ``get_inverse_kin`` near the last joints). The ratio acts one period later, as in the
          simulation. The law is written line for line from the machining loop's compiled
          controllers (``machining._kernel``), with their parameters and initial state
          (``_kernel.pack_controller``: the controller as designed for the cut), and the
          adaptive LQ's designs as a table over its Df grid. The force supervision of the
          simulated cell (the spindle's trip at twice the limit) and the fuzzy controllers'
          protection rule stop the robot with a popup.
SOLUTION  ``UrFeedLoop`` and ``feed_loop_lines``; ``urscript.urscript_program`` writes them
          instead of the movel list when it is given a loop. ``LAW_BEGIN`` / ``LAW_END`` mark
          the law so a test can run it against the simulation's (URScript's ``log(b, f)`` is
          the logarithm to the base b, ``pow(b, e)``; it has no ``exp``, ``abs``, ``min`` or
          ``max``: the law spells them out).

URScript reference: Universal Robots, "The URScript Programming Language" (servoj,
get_inverse_kin, interpolate_pose, get_tcp_force, get_actual_tcp_speed, zero_ftsensor).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

# The law between these two comment lines is what the controller does each period.
LAW_BEGIN = "# -- CMRR law begin: cm_f [N], cm_v [m/s] -> cm_next, cm_stop"
LAW_END = "# -- CMRR law end"
E = "2.718281828459045"
# servoj: look-ahead time [s] and gain (the UR's recommended range 0.03-0.2 s, 100-2000).
SERVO_LOOKAHEAD_S = 0.1
SERVO_GAIN = 300
# The adaptive LQ's designs written into the program: Df grid indices within this of the
# initial estimate's (a factor of (1 + tolerance)^25, 10.8 at the 10 % grid, either way).
LQ_TABLE_HALF_WIDTH = 25
KIND_NAMES = {1: "fixed-pi", 2: "adaptive-pi", 3: "fuzzy", 4: "adaptive-lq"}


@dataclass(frozen=True, eq=False)
class UrFeedLoop:
    """What the feed loop needs.

    Attributes:
        controller: the controller's name (a comment).
        reference_N: Fr it holds (a comment; the law has it in its parameters).
        packed: ``machining._kernel.PackedController`` of the controller as designed for the
            cut (the LQ's table is filled here for ``LQ_TABLE_HALF_WIDTH``).
        filter_sos: the force filter's section (b0, b1, b2, 1, a1, a2); ``filter_z0`` its
            initial state.
        dt_s: the control period; ``acceleration_m_s2`` the path acceleration.
        force_limit_N: the supervision stops the robot at ``supervision_factor`` x this.
    """

    controller: str
    reference_N: float
    packed: Any
    filter_sos: tuple[float, ...]
    filter_z0: tuple[float, float]
    dt_s: float
    acceleration_m_s2: float
    force_limit_N: float
    supervision_factor: float = 2.0


def _num(x: float) -> str:
    """A float literal URScript reads exactly (17 significant digits, always a point)."""
    value = float(x)
    if not math.isfinite(value):
        value = 1.0e300 if value > 0 else -1.0e300
    text = repr(value)
    if "e" in text or "E" in text:
        mantissa, exp = text.lower().split("e")
        if "." not in mantissa:
            mantissa += ".0"
        return f"{mantissa}e{exp}"
    return text if "." in text else text + ".0"


def _list(values) -> str:
    return "[" + ", ".join(_num(v) for v in np.asarray(values, dtype=float).ravel()) + "]"


def _int_list(values) -> str:
    return "[" + ", ".join(str(int(v)) for v in np.asarray(values).ravel()) + "]"


def _rows(values, as_int: bool = False) -> str:
    rows = np.atleast_2d(np.asarray(values))
    fmt = _int_list if as_int else _list
    return "[" + ", ".join(fmt(r) for r in rows) + "]"


def law_state_lines(loop: UrFeedLoop) -> list[str]:
    """The law's parameters, tables and initial state."""
    p = loop.packed
    lines = [
        f"cm_euler = {E}",
        f"cm_fp = {_list(p.fp)}",
        f"cm_fs = {_list(p.fs)}",
    ]
    if p.kind == 3:
        lines += [
            f"cm_stages = {_list(p.stages)}",
            f"cm_nst = {len(p.stages)}",
            f"cm_rules = {_rows(p.rules, as_int=True)}",
            f"cm_nrules = {len(p.rules)}",
            f"cm_setidx = {_rows(p.set_idx, as_int=True)}",
            f"cm_setval = {_rows(p.set_val)}",
            f"cm_nset = {p.set_idx.shape[1]}",
            f"cm_univ = {_list(p.universe)}",
            f"cm_nuniv = {len(p.universe)}",
            "cm_mu = " + _list(np.zeros(16)),
        ]
    if p.kind == 4:
        fill_lq_table(p)
        n = int(p.fp[14])
        lines += [
            f"cm_phi = {_rows(p.lq_mats[:n, :n])}",
            f"cm_sphi = {_rows(p.lq_mats[:2, n : n + 2])}",
            f"cm_vec = {_rows(p.lq_vecs)}",
            f"cm_gains = {_rows(p.lq_gains)}",
            f"cm_ff = {_list(p.lq_ff)}",
            f"cm_i0 = {int(p.lq_index0)}",
            f"cm_ng = {len(p.lq_ff)}",
            "cm_nxt = " + _list(np.zeros(n)),
        ]
    return lines


def fill_lq_table(packed: Any) -> None:
    """Design the LQ for every grid index within ``LQ_TABLE_HALF_WIDTH`` of the initial one."""
    have = {packed.lq_index0 + i for i, h in enumerate(packed.lq_have) if h}
    for index in range(-LQ_TABLE_HALF_WIDTH, LQ_TABLE_HALF_WIDTH + 1):
        if index not in have:
            packed.add_design(index)
    lo = -LQ_TABLE_HALF_WIDTH - packed.lq_index0
    hi = lo + 2 * LQ_TABLE_HALF_WIDTH + 1
    packed.lq_gains = packed.lq_gains[lo:hi].copy()
    packed.lq_ff = packed.lq_ff[lo:hi].copy()
    packed.lq_have = packed.lq_have[lo:hi].copy()
    packed.lq_index0 = -LQ_TABLE_HALF_WIDTH


def law_lines(kind: int) -> list[str]:
    """The controller's law (``machining._kernel``'s step of this kind), as URScript lines
    between ``LAW_BEGIN`` and ``LAW_END`` (indented two spaces per block)."""
    body = {1: _FIXED_PI, 2: _ADAPTIVE_PI, 3: _FUZZY, 4: _LQ}[kind]
    return [LAW_BEGIN, *body.strip("\n").splitlines(), LAW_END]


def _power(dst: str, x: str, p: str) -> str:
    """_kernel._power: x^p for x > 0 (0 otherwise), capped at e^300."""
    return f"""{dst} = 0.0
if {x} > 0.0:
  cm_ex = {p} * log(cm_euler, {x})
  if cm_ex < 300.0:
    {dst} = pow(cm_euler, cm_ex)
  else:
    {dst} = pow(cm_euler, 300.0)
  end
end"""


def _saturate_and_integrate(err: str, kp: str, ki: str, dt: str, low: str, integral: str) -> str:
    """The positional PI with saturation (eq. 13) and conditional integration."""
    return f"""cm_ufree = {kp} * {err} + {integral}
cm_next = cm_ufree
if cm_ufree >= 1.0:
  cm_next = 1.0
elif cm_ufree <= {low}:
  cm_next = {low}
end
if not ((cm_ufree >= 1.0 and {err} > 0.0) or (cm_ufree <= {low} and {err} < 0.0)):
  cm_int = {integral} + {ki} * {err} * {dt}
  if cm_int < {low}:
    cm_int = {low}
  end
  if cm_int > 1.0:
    cm_int = 1.0
  end
  {integral} = cm_int
end"""


_FIXED_PI = (
    """# fixed-pi (eqs. 10-13): cm_fp = [(Fr/Kf)^(1/beta), Kf, 1/beta, Kp, Ki, dt, delta]
cm_stop = False
cm_x = 0.0
if cm_f > 0.0:
  cm_x = cm_f / cm_fp[1]
end
"""
    + _power("cm_pw", "cm_x", "cm_fp[2]")
    + """
cm_err = cm_fp[0] - cm_pw
"""
    + _saturate_and_integrate("cm_err", "cm_fp[3]", "cm_fp[4]", "cm_fp[5]", "cm_fp[6]", "cm_fs[0]")
)

_ADAPTIVE_PI = (
    """# adaptive-pi (eqs. 15-16): RLS on log F = log Kf + beta log f, gains re-set each period
cm_stop = False
cm_feed = cm_v
if cm_fp[5] > 0.5:
  cm_out = cm_fp[0] * cm_feed + cm_fs[7]
  cm_fs[7] = cm_fp[1] * cm_feed - cm_fp[3] * cm_out + cm_fs[8]
  cm_fs[8] = cm_fp[2] * cm_feed - cm_fp[4] * cm_out
  cm_feed = cm_out
end
cm_force = cm_f
if cm_force < 0.0:
  cm_force = 0.0
end
cm_t0 = cm_fs[1]
cm_t1 = cm_fs[2]
cm_p00 = cm_fs[3]
cm_p01 = cm_fs[4]
cm_p10 = cm_fs[5]
cm_p11 = cm_fs[6]
cm_lam = cm_fp[6]
if cm_force > cm_fp[16] and cm_feed > cm_fp[17]:
  cm_x1 = log(cm_euler, cm_feed / cm_fp[11])
  cm_y = log(cm_euler, cm_force)
  cm_px0 = cm_p00 + cm_p01 * cm_x1
  cm_px1 = cm_p10 + cm_p11 * cm_x1
  cm_den = cm_lam + (cm_px0 + cm_x1 * cm_px1)
  cm_g0 = cm_px0 / cm_den
  cm_g1 = cm_px1 / cm_den
  cm_e = cm_y - (cm_t0 + cm_t1 * cm_x1)
  cm_n00 = (cm_p00 - cm_g0 * cm_px0) / cm_lam
  cm_n01 = (cm_p01 - cm_g0 * cm_px1) / cm_lam
  cm_n10 = (cm_p10 - cm_g1 * cm_px0) / cm_lam
  cm_n11 = (cm_p11 - cm_g1 * cm_px1) / cm_lam
  cm_n01 = 0.5 * (cm_n01 + cm_n10)
  cm_n10 = cm_n01
  if cm_n00 > cm_fp[7] or cm_n11 > cm_fp[8]:
    cm_a0 = cm_n00
    if cm_a0 < 1.0e-300:
      cm_a0 = 1.0e-300
    end
    cm_a1 = cm_n11
    if cm_a1 < 1.0e-300:
      cm_a1 = 1.0e-300
    end
    cm_r0 = cm_fp[7] / cm_a0
    if cm_r0 > 1.0:
      cm_r0 = 1.0
    end
    cm_r1 = cm_fp[8] / cm_a1
    if cm_r1 > 1.0:
      cm_r1 = 1.0
    end
    cm_s0 = sqrt(cm_r0)
    cm_s1 = sqrt(cm_r1)
    cm_n00 = cm_n00 * cm_s0 * cm_s0
    cm_n01 = cm_n01 * cm_s0 * cm_s1
    cm_n10 = cm_n10 * cm_s1 * cm_s0
    cm_n11 = cm_n11 * cm_s1 * cm_s1
  end
  cm_t0 = cm_t0 + cm_g0 * cm_e
  cm_t1 = cm_t1 + cm_g1 * cm_e
  cm_p00 = cm_n00
  cm_p01 = cm_n01
  cm_p10 = cm_n10
  cm_p11 = cm_n11
end
cm_beta = cm_t1
if cm_beta < cm_fp[9]:
  cm_beta = cm_fp[9]
end
if cm_beta > cm_fp[10]:
  cm_beta = cm_fp[10]
end
cm_kf = pow(cm_euler, cm_t0 - cm_beta * cm_fp[12])
cm_ib = 1.0 / cm_beta
cm_k = pow(cm_kf, cm_ib)
cm_ki = cm_fp[18] / (cm_fp[20] * cm_k)
cm_kp = cm_ki / cm_fp[19]
cm_err = pow(cm_fp[13], cm_ib)
if cm_force > 0.0:
  cm_err = cm_err - pow(cm_force, cm_ib)
end
"""
    + _saturate_and_integrate("cm_err", "cm_kp", "cm_ki", "cm_fp[15]", "cm_fp[14]", "cm_fs[0]")
    + """
cm_fs[1] = cm_t0
cm_fs[2] = cm_t1
cm_fs[3] = cm_p00
cm_fs[4] = cm_p01
cm_fs[5] = cm_p10
cm_fs[6] = cm_p11"""
)


def _memberships(dst: str, offset: int, x: str, lo: str, hi: str, count: int) -> str:
    """cmrr.controllers._fast._memberships into cm_mu[offset:offset + count]."""
    return f"""cm_w = ({hi} - {lo}) / {count - 1}.0
cm_xc = {x}
if cm_xc < {lo}:
  cm_xc = {lo}
end
if cm_xc > {hi}:
  cm_xc = {hi}
end
cm_j = 0
while cm_j < {count}:
  cm_g = cm_xc - ({lo} + cm_j * cm_w)
  if cm_g < 0.0:
    cm_g = -cm_g
  end
  cm_g = 1.0 - cm_g / cm_w
  if cm_g < 0.0:
    cm_g = 0.0
  end
  {dst}[{offset} + cm_j] = cm_g
  cm_j = cm_j + 1
end"""


_FUZZY = (
    """# fuzzy / two-stage (chapter 4.3.4): Mamdani PD on the error, its trend and the stage
cm_stop = False
if cm_fs[5] > 0.5:
  cm_next = 0.0
  cm_stop = True
else:
  cm_stage = floor(cm_fs[1] + 0.5)
  cm_error = cm_f - cm_fp[0]
  cm_trend = cm_fp[3] * cm_fs[2] + (1.0 - cm_fp[3]) * ((cm_error - cm_fs[3]) / cm_fp[4])
  cm_fs[6] = cm_fs[6] + cm_fp[4]
  if cm_fs[6] < cm_fp[10]:
    cm_trend = 0.0
  end
"""
    + "\n".join(
        "  " + line
        for line in (
            _memberships("cm_mu", 0, "cm_error / cm_fp[1]", "-1.0", "1.0", 5)
            + "\n"
            + _memberships("cm_mu", 5, "cm_trend / cm_fp[2]", "-1.0", "1.0", 3)
            + "\n"
            + _memberships(
                "cm_mu", 8, "cm_stages[cm_stage]", "cm_stages[0]", "cm_stages[cm_nst - 1]", 3
            )
        ).splitlines()
    )
    + """
  cm_j = 0
  while cm_j < 5:
    cm_mu[11 + cm_j] = 0.0
    cm_j = cm_j + 1
  end
  cm_strength = 0.0
  cm_r = 0
  while cm_r < cm_nrules:
    cm_w = 1.0
    if cm_rules[cm_r][0] >= 0:
      if cm_mu[cm_rules[cm_r][0]] < cm_w:
        cm_w = cm_mu[cm_rules[cm_r][0]]
      end
    end
    if cm_rules[cm_r][1] >= 0:
      if cm_mu[5 + cm_rules[cm_r][1]] < cm_w:
        cm_w = cm_mu[5 + cm_rules[cm_r][1]]
      end
    end
    if cm_rules[cm_r][2] >= 0:
      if cm_mu[8 + cm_rules[cm_r][2]] < cm_w:
        cm_w = cm_mu[8 + cm_rules[cm_r][2]]
      end
    end
    if cm_rules[cm_r][3] < 0:
      if cm_w > cm_strength:
        cm_strength = cm_w
      end
    elif cm_w > cm_mu[11 + cm_rules[cm_r][3]]:
      cm_mu[11 + cm_rules[cm_r][3]] = cm_w
    end
    cm_r = cm_r + 1
  end
  cm_area = 0.0
  cm_moment = 0.0
  cm_j = 0
  while cm_j < cm_nuniv:
    cm_a = 0.0
    cm_q = 0
    while cm_q < cm_nset:
      cm_o = cm_setidx[cm_j][cm_q]
      if cm_o >= 0:
        cm_m = cm_setval[cm_j][cm_q]
        if cm_mu[11 + cm_o] < cm_m:
          cm_m = cm_mu[11 + cm_o]
        end
        if cm_m > cm_a:
          cm_a = cm_m
        end
      end
      cm_q = cm_q + 1
    end
    cm_area = cm_area + cm_a
    cm_moment = cm_moment + cm_a * cm_univ[cm_j]
    cm_j = cm_j + 1
  end
  cm_change = 0.0
  if cm_area > 0.0:
    cm_change = cm_moment / cm_area
  end
  cm_firing = cm_strength >= cm_fp[5]
  cm_prot = 0.0
  if cm_firing:
    cm_prot = cm_fs[4] + cm_fp[4]
  end
  cm_fs[2] = cm_trend
  cm_fs[3] = cm_error
  cm_fs[4] = cm_prot
  if cm_firing and cm_prot >= cm_fp[6]:
    cm_fs[5] = 1.0
    cm_next = 0.0
    cm_stop = True
  else:
    cm_in = cm_fs[0] + cm_change * cm_fp[7] * cm_fp[4]
    if cm_in < cm_stages[0]:
      cm_in = cm_stages[0]
    end
    if cm_in > cm_stages[cm_nst - 1]:
      cm_in = cm_stages[cm_nst - 1]
    end
    cm_fnow = cm_f
    if cm_fnow < 0.0:
      cm_fnow = 0.0
    end
    cm_new = cm_stage
    cm_go = True
    while cm_go and cm_new + 1 < cm_nst:
      cm_mid = 0.5 * (cm_stages[cm_new] + cm_stages[cm_new + 1])
      cm_lvl = cm_mid + cm_fp[8] * (cm_stages[cm_new + 1] - cm_stages[cm_new])
      if cm_in > cm_lvl:
        cm_pred = cm_fnow * pow(cm_stages[cm_new + 1] / cm_stages[cm_new], cm_fp[9])
        if cm_pred >= cm_fp[0] * (1.0 - cm_fp[11]):
          cm_in = cm_lvl
          cm_go = False
        else:
          cm_new = cm_new + 1
        end
      else:
        cm_go = False
      end
    end
    cm_go = True
    while cm_go and cm_new > 0:
      cm_mid = 0.5 * (cm_stages[cm_new] + cm_stages[cm_new - 1])
      cm_lvl = cm_mid - cm_fp[8] * (cm_stages[cm_new] - cm_stages[cm_new - 1])
      if cm_in < cm_lvl:
        cm_new = cm_new - 1
      else:
        cm_go = False
      end
    end
    if cm_new != cm_stage:
      cm_fs[6] = 0.0
    end
    cm_fs[0] = cm_in
    cm_fs[1] = cm_new * 1.0
    cm_next = cm_stages[cm_new]
  end
end"""
)

_LQ = """# adaptive-lq (Lund paper sec. 2.1): Kalman filter, RLS on Df, LQ gain from the grid table
cm_stop = False
cm_n = floor(cm_fp[14] + 0.5)
cm_d = floor(cm_fp[15] + 0.5)
cm_o = cm_n + cm_d
cm_it = cm_o + 6
cm_vr = cm_fp[2]
cm_fr = cm_fp[0]
cm_feedmm = cm_v / 0.001
cm_yh = 0.0
cm_j = 0
while cm_j < cm_n:
  cm_yh = cm_yh + cm_vec[1][cm_j] * cm_fs[cm_j]
  cm_j = cm_j + 1
end
cm_inn = cm_feedmm - cm_yh
cm_j = 0
while cm_j < cm_n:
  cm_fs[cm_j] = cm_fs[cm_j] + cm_vec[2][cm_j] * cm_inn
  cm_j = cm_j + 1
end
cm_ff_v = cm_feedmm
if cm_fp[13] > 0.5:
  cm_out = cm_vec[4][0] * cm_feedmm + cm_fs[cm_o + 4]
  cm_fs[cm_o + 4] = cm_vec[4][1] * cm_feedmm - cm_vec[4][4] * cm_out + cm_fs[cm_o + 5]
  cm_fs[cm_o + 5] = cm_vec[4][2] * cm_feedmm - cm_vec[4][5] * cm_out
  cm_ff_v = cm_out
end
cm_f0 = cm_sphi[0][0] * cm_fs[cm_o] + cm_sphi[0][1] * cm_fs[cm_o + 1] + cm_vec[3][0] * cm_f
cm_f1 = cm_sphi[1][0] * cm_fs[cm_o] + cm_sphi[1][1] * cm_fs[cm_o + 1] + cm_vec[3][1] * cm_f
cm_v0 = cm_sphi[0][0] * cm_fs[cm_o + 2] + cm_sphi[0][1] * cm_fs[cm_o + 3] + cm_vec[3][0] * cm_ff_v
cm_v1 = cm_sphi[1][0] * cm_fs[cm_o + 2] + cm_sphi[1][1] * cm_fs[cm_o + 3] + cm_vec[3][1] * cm_ff_v
cm_fs[cm_o] = cm_f0
cm_fs[cm_o + 1] = cm_f1
cm_fs[cm_o + 2] = cm_v0
cm_fs[cm_o + 3] = cm_v1
cm_y = cm_f0 / cm_fr
cm_x = (cm_v0 - cm_f1 / cm_fp[1]) / cm_vr
cm_th = cm_fs[cm_it]
cm_p = cm_fs[cm_it + 1]
cm_r2 = cm_fs[cm_it + 2]
cm_adapt = cm_fp[3] > 0.5
if cm_adapt and cm_x > 0.03 and cm_y > 0.03:
  cm_res = cm_y - cm_th * cm_x
  cm_gr = cm_p * cm_x / (cm_fp[4] + cm_x * cm_p * cm_x)
  cm_th = cm_th + cm_gr * cm_res
  cm_p = (cm_p - cm_gr * cm_x * cm_p) / cm_fp[4]
  if cm_p > 1000.0:
    cm_p = 1000.0
  end
  cm_r2 = cm_fp[4] * cm_r2 + (1.0 - cm_fp[4]) * cm_res * cm_res
  cm_fs[cm_it] = cm_th
  cm_fs[cm_it + 1] = cm_p
  cm_fs[cm_it + 2] = cm_r2
end
cm_dfh = cm_th * cm_fr / cm_vr
cm_int = cm_fs[cm_it + 3]
cm_fs[cm_it + 4] = cm_fs[cm_it + 4] + cm_fp[10]
cm_active = cm_fs[cm_it + 5] > 0.5
cm_idx = floor(cm_fs[cm_it + 6] + 0.5)
cm_row = cm_idx - cm_i0
cm_key = cm_fp[5]
if cm_idx != 0:
  cm_key = cm_fp[5] * pow(cm_euler, cm_fp[6] * cm_idx)
end
cm_lo = cm_key / cm_fp[7] * (1.0 + 1.0e-9)
cm_hi = cm_key * cm_fp[7] * (1.0 - 1.0e-9)
if cm_adapt and not (cm_lo < cm_dfh and cm_dfh < cm_hi) and cm_dfh > 0.0:
  cm_new = floor(log(cm_euler, cm_dfh / cm_fp[5]) / cm_fp[6] + 0.5)
  if cm_new < cm_i0:
    cm_new = cm_i0
  end
  if cm_new > cm_i0 + cm_ng - 1:
    cm_new = cm_i0 + cm_ng - 1
  end
  if cm_new != cm_idx:
    cm_nrow = cm_new - cm_i0
    if cm_active:
      cm_fb = 0.0
      cm_j = 0
      while cm_j < cm_o:
        cm_fb = cm_fb + cm_gains[cm_row][cm_j] * cm_fs[cm_j]
        cm_j = cm_j + 1
      end
      cm_fb = cm_fb + cm_gains[cm_row][cm_o] * cm_f + cm_gains[cm_row][cm_o + 1] * cm_int
      cm_before = -cm_fb + cm_ff[cm_row] * cm_fr
      cm_li = cm_gains[cm_nrow][cm_o + 1]
      if cm_li > 1.0e-12 or cm_li < -1.0e-12:
        cm_fb = 0.0
        cm_j = 0
        while cm_j < cm_o:
          cm_fb = cm_fb + cm_gains[cm_nrow][cm_j] * cm_fs[cm_j]
          cm_j = cm_j + 1
        end
        cm_fb = cm_fb + cm_gains[cm_nrow][cm_o] * cm_f
        cm_int = ((-cm_fb + cm_ff[cm_nrow] * cm_fr) - cm_before) / cm_li
      end
    end
    cm_idx = cm_new
    cm_row = cm_nrow
    cm_fs[cm_it + 6] = cm_idx * 1.0
  end
end
if not cm_active and cm_fs[cm_it + 4] >= cm_fp[11]:
  cm_ath = cm_th
  if cm_ath < 0.0:
    cm_ath = -cm_ath
  end
  if cm_ath < 1.0e-9:
    cm_ath = 1.0e-9
  end
  cm_rp = cm_r2 * cm_p
  if cm_rp < 0.0:
    cm_rp = 0.0
  end
  if not cm_adapt or sqrt(cm_rp) / cm_ath < cm_fp[12]:
    cm_active = True
    cm_cur = cm_fp[9] * cm_vr
    if cm_d > 0:
      cm_cur = cm_fs[cm_n + cm_d - 1]
    end
    cm_li = cm_gains[cm_row][cm_o + 1]
    if cm_li > 1.0e-12 or cm_li < -1.0e-12:
      cm_fb = 0.0
      cm_j = 0
      while cm_j < cm_o:
        cm_fb = cm_fb + cm_gains[cm_row][cm_j] * cm_fs[cm_j]
        cm_j = cm_j + 1
      end
      cm_fb = cm_fb + cm_gains[cm_row][cm_o] * cm_f
      cm_int = ((-cm_fb + cm_ff[cm_row] * cm_fr) - cm_cur) / cm_li
    end
  end
end
if cm_active:
  cm_fb = 0.0
  cm_j = 0
  while cm_j < cm_o:
    cm_fb = cm_fb + cm_gains[cm_row][cm_j] * cm_fs[cm_j]
    cm_j = cm_j + 1
  end
  cm_fb = cm_fb + cm_gains[cm_row][cm_o] * cm_f + cm_gains[cm_row][cm_o + 1] * cm_int
  cm_u = (-cm_fb + cm_ff[cm_row] * cm_fr) / cm_vr
  cm_next = cm_u
  if cm_u >= 1.0:
    cm_next = 1.0
  elif cm_u <= cm_fp[8]:
    cm_next = cm_fp[8]
  end
  cm_e = cm_fr - cm_f
  if not ((cm_next >= 1.0 and cm_e > 0.0) or (cm_next <= cm_fp[8] and cm_e < 0.0)):
    cm_int = cm_int + cm_fp[10] * cm_e
  end
else:
  cm_next = cm_fp[9]
end
cm_cmd = cm_next * cm_vr
cm_act = cm_cmd
if cm_d > 0:
  cm_act = cm_fs[cm_n]
end
cm_j = 0
while cm_j < cm_n:
  cm_acc = cm_vec[0][cm_j] * cm_act
  cm_k = 0
  while cm_k < cm_n:
    cm_acc = cm_acc + cm_phi[cm_j][cm_k] * cm_fs[cm_k]
    cm_k = cm_k + 1
  end
  cm_nxt[cm_j] = cm_acc
  cm_j = cm_j + 1
end
cm_j = 0
while cm_j < cm_n:
  cm_fs[cm_j] = cm_nxt[cm_j]
  cm_j = cm_j + 1
end
if cm_d > 0:
  cm_j = 0
  while cm_j < cm_d - 1:
    cm_fs[cm_n + cm_j] = cm_fs[cm_n + cm_j + 1]
    cm_j = cm_j + 1
  end
  cm_fs[cm_n + cm_d - 1] = cm_cmd
end
cm_fs[cm_it + 3] = cm_int
if cm_active:
  cm_fs[cm_it + 5] = 1.0
else:
  cm_fs[cm_it + 5] = 0.0
end"""


def feed_loop_lines(
    loop: UrFeedLoop,
    path_literals: list[str],
    speeds_m_s: np.ndarray,
    arc_m: np.ndarray,
    *,
    fixed,
) -> list[str]:
    """The program's lines from the first target to the end of the path (two-space blocks):
    the path, the law's state, the sensor zeroed at rest, and the loop."""
    p = loop.packed
    b0, b1, b2, _, a1, a2 = (float(v) for v in loop.filter_sos)
    z0, z1 = (float(v) for v in loop.filter_z0)
    dt = loop.dt_s
    n = len(path_literals)
    lines = [
        f"# CMRR: {loop.controller} holding {fixed(loop.reference_N)} N. UR controllers have no "
        "feed override driven by the force, so this program runs one:",
        f"# every {fixed(dt * 1e3)} ms it reads the TCP wrench, filters it, runs the "
        f"{loop.controller} law, advances along the path by ratio x programmed speed and",
        "# servoj's there. The law is the simulation's, with its parameters (cm_fp) and state "
        "(cm_fs); the ratio acts one period later.",
        f"cm_path = [{', '.join(path_literals)}]",
        f"cm_speed = {_list(np.round(speeds_m_s, 10))}",
        f"cm_arc = {_list(arc_m)}",
        f"cm_npath = {n}",
        *law_state_lines(loop),
        f"movel(cm_path[0], a={fixed(loop.acceleration_m_s2)}, v={fixed(speeds_m_s[0])}, r=0)",
        "sleep(0.5)",
        "zero_ftsensor()",
        "cm_s = 0.0",
        "cm_i = 1",
        f"cm_ratio = {_num(p.first_ratio)}",
        "cm_vplan = 0.0",
        f"cm_z1 = {_num(z0)}",
        f"cm_z2 = {_num(z1)}",
        "cm_qn = get_actual_joint_positions()",
        "while cm_s < cm_arc[cm_npath - 1]:",
        "  cm_wr = get_tcp_force()",
        "  cm_raw = norm([cm_wr[0], cm_wr[1], cm_wr[2]])",
        f"  if cm_raw > {_num(loop.supervision_factor * loop.force_limit_N)}:",
        "    stopl(1.0)",
        '    popup("force supervision: the cut force passed twice the limit", '
        '"robomach CMRR", error=True)',
        "    halt",
        "  end",
        f"  cm_f = {_num(b0)} * cm_raw + cm_z1",
        f"  cm_z1 = {_num(b1)} * cm_raw - {_num(a1)} * cm_f + cm_z2",
        f"  cm_z2 = {_num(b2)} * cm_raw - {_num(a2)} * cm_f",
        "  cm_tv = get_actual_tcp_speed()",
        "  cm_v = norm([cm_tv[0], cm_tv[1], cm_tv[2]])",
        *(f"  {line}" for line in law_lines(p.kind)),
        "  if cm_stop:",
        "    stopl(1.0)",
        '    popup("CMRR protection rule: the force stays too high at the lowest stage", '
        '"robomach CMRR", error=True)',
        "    halt",
        "  end",
        "  cm_vp = cm_speed[cm_i]",
        "  if cm_i + 1 < cm_npath:",
        f"    cm_ahead = sqrt(pow(cm_speed[cm_i + 1], 2) + "
        f"{_num(2.0 * loop.acceleration_m_s2)} * (cm_arc[cm_i] - cm_s))",
        "    if cm_ahead < cm_vp:",
        "      cm_vp = cm_ahead",
        "    end",
        "  end",
        f"  if cm_vp > cm_vplan + {_num(loop.acceleration_m_s2 * dt)}:",
        f"    cm_vp = cm_vplan + {_num(loop.acceleration_m_s2 * dt)}",
        "  end",
        "  cm_vplan = cm_vp",
        f"  cm_s = cm_s + cm_ratio * cm_vp * {_num(dt)}",
        "  cm_ratio = cm_next",
        "  while cm_i < cm_npath - 1 and cm_s > cm_arc[cm_i]:",
        "    cm_i = cm_i + 1",
        "  end",
        "  cm_al = (cm_s - cm_arc[cm_i - 1]) / (cm_arc[cm_i] - cm_arc[cm_i - 1])",
        "  if cm_al > 1.0:",
        "    cm_al = 1.0",
        "  end",
        "  cm_qn = get_inverse_kin(interpolate_pose(cm_path[cm_i - 1], cm_path[cm_i], cm_al), "
        "qnear=cm_qn)",
        f"  servoj(cm_qn, t={_num(dt)}, lookahead_time={_num(SERVO_LOOKAHEAD_S)}, "
        f"gain={SERVO_GAIN})",
        "end",
        "stopl(1.0)",
    ]
    return lines
