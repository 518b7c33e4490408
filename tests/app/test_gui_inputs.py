"""The typed helpers the viser panels write their inputs and answer their clicks through, on a
real viser server in process: ``set_value`` is ``handle.value = value`` (the value, its type,
the listeners it calls), ``client_of`` the browser of a guarded callback's event. Over
generated values (a fresh seed each run; ``ROBOMACH_SEED`` replays one)."""

from __future__ import annotations

import numpy as np
import pytest
import viser

from app.gui.panels.feedback import client_of, guarded
from app.gui.panels.inputs import set_value
from tests.envelope import replay, run_seed

SEED = run_seed()


def test_set_value_writes_each_kind_of_input_and_calls_its_listeners(server) -> None:
    rng = np.random.default_rng(SEED)
    number = server.gui.add_number("n", 0.0, min=-1e3, max=1e3)
    checkbox = server.gui.add_checkbox("c", False)
    options = ("tool", "base", "wobj")
    dropdown = server.gui.add_dropdown("d", options, initial_value="tool")
    progress = server.gui.add_progress_bar(0.0)
    seen: list[object] = []
    for handle in (number, checkbox, dropdown):
        handle.on_update(lambda e: seen.append(e.target.value))
    for _ in range(20):
        value = round(float(rng.uniform(-1e3, 1e3)), int(rng.integers(0, 4)))
        flag = bool(rng.integers(0, 2))
        choice = options[int(rng.integers(0, len(options)))]
        percent = round(float(rng.uniform(0.0, 100.0)), 1)
        changed = [number.value != value, checkbox.value != flag, dropdown.value != choice]
        seen.clear()
        set_value(number, value)
        set_value(checkbox, flag)
        set_value(dropdown, choice)
        set_value(progress, percent)
        got = (number.value, checkbox.value, dropdown.value, progress.value)
        assert got == (value, flag, choice, percent), f"{replay(SEED)}: {got}"
        assert type(number.value) is float and type(checkbox.value) is bool, replay(SEED)
        # A listener hears a change, and only a change (as for an assignment).
        expected = [v for v, c in zip((value, flag, choice), changed, strict=True) if c]
        assert seen == expected, f"{replay(SEED)}: {seen} != {expected}"


def test_client_of_refuses_an_event_without_a_browser_and_guarded_never_passes_one(
    server,
) -> None:
    button = server.gui.add_button("b")
    event = viser.GuiEvent(client=None, client_id=None, target=button)
    with pytest.raises(RuntimeError, match="without a browser"):
        client_of(event)
    reached: list[object] = []
    guarded("Test", lambda e: reached.append(client_of(e)))(event)
    assert reached == []  # guarded drops a server-side event before the callback
