"""The UR program's CMRR feed loop runs the controller the simulation ran: its law, read from
the written program and executed (a line-by-line translation of the URScript subset it is
written in), gives the compiled controller's speed ratio and state at every period, for every
controller as the machining design makes it, over generated force and feed signals."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robomach_core.cell import Robot, Tool
from robomach_core.export.urscript import script_numbers, script_poses, urscript_program
from robomach_core.export.urscript_feed import (
    LAW_BEGIN,
    LAW_END,
    UrFeedLoop,
    fill_lq_table,
    law_lines,
    law_state_lines,
)
from robomach_core.machining import MachiningSettings, builtin_stock, targets_along_wall
from robomach_core.machining import _kernel as K
from robomach_core.machining.run import plan_cut
from robomach_core.part import builtin_workpiece
from robomach_core.postprocess import Targets

KINDS = ("fixed-pi", "adaptive-pi", "fuzzy", "two-stage", "adaptive-lq")


@pytest.fixture(scope="module")
def robot() -> Robot:
    return Robot("ur10", Tool().T_flange_tcp)


@pytest.fixture(scope="module")
def short_program(robot: Robot) -> Targets:
    """The first ~120 mm along the water pump's true wall."""
    wall = targets_along_wall(robot, builtin_workpiece("water_pump"), tool_radius_m=0.001)
    return Targets(**{k: np.asarray(getattr(wall, k))[:61] for k in wall.__dataclass_fields__})


def python_of(urscript: list[str]) -> str:
    """The URScript subset the loop is written in, as Python: blocks closed by ``end`` become
    indentation; ``log(b, f)``, ``pow``, ``sqrt``, ``floor`` as URScript defines them."""
    out, depth = [], 0
    for raw in urscript:
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if line == "end":
            depth -= 1
            continue
        if line.startswith(("elif ", "else:")):
            out.append("    " * (depth - 1) + line)
            continue
        out.append("    " * depth + line)
        if line.endswith(":") and line.split()[0] in ("if", "while"):
            depth += 1
    assert depth == 0, "unbalanced blocks"
    return "\n".join(out)


NAMESPACE = {
    "log": lambda b, f: math.log(f) / math.log(b),
    "pow": lambda b, e: float(b) ** float(e),
    "sqrt": math.sqrt,
    "floor": lambda x: int(math.floor(x)),
    "True": True,
    "False": False,
}


def _designed(kind: str, robot, short_program):
    stock = builtin_stock(short_program.position_m, seed=0)
    plan = plan_cut(robot, short_program, None, stock, MachiningSettings(controller=kind))
    packed = copy.deepcopy(plan.packed)
    if packed.kind == K.KIND_LQ:
        fill_lq_table(packed)
    return plan, packed


def _kernel_step(packed, fs: np.ndarray, force: float, feed: float) -> tuple[float, bool]:
    p = packed
    if p.kind == K.KIND_FIXED_PI:
        return K._fixed_pi_step(p.fp, fs, force), False
    if p.kind == K.KIND_ADAPTIVE_PI:
        return K._adaptive_pi_step(p.fp, fs, force, feed), False
    if p.kind == K.KIND_FUZZY:
        return K._fuzzy_step(
            p.fp, fs, p.stages, p.rules, p.set_idx, p.set_val, p.universe, np.zeros(16), force
        )
    ratio, need = K._lq_step(
        p.fp, fs, p.lq_mats, p.lq_vecs, p.lq_gains, p.lq_ff, p.lq_have, p.lq_index0, force, feed
    )
    if need != -(2**62):
        pytest.skip("Df_hat left the program's table of designs")  # not in these signals
    return ratio, False


signals = st.lists(
    st.tuples(st.floats(0.0, 400.0), st.floats(0.0, 0.012)), min_size=20, max_size=200
)


@given(signals, st.sampled_from(KINDS))
@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_the_programs_law_is_the_simulated_controller(robot, short_program, values, kind):
    _, packed = _designed(kind, robot, short_program)
    loop = UrFeedLoop(kind, 105.0, packed, (1, 0, 0, 1, 0, 0), (0.0, 0.0), 0.004, 0.05, 150.0)
    namespace = dict(NAMESPACE)
    exec(python_of(law_state_lines(loop)), namespace)  # noqa: S102 - the program's own text
    law = compile(python_of(law_lines(packed.kind)), "law", "exec")
    fs = packed.fs.copy()
    for force, feed in values:
        namespace["cm_fs"] = fs.tolist()  # both from the simulation's state
        namespace.update(cm_f=force, cm_v=feed)
        exec(law, namespace)  # noqa: S102
        ratio, stop = _kernel_step(packed, fs, force, feed)
        assert namespace["cm_next"] == pytest.approx(ratio, rel=1e-9, abs=1e-12), (force, feed)
        assert namespace["cm_stop"] == stop
        np.testing.assert_allclose(namespace["cm_fs"], fs, rtol=1e-9, atol=1e-12)


def test_the_written_loop_carries_the_path_the_speeds_and_the_law(robot, short_program):
    """A UR program with a feed loop: its path list is the targets, its speeds the programmed
    ones, the law between its markers, blocks balanced; the program reads the wrench, steps
    by servoj and stops on the supervision and the protection rule."""
    plan, packed = _designed("fuzzy", robot, short_program)
    i = plan.inputs
    loop = UrFeedLoop("fuzzy", 105.0, packed, tuple(i.filt), tuple(i.filt_z), i.dt, 0.05, 150.0)
    pump = builtin_workpiece("water_pump", robot="ur10")
    text = urscript_program(short_program, Tool(), pump, feed_loop=loop)
    path = next(poses for kind, poses in script_poses(text) if kind == "path")
    np.testing.assert_allclose([p[:3] for p in path], short_program.position_m, atol=1e-7)
    speeds = script_numbers(text, "cm_speed")
    np.testing.assert_allclose(speeds, short_program.speed_m_s, atol=1e-10)
    lines = text.splitlines()
    body = lines[1:-1]
    assert lines[0].startswith("def ") and lines[-1] == "end"
    python_of(body)  # balanced
    begin = next(k for k, line in enumerate(lines) if line.strip() == LAW_BEGIN)
    end = next(k for k, line in enumerate(lines) if line.strip() == LAW_END)
    assert [line.strip() for line in lines[begin : end + 1]] == [
        line.strip() for line in law_lines(packed.kind)
    ]
    for call in ("get_tcp_force()", "zero_ftsensor()", "servoj(", "interpolate_pose(", "halt"):
        assert call in text, call
    assert not any(line.strip().startswith("movel(p[") for line in lines[12:-3])


def test_a_feed_loop_reads_back_with_its_law_or_is_refused_without_it(robot, short_program):
    """Read back, the loop names its controller and force; a loop whose '# CMRR:' line is gone
    is refused with a message (it was an AttributeError)."""
    from robomach_core.errors import InvalidInputError
    from robomach_core.export.read_back import read_program

    plan, packed = _designed("fuzzy", robot, short_program)
    i = plan.inputs
    loop = UrFeedLoop("fuzzy", 105.0, packed, tuple(i.filt), tuple(i.filt_z), i.dt, 0.05, 150.0)
    pump = builtin_workpiece("water_pump", robot="ur10")
    text = urscript_program(short_program, Tool(), pump, feed_loop=loop)
    path = read_program("urscript", {"cut.script": text})
    assert (path.feed_control, path.reference_N, path.controller) == (
        "URScript feed loop", 105.0, "fuzzy",
    )  # fmt: skip
    without = "\n".join(line for line in text.splitlines() if "# CMRR:" not in line)
    assert without != text
    with pytest.raises(InvalidInputError, match="no '# CMRR:"):
        read_program("urscript", {"cut.script": without})
