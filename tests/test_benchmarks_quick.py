"""Every script in benchmarks/ still runs: each in its ``--quick`` mode, as a subprocess.

A refactor that breaks a benchmark (an import, a renamed function, a changed signature) fails
here. The figures printed in quick mode are not measurements: only that they are printed is
checked (timing belongs in benchmarks/, not in asserts).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TIMEOUT_S = 600
NUMBER = r"[-+]?\d+(?:\.\d+)?"

# Script -> patterns its output must contain (each with the figure it prints).
EXPECTED: dict[str, list[str]] = {
    "bench_reduction.py": [
        rf"deviation height .*-> \d+ targets, median {NUMBER} ms",
        rf"RDP reference .*median {NUMBER} ms",
        rf"ratio ours / RDP: {NUMBER} of the time",
        rf"learned at 5 mm/s: \d+ samples -> \d+ targets in {NUMBER} ms, \d+ ns per sample",
        rf"learned at 0.5 mm/s: \d+ samples -> \d+ targets in {NUMBER} ms, \d+ ns per sample",
        r"postprocess\(\) on a synthetic \d+-sample recording: .* in \d+ ms",
    ],
    "bench_api.py": [
        rf"idle\s+\d+\s+{NUMBER}\s+{NUMBER}",
        rf"during the example job\s+\d+\s+{NUMBER}\s+{NUMBER}",
        rf"4 clients at once \(per request\)\s+\d+\s+{NUMBER}\s+{NUMBER}",
    ],
    "bench_cmrr.py": [
        rf"{name}\s+{NUMBER}\s+{NUMBER}\s+{NUMBER}"
        for name in ("constant", "fixed-pi", "adaptive-pi", "fuzzy", "two-stage", "adaptive-lq")
    ],
    "bench_path_learning.py": [
        rf"lead-through: {NUMBER} s simulated",
        rf"path learning: \d+ samples, .*real-time factor median x{NUMBER}",
        rf"whole cell step\s+{NUMBER}",
        rf"one period = {NUMBER} x the pinocchio reference",
        *(
            rf"{part}\s+{NUMBER} us\s+{NUMBER} %"
            for part in (
                r"supervision \(limits, IK step\)",
                r"cell: contact \(coal, nearest face, force\)",
                r"force loop \(law, turn, recording row\)",
            )
        ),
        rf"inside supervision: the IK step \(ik_newton_step\)\s+{NUMBER} us",
        rf"the block's outer wall from 1 sloppy set: real-time factor median x{NUMBER}",
        rf"every near clearance by coal, median x{NUMBER}; the kernel's GJK is x{NUMBER} as fast",
    ],
    "bench_stiffness.py": [
        rf"online compensation step \(fig. 15\)\s+{NUMBER}\s+{NUMBER} %",
        rf"offline correction per target, eq. \(32\)\s+{NUMBER}",
    ],
    "bench_machining.py": [
        r"water pump, program along the true wall \(--quick\): \d+ targets, \d+ mm",
        *(
            rf"{c}\s+{m}\s+{NUMBER}\s+{NUMBER}\s+{NUMBER}"
            for c, m in (("adaptive-pi", "off"), ("constant", "off"), ("adaptive-lq", "offline"))
        ),
        rf"slowest configuration: x{NUMBER} real time",
        rf"variations: \d+ stocks x 18 runs: 1 worker {NUMBER} s, \d+ workers {NUMBER} s: "
        rf"x{NUMBER} faster \(same figures: yes\)",
    ],
    "bench_offline_stocks.py": [
        rf"ur10 stock \d+: constant {NUMBER}% fuzzy {NUMBER}% two-stage {NUMBER}%",
        *(
            rf"{c}\s+median\s+{NUMBER} %\s+worst\s+{NUMBER} %\s+under 75 %: \d+/\d+"
            for c in ("constant", "fuzzy", "two-stage")
        ),
    ],
    "bench_reads_during_postprocess.py": [rf"worst read p99 during post-processing {NUMBER} ms"],
    "bench_events.py": [
        rf"no listener, robot still\s+\d+\s+{NUMBER}\s+{NUMBER}",
        rf"no listener, robot moving\s+\d+\s+{NUMBER}\s+{NUMBER}",
        rf"\d+ listeners, robot moving\s+\d+\s+{NUMBER}\s+{NUMBER}",
        rf"robot events per listener: {NUMBER}/s",
    ],
    "bench_answer_times.py": [
        rf"stop during a paced push\s+1\s+{NUMBER}\s+{NUMBER}",
        rf"a new project with the default cell\s+5\s+{NUMBER}\s+{NUMBER}",
        rf"refuse a 6 M-face OBJ \(48 MB\)\s+1\s+{NUMBER}",
        rf"refuse the 5,000-link URDF\s+1\s+{NUMBER}",
        rf"refuse a project file number out of range\s+1\s+{NUMBER}",
        rf"refuse a language the arm does not run \(demo\)\s+1\s+{NUMBER}",
        rf"cut an isolated child hanging past 0.5 s\s+1\s+{NUMBER}",
    ],
    "bench_pointing.py": [
        rf"paced \(a person's wait\)\s+1\s+{NUMBER}\s+{NUMBER}\s+{NUMBER}",
        rf"unpaced \(planning only\)\s+1\s+{NUMBER}\s+{NUMBER}\s+{NUMBER}",
        r"points within 5 s \(paced\): \d of 1",
    ],
    "bench_soak.py": [
        rf"soak: {NUMBER} min, \d+ event readers, \d+ rounds",
        r"done: \d+ comparisons, \d+ uploads, \d+ cell changes; \d+ robot events read",
        rf"server RSS \d+-\d+ MiB, slope {NUMBER} MiB/min, last minus first {NUMBER} MiB",
    ],
    "bench_browser_pose_rate.py": [
        rf"handle\s+\d+ pose updates in {NUMBER} s: +{NUMBER} Hz",
        rf"rest\s+\d+ pose updates in {NUMBER} s: +{NUMBER} Hz",
    ],
}


def run_quick(script: str) -> str:
    """Run ``benchmarks/<script> --quick`` from the repository root; return its stdout."""
    env = {k: v for k, v in os.environ.items() if k != "ROBOMACH_TOKEN"}
    # The scripts import this checkout's packages, not an installed copy from elsewhere.
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])])
    done = subprocess.run(
        [sys.executable, f"benchmarks/{script}", "--quick"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
    )
    assert done.returncode == 0, f"{script} exited {done.returncode}:\n{done.stdout}\n{done.stderr}"
    return done.stdout


def assert_figures(script: str, out: str) -> None:
    for pattern in EXPECTED[script]:
        assert re.search(pattern, out), f"{script} did not print /{pattern}/:\n{out}"


def test_every_benchmark_has_a_quick_test():
    scripts = {p.name for p in (ROOT / "benchmarks").glob("bench_*.py")}
    assert scripts <= set(EXPECTED), f"no quick test for {sorted(scripts - set(EXPECTED))}"


# Quick modes that start a server, a process pool or an isolated helper: 10-30 s each.
SLOW_SCRIPTS = frozenset(
    {
        "bench_answer_times.py",
        "bench_api.py",
        "bench_events.py",
        "bench_machining.py",
        "bench_pointing.py",
        "bench_reads_during_postprocess.py",
        "bench_soak.py",
    }
)


@pytest.mark.parametrize(
    "script",
    [
        pytest.param(name, marks=[pytest.mark.slow] if name in SLOW_SCRIPTS else [])
        for name in sorted(EXPECTED)
        if name != "bench_browser_pose_rate.py"
    ],
)
def test_benchmark_runs_in_quick_mode(script):
    assert_figures(script, run_quick(script))


@pytest.mark.slow
def test_browser_benchmark_runs_in_quick_mode():
    if not Path("/usr/bin/chromium").exists() and shutil.which("chromium") is None:
        message = "chromium is not installed (apt-get install chromium chromium-driver)"
        if os.environ.get("CI"):
            pytest.fail(message)
        pytest.skip(message)
    script = "bench_browser_pose_rate.py"
    assert_figures(script, run_quick(script))
