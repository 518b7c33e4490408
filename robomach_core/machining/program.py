"""The program a machining configuration runs: the learned targets with the feed it commands.

PROBLEM   The simulated cut capped the learned speeds at the CMRR speed cap, or ran the greatest
          safe constant feed, while the exported program kept the learned speeds (up to 7 x the
          constant feed that was simulated, and 21.5 mm/s where the simulation capped at 10):
          the program that left was not the cut that was simulated.
STRATEGY  One function makes the program of a configuration, and both the simulation and every
          exporter take it: each move's speed is the learned one, capped at Vr (the speed the
          CMRR controllers scale from), and for the constant feed at that feed; then rounded
          down to 0.01 mm/s, a value each language writes exactly (RAPID speeddata in mm/s with
          two decimals, KRL $VEL.CP in m/s with five, URScript v in m/s with six), so a program
          read back from its file commands the very feeds that were cut, and the constant feed
          stays within the force limit it was computed for.
SOLUTION  ``machining_program(targets, settings, design_depth_m=...)`` and
          ``constant_feed_m_s``.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..postprocess import Targets
from .errors import MachiningSettingsError
from .settings import MachiningSettings

# Every machining program's speeds are multiples of this [m/s] (0.01 mm/s).
SPEED_QUANTUM_M_S = 1e-5
MM = 1e-3
# Every exported program writes its positions to this in the work object's frame [m] (RAPID
# and KRL: mm with four decimals); the simulation cuts them so (``as_written``).
POSITION_RESOLUTION_M = 1e-7
# Below this a constant feed rubs rather than cuts (the MRR paper's minimal feed) [m/s].
MIN_CONSTANT_FEED_M_S = 0.05 * MM


def quantized_down(speed_m_s: np.ndarray | float) -> np.ndarray:
    """Speeds rounded down to ``SPEED_QUANTUM_M_S`` (a speed a hair under a multiple, from
    float arithmetic, counts as that multiple)."""
    per_m_s = round(1.0 / SPEED_QUANTUM_M_S)
    steps = np.floor(np.asarray(speed_m_s, dtype=float) * per_m_s + 1e-6)
    return steps / per_m_s  # the decimal's nearest float (852 / 1e5 is 0.00852)


def design_depth_m(settings: MachiningSettings, stock_max_depth_m: float) -> float:
    """The deepest cut the program and its controllers are designed for: the settings' own
    (a sweep over castings keeps the nominal stock's design), else the stock's."""
    return settings.design_depth_m if settings.design_depth_m is not None else stock_max_depth_m


def constant_feed_m_s(settings: MachiningSettings, max_depth_m: float) -> float:
    """The constant feed's program speed: ``settings.constant_feed_m_s``, else the greatest
    constant feed keeping the force limit at the deepest cut (inverse of eq. 5), capped at Vr;
    rounded down to the program's speed quantum."""
    feed = settings.constant_feed_m_s
    if feed is None:
        feed = settings.safe_constant_feed_m_s(max_depth_m)
    return float(quantized_down(feed)) if math.isfinite(feed) else feed


def check_constant_feed(settings: MachiningSettings, max_depth_m: float) -> None:
    """Raise ``MachiningSettingsError`` when no constant feed of at least
    ``MIN_CONSTANT_FEED_M_S`` keeps the force limit at the deepest cut."""
    feed = constant_feed_m_s(settings, max_depth_m)
    if not feed >= MIN_CONSTANT_FEED_M_S:
        raise MachiningSettingsError(
            f"no constant feed keeps the {settings.force_limit_N:g} N force limit at the deepest "
            f"cut ({max_depth_m / MM:.2f} mm): F = {settings.process_gain_N:g} d^"
            f"{settings.depth_exponent:g} f^{settings.feed_exponent:g} reaches it at "
            f"{feed / MM:.2g} mm/s, below {MIN_CONSTANT_FEED_M_S / MM:g} mm/s (rubbing, "
            "not cutting); raise the force limit or check the process K, alpha and beta"
        )


def machining_program(
    targets: Targets, settings: MachiningSettings, *, design_depth_m: float
) -> Targets:
    """The program ``settings``' configuration runs and every exporter writes (module
    docstring): speeds min(learned, Vr) and for the constant feed min(.., feed), rounded down
    to 0.01 mm/s.

    Raises:
        MachiningSettingsError: a speed rounds to zero (a learned speed or constant feed below
            0.01 mm/s).
    """
    v = np.minimum(np.asarray(targets.speed_m_s, dtype=float), settings.command_speed_cap_m_s)
    if settings.controller == "constant":
        check_constant_feed(settings, design_depth_m)
        v = np.minimum(v, constant_feed_m_s(settings, design_depth_m))
    v = quantized_down(v)
    if not np.all(v >= SPEED_QUANTUM_M_S):
        raise MachiningSettingsError(
            f"a program speed rounds to 0 at {SPEED_QUANTUM_M_S / MM:g} mm/s (the slowest "
            f"is {float(np.min(v)) / MM:g} mm/s); raise the speeds or the force limit"
        )
    return replace(targets, speed_m_s=v)


def as_written(targets: Targets, T_base_wobj: np.ndarray | None) -> Targets:
    """``targets`` with their positions as the program files write them: rounded to
    ``POSITION_RESOLUTION_M`` in the work object's frame (unchanged without a frame). A
    compensated cut's wall error is a few micrometres; the files' rounding must not be what
    moves it."""
    if T_base_wobj is None:
        return targets
    T = np.asarray(T_base_wobj, dtype=float)
    local = (np.asarray(targets.position_m, dtype=float) - T[:3, 3]) @ T[:3, :3]
    per_m = round(1.0 / POSITION_RESOLUTION_M)
    local = np.round(local * per_m) / per_m
    return replace(targets, position_m=local @ T[:3, :3].T + T[:3, 3])
