"""The order a program meets the guide points in (``walk.met_order``): a loop that went round
another wall, or the other way round, meets its points out of order though every wall point
it reads off its own walk is passed (issue 28: a sparse loop round an island went round the
groove's outer wall the other way and passed, 4.0 mm off). Properties over generated loops and
open stretches (ellipses with a wobble, sampled as a program is), points 0-5 mm off them, some
two at one station; a fresh seed each run (``ROBOMACH_SEED`` replays it)."""

from __future__ import annotations

import numpy as np

from robomach_core.learning.walk import met_order
from robomach_core.transforms import arc_length_m
from tests.envelope import replay, run_seed

SEED = run_seed()
AXIS = np.array([0.0, 0.0, -1.0])


def _contour(rng: np.random.Generator, closed: bool) -> tuple[np.ndarray, callable]:
    """A program's points every 0.25 mm (m) and the point at a share of its length."""
    a, b = rng.uniform(0.03, 0.15, 2)
    wobble = rng.uniform(0.0, 0.005)
    span = 2 * np.pi if closed else rng.uniform(0.5, 1.5) * np.pi
    t0 = rng.uniform(0, 2 * np.pi)

    def at(u: np.ndarray) -> np.ndarray:
        t = t0 + np.asarray(u) * span
        r = 1.0 + wobble / max(a, b) * np.sin(7 * t)
        return np.column_stack([a * r * np.cos(t), b * r * np.sin(t), np.full(np.size(t), 0.01)])

    n = int(2 * np.pi * max(a, b) / 2.5e-4)
    return at(np.linspace(0.0, 1.0, n)), at


def _places(at, shares: np.ndarray, rng: np.random.Generator) -> list[np.ndarray]:
    out = []
    for u in shares:
        p, q = at(np.array([u - 1e-4, u + 1e-4]))
        tangent = (q - p) / np.linalg.norm(q - p)
        across = np.cross(AXIS, tangent)
        out.append(at(np.array([u]))[0] + across * rng.uniform(-0.003, 0.003))
    return out


def _shares(rng: np.random.Generator, closed: bool) -> np.ndarray:
    n = int(rng.integers(3, 12))
    u = np.sort(rng.uniform(0.0, 1.0 if closed else 0.98, n))
    if not closed:
        u[0] = 0.0
    if rng.random() < 0.5:  # two points at one station
        k = int(rng.integers(0, n))
        u = np.insert(u, k + 1, u[k])
    return u


def test_points_met_in_the_order_taught_are_in_order():
    rng = np.random.default_rng(SEED)
    for case in range(150):
        closed = bool(rng.random() < 0.6)
        program, at = _contour(rng, closed)
        shares = _shares(rng, closed)
        if closed:
            shares = np.roll(shares, int(rng.integers(0, len(shares))))  # any point first
        found = met_order(_places(at, shares, rng), program, AXIS, closed)
        assert found is None, f"{replay(SEED)}, case {case}: in order, but met as {found}"


def test_points_met_round_the_other_way_are_out_of_order():
    rng = np.random.default_rng(SEED + 1)
    for case in range(150):
        closed = bool(rng.random() < 0.6)
        program, at = _contour(rng, closed)
        shares = _shares(rng, closed)
        stations = np.unique(np.round(shares, 3))
        length = float(arc_length_m(program)[-1])
        apart = np.diff(stations)
        if closed:  # round the loop too: shares 0.999 and 0.005 are one station
            apart = np.append(apart, 1.0 - stations[-1] + stations[0])
        if len(stations) < 3 or np.min(apart) * length < 0.02:
            continue  # the stations a step back of two points in place could hide
        found = met_order(_places(at, shares[::-1], rng), program, AXIS, closed)
        assert found is not None, f"{replay(SEED)}, case {case}: reversed, but found in order"
