"""Machining settings: physical ranges with the range in the message, the safe constant feed."""

from __future__ import annotations

import pytest

from robomach_core.errors import InvalidInputError
from robomach_core.limits import MACHINING_FORCE_LIMIT_N
from robomach_core.machining import MachiningSettings, MachiningSettingsError

MM = 1e-3


@pytest.mark.parametrize(
    ("field", "value", "words"),
    [
        ("process_gain_N", 0.0, "process_gain_N must be in [0.1, 10000] N"),
        ("feed_exponent", 3.0, "feed_exponent must be in [0.01, 2]"),
        ("force_limit_N", -5.0, "force_limit_N must be in [1.5, 1400] N"),
        ("command_speed_cap_m_s", 1.0, "command_speed_cap_m_s must be in [0.001, 0.5] m/s"),
        ("min_speed_ratio", 1.5, "min_speed_ratio must be in [0.01, 0.99]"),
        ("sensor_noise_N", float("nan"), "sensor_noise_N must be in [0, 50] N"),
        ("reference_force_N", 400.0, "within 1-150 N (at most the force limit)"),
        ("reference_force_N", 0.7, "within 1-150 N (at most the force limit)"),
        ("controller", "pid", "choose one of constant, fixed-pi"),
        ("compensation", "both", "choose one of off, offline, online"),
        ("max_samples", 10, "max_samples must be an integer in [1000"),
    ],
)
def test_out_of_range_settings_name_the_range(field, value, words):
    with pytest.raises(MachiningSettingsError) as info:
        MachiningSettings(**{field: value})
    assert words in str(info.value)
    assert isinstance(info.value, InvalidInputError)


def test_safe_constant_feed_is_the_inverse_of_the_lab_fit_at_the_deepest_cut():
    s = MachiningSettings(force_limit_N=150.0, command_speed_cap_m_s=0.05)
    # f = (F_lim / (23 d^0.9))^(1/0.5) with d = 4 mm: (150 / (23 * 4^0.9))^2 = 3.508 mm/s.
    assert s.safe_constant_feed_m_s(4.0 * MM) / MM == pytest.approx(3.508, abs=0.001)
    assert s.process.steady_force(4.0 * MM, s.safe_constant_feed_m_s(4.0 * MM)) == pytest.approx(
        150.0
    )
    # Capped by the command speed where the stock is thin.
    assert s.safe_constant_feed_m_s(0.1 * MM) == pytest.approx(0.05)


def test_reference_defaults_below_the_limit():
    assert MachiningSettings(force_limit_N=200.0).reference_N == pytest.approx(140.0)
    assert MachiningSettings(reference_force_N=90.0).reference_N == 90.0


def test_settings_dict_is_json_ready_with_units_in_the_keys():
    import json

    from robomach_core.machining import settings_to_dict

    data = json.loads(json.dumps(settings_to_dict(MachiningSettings(controller="fuzzy"))))
    assert data["controller"] == "fuzzy" and data["force_limit_N"] == 150.0
    assert data["command_speed_cap_m_s"] == 0.01 and data["controller_settings"] is None


@pytest.mark.parametrize("limit", [MACHINING_FORCE_LIMIT_N.min, 150.0, MACHINING_FORCE_LIMIT_N.max])
@pytest.mark.parametrize("controller", ["fixed-pi", "two-stage"])
def test_every_advertised_force_limit_is_accepted_by_the_cmrr_settings_the_choice_makes(
    limit, controller
):
    """Issue 19 R12: a force limit inside its advertised range was refused under another
    field's name ("reference_force_N ... got 0.7"): the default Fr = 0.7 x limit left the CMRR
    range. Both ends of the advertised range now pass every layer the choice goes through."""
    from robomach_core.cmrr import settings_from_dict, settings_to_dict
    from robomach_core.project._machining import cmrr_for

    settings = MachiningSettings(force_limit_N=limit, controller=controller)
    cmrr = cmrr_for(settings)
    assert cmrr.reference_force_N == pytest.approx(0.7 * limit)
    assert settings_from_dict(settings_to_dict(cmrr)).reference_force_N == cmrr.reference_force_N
