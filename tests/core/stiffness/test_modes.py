"""One compensation vocabulary (issue 30): ``off / offline / online`` and, for offline, a
``linear / nonlinear`` model; the old spellings are read by one rule or refused by name."""

from __future__ import annotations

import itertools
import json

import pytest

from robomach_core.cell import ToolGravity
from robomach_core.errors import InvalidInputError
from robomach_core.stiffness.errors import SettingsFileError
from robomach_core.stiffness.modes import (
    COMPENSATIONS,
    DEFAULT_OFFLINE_MODEL,
    OFFLINE_MODELS,
    read_compensation,
    variant_name,
)
from robomach_core.stiffness.settings import (
    SETTINGS_VERSION,
    CompensationSettings,
    load_settings,
    save_settings,
    settings_from_dict,
    settings_to_dict,
)

STIFFNESS = (1.1e6, 1.0e6, 7.2e5, 2.4e5, 2.6e5, 1.9e5)
GRAVITY = ToolGravity(2.5, (0.0, 0.001, 0.07))
# Every pair a user can set (the domain is finite: all of it, not a sample).
PAIRS = list(itertools.product(COMPENSATIONS, OFFLINE_MODELS))


@pytest.mark.parametrize(("compensation", "model"), PAIRS)
def test_every_pair_reads_back_as_itself(compensation, model):
    assert read_compensation(compensation, model) == (compensation, model)
    assert read_compensation(compensation) == (compensation, DEFAULT_OFFLINE_MODEL)
    # the one-word output name reads back to the pair (the model only where it matters)
    expected = model if compensation == "offline" else DEFAULT_OFFLINE_MODEL
    assert read_compensation(variant_name(compensation, model)) == (compensation, expected)


@pytest.mark.parametrize("model", OFFLINE_MODELS)
def test_an_old_spelling_is_offline_with_its_model(model):
    old = f"offline_{model}"
    assert read_compensation(old) == ("offline", model)
    assert read_compensation(old, model) == ("offline", model)
    other = next(m for m in OFFLINE_MODELS if m != model)
    with pytest.raises(InvalidInputError, match=f"means offline with the {model} model"):
        read_compensation(old, other)
    assert read_compensation("none") == ("off", DEFAULT_OFFLINE_MODEL)
    assert read_compensation("none", model) == ("off", model)


@pytest.mark.parametrize("value", ["sometimes", "OFF", "", None, 1, "offline_quadratic"])
def test_anything_else_is_refused_naming_the_choices(value):
    with pytest.raises(InvalidInputError, match="choose one of off, offline, online"):
        read_compensation(value)
    with pytest.raises(InvalidInputError, match="linear, nonlinear"):
        read_compensation("offline", "quadratic")


def test_the_dataclass_takes_only_the_one_vocabulary():
    with pytest.raises(SettingsFileError, match="offline_model"):
        CompensationSettings("ur10", STIFFNESS, mode="offline_linear")  # type: ignore[arg-type]
    with pytest.raises(SettingsFileError, match="linear, nonlinear"):
        CompensationSettings("ur10", STIFFNESS, mode="offline", offline_model="eq32")  # type: ignore[arg-type]


@pytest.mark.parametrize(("compensation", "model"), PAIRS)
def test_settings_round_trip_every_pair(tmp_path, compensation, model):
    gravity = GRAVITY if compensation == "online" else None
    settings = CompensationSettings(
        "ur10", STIFFNESS, mode=compensation, offline_model=model, tool_gravity=gravity
    )
    path = save_settings(settings, tmp_path / "settings.json")
    doc = json.loads(path.read_text())
    assert doc["version"] == SETTINGS_VERSION
    assert (doc["mode"], doc["offline_model"]) == (compensation, model)
    assert load_settings(path) == settings


@pytest.mark.parametrize("model", OFFLINE_MODELS)
def test_a_version_1_file_reads_by_the_rule(tmp_path, model):
    """What robomach wrote before (version 1, the model in the mode) is read, not refused, and
    written back in the one vocabulary."""
    current = settings_to_dict(CompensationSettings("ur10", STIFFNESS, mode="offline"))
    old = {k: v for k, v in current.items() if k != "offline_model"}
    old |= {"version": 1, "mode": f"offline_{model}"}
    path = tmp_path / "old.json"
    path.write_text(json.dumps(old))
    back = load_settings(path)
    assert (back.mode, back.offline_model) == ("offline", model)
    assert settings_to_dict(back)["mode"] == "offline"
    with pytest.raises(SettingsFileError, match="means offline"):
        other = next(m for m in OFFLINE_MODELS if m != model)
        settings_from_dict(old | {"offline_model": other})
    with pytest.raises(SettingsFileError, match="version 3 is not supported"):
        settings_from_dict(old | {"version": 3})
