"""Controller settings to and from JSON, and to the RAPID exporter's FC SpeedChange block."""

from __future__ import annotations

import json

import pytest

from robomach_core.cmrr import (
    CONTROLLER_NAMES,
    CmrrSettings,
    FuzzySettings,
    TwoStageSettings,
    build_scenario,
    cmrr_settings_for,
    load_settings,
    save_settings,
    settings_for,
    settings_from_dict,
    settings_to_dict,
    to_speed_change_settings,
)
from robomach_core.cmrr.errors import CmrrSettingsError


@pytest.mark.parametrize("name", CONTROLLER_NAMES)
def test_every_controller_round_trips_through_json(name, tmp_path):
    settings = cmrr_settings_for(build_scenario("deburr-burrs"), settings_for(name))
    data = json.loads(json.dumps(settings_to_dict(settings)))
    assert data["controller"] == name
    assert data["command_speed_mm_s"] == pytest.approx(100.0)
    assert settings_from_dict(data) == settings
    assert load_settings(save_settings(settings, tmp_path / "s.json")) == settings


def test_changed_settings_survive_the_round_trip():
    settings = CmrrSettings(
        FuzzySettings(stages=(0.25, 0.5, 1.0), max_rate_per_s=5.0), 180.0, 0.08, 0.2
    )
    back = settings_from_dict(settings_to_dict(settings))
    assert back.controller.stages == (0.25, 0.5, 1.0)
    assert back.controller.max_rate_per_s == 5.0


@pytest.mark.parametrize(
    "mutate",
    [
        lambda d: d.update(controller="nope"),
        lambda d: d["controller_settings"].update(bogus=1),
        lambda d: d.update(reference_force_N=-5),
        lambda d: d.pop("min_speed_ratio"),
        lambda d: d["controller_settings"].update(stages=[0.5, 0.2, 1.0]),
        lambda d: d.update(format="something-else"),
    ],
)
def test_malformed_settings_raise_a_settings_error(mutate):
    data = settings_to_dict(CmrrSettings(FuzzySettings(), 200.0, 0.1, 0.1))
    mutate(data)
    with pytest.raises(CmrrSettingsError):
        settings_from_dict(data)


def test_speed_change_block_maps_stages_and_reference():
    pytest.importorskip("robomach_core.export.rapid")
    fuzzy = to_speed_change_settings(CmrrSettings(FuzzySettings(), 200.0, 0.1, 0.1))
    assert (fuzzy.reference_force_N, fuzzy.speed_levels, fuzzy.min_speed_ratio) == (200.0, 5, 0.2)
    two = to_speed_change_settings(CmrrSettings(TwoStageSettings(), 250.0, 0.1, 0.1))
    assert (two.speed_levels, two.min_speed_ratio) == (2, 0.5)
    pi = to_speed_change_settings(CmrrSettings(settings_for("adaptive-pi"), 250.0, 0.03, 0.1))
    assert (pi.speed_levels, pi.min_speed_ratio) == (10, 0.1)
    assert (
        to_speed_change_settings(CmrrSettings(settings_for("constant"), 250.0, 0.03, 0.1)) is None
    )


def test_rapid_program_wraps_moves_in_fc_speed_change():
    rapid = pytest.importorskip("robomach_core.export.rapid")
    import inspect

    sc = to_speed_change_settings(CmrrSettings(TwoStageSettings(), 300.0, 0.1, 0.1))
    params = inspect.signature(rapid.RapidProgram).parameters
    if "speed_change" not in params:
        pytest.skip("RAPID exporter has no speed_change field")
    assert isinstance(sc, rapid.SpeedChangeSettings)
