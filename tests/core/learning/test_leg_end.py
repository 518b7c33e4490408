"""Where a closed route's last leg ends (``walk.LegEnd``): past its start, not at the first
step away from it. At slow feeds the wall's direction wiggles, so the distance to the start
does not fall monotonically; a loop that ended at its first rise stopped 1.7 mm short of its
start and left a 0.46 mm ridge (a good program condemned, issue 28). Properties over generated
approaches, a fresh seed each run (``ROBOMACH_SEED`` replays it)."""

from __future__ import annotations

import numpy as np

from robomach_core.learning import thresholds as th
from robomach_core.learning.route import Leg
from robomach_core.learning.walk import LegEnd
from tests.envelope import replay, run_seed

SEED = run_seed()
AXIS = np.array([0.0, 0.0, -1.0])


def _closing_leg(length_m: float) -> Leg:
    a, b = np.array([0.0, 0.0, 0.0]), np.array([length_m, 0.0, 0.0])
    return Leg(a, b, length_m, np.array([1.0, 0.0, 0.0]), np.eye(3), np.zeros(3), 3, 0)


def test_a_loop_ends_past_its_start_through_the_walls_wiggles():
    rng = np.random.default_rng(SEED)
    for case in range(200):
        radius = float(rng.uniform(0.001, 0.006))
        length = float(rng.uniform(0.02, 0.2))
        end = LegEnd(_closing_leg(length), AXIS, last=True, closed=True, tool_radius_m=radius)
        start = np.array([length + rng.uniform(-0.002, 0.002), rng.uniform(-0.5, 0.5) * radius, 0])
        step = float(rng.uniform(2e-5, 2e-4))  # 0.5-20 mm/s at 4 ms, and the walk's steps
        wiggle = float(rng.uniform(0.0, 0.4)) * th.CLOSE_PASSED_M  # across the travel
        s = 0.5 * length
        ended_at = None
        while s < length + th.CLOSE_LOOP_OVERRUN_M:
            p = np.array([s, start[1] + wiggle * np.sin(s / 3e-4), 0.0])
            if end.reached(p, s, start):
                ended_at = s
                break
            s += step
        where = (
            f"{replay(SEED)}, case {case}: radius {radius * 1e3:.2f} mm, step {step * 1e6:.0f} um"
        )
        assert ended_at is not None, f"{where}: the loop never closed"
        assert ended_at >= start[0], (
            f"{where}: the loop ended {(start[0] - ended_at) * 1e3:.2f} mm short of its start"
        )
        # receding CLOSE_PASSED_M from a nearest approach b across the travel takes this much
        b = abs(float(start[1]))
        beyond = np.sqrt((b + th.CLOSE_PASSED_M + 2 * wiggle) ** 2 - max(b - wiggle, 0.0) ** 2)
        # + a step for where the sampled nearest approach falls, and one for seeing it recede
        assert ended_at <= start[0] + beyond + 2 * step, (
            f"{where}: the loop ran {(ended_at - start[0]) * 1e3:.2f} mm past its start"
        )
