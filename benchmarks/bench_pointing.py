"""Seconds from a click on the part to its recorded guide point, as a person at the workbench
waits for them (issue 15: "every point within 5 s").

Run: ``python benchmarks/bench_pointing.py``. A paced Session (motions take their wall-clock
time, as at the pendant) teaches the pump's outer wall at the 14 places of the browser test
(tests/browser/test_pointing.py) through ``Pointing.teach_at_surface``, what a click in "teach
a point" mode calls; then one click proposes the groove and the proposal is accepted. The same
points on an unpaced Session are the reference: the difference is the motion itself, the rest
is planning. ``--quick``: the first point, no proposal (a smoke test, not a measurement).

The browser adds the picking round trip (tens of ms); the browser test checks the clicks
themselves, unpaced.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.browser.test_pointing import PUMP_WALL_POINTS, WALL_MID_Z_MM  # noqa: E402


def teach_points(real_time: bool, points) -> list[float]:
    """Seconds per ``teach_at_surface`` call on a new Session (paced or not)."""
    from app.session import Session

    session = Session(real_time=real_time)
    try:
        seconds = []
        for xy, normal in points:
            p = np.array([xy[0], xy[1], WALL_MID_Z_MM]) * 1e-3
            started = time.perf_counter()
            session.pointing.teach_at_surface(p, np.array([normal[0], normal[1], 0.0]))
            seconds.append(time.perf_counter() - started)
        return seconds
    finally:
        session.close()


def propose_and_accept() -> tuple[float, float, int]:
    """Seconds to propose the groove's wall from one click, and to accept it (the robot led to
    every proposed point, paced); the number of points."""
    from app.session import Session

    session = Session(real_time=True)
    try:
        started = time.perf_counter()
        click_wobj_m = np.array([40.0, 65.0, 17.5]) * 1e-3  # the browser test's click
        proposal = session.pointing.propose(click_wobj_m, np.array([0.0, -1.0, 0.0]))
        proposed_s = time.perf_counter() - started
        started = time.perf_counter()
        job_id = session.pointing.accept()
        while session.robot.busy() or len(session.project().guide_points) < len(proposal.points):
            job = session.jobs.get(job_id)
            if job.status in ("failed", "cancelled"):  # no points will come
                raise SystemExit(f"accepting the proposal ended {job.status}: {job.error}")
            time.sleep(0.05)
        return proposed_s, time.perf_counter() - started, len(proposal.points)
    finally:
        session.close()


def row(name: str, seconds: list[float]) -> None:
    print(
        f"{name:<30} {len(seconds):>3} {statistics.median(seconds):>8.2f} "
        f"{max(seconds):>8.2f} {seconds[0]:>8.2f}"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="1 point, no proposal")
    args = parser.parse_args()
    points = PUMP_WALL_POINTS[:1] if args.quick else PUMP_WALL_POINTS
    print(f"{'click to recorded point':<30} {'n':>3} {'median s':>8} {'max s':>8} {'first s':>8}")
    paced = teach_points(True, points)
    row("paced (a person's wait)", paced)
    unpaced = teach_points(False, points)
    row("unpaced (planning only)", unpaced)
    print(
        f"points within 5 s (paced): {sum(s <= 5.0 for s in paced)} of {len(paced)}; "
        f"motion is {1 - statistics.median(unpaced) / statistics.median(paced):.0%} of the median"
    )
    if not args.quick:
        proposed_s, accepted_s, n = propose_and_accept()
        print(f"one click proposes {n} points in {proposed_s:.2f} s; accepting them (paced) "
              f"{accepted_s:.1f} s, {accepted_s / n:.1f} s per point")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
