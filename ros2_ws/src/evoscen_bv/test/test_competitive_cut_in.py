"""``models.learned.competitive_cut_in`` (docs/learned-bvs.md, "Competitive BVs and a SUT cutting in"):
the scenario key, its default and the old rule kept selectable. The rule itself, by hand:
test_car_following.py::test_a_competitive_bv_does_not_yield_to_the_sut_cutting_in_until_its_body_is_in_the_lane."""

from __future__ import annotations

import pytest
from evoscen_bringup.model_testing import commands_digest
from evoscen_sim.errors import InputError

BEFORE_COMMANDS_SHA256 = "32c3b0ffe38757126b4fba35ad04a0bfe3337e84ca1f40da26067bd612179748"
"""Every BV and SUT command of 1,000 steps of the default scenario with learned BVs, seed 3, SUT mobil,
computed with the code before the key existed (main at a70f887: every BV yielded on the SUT's intent)."""


def test_yield_drives_exactly_as_before_and_compete_is_the_default():
    from evoscen_sim.config.scenario_config import config_from_dict
    from evoscen_sim.scenario_builders import build_bv_driver

    assert build_bv_driver(config_from_dict({"bvs": {"driver": "learned", "makeup": "uniform"}})).compete_with_sut is True
    assert build_bv_driver(config_from_dict({"bvs": {"driver": "learned", "makeup": "uniform"}, "models": {
        "learned": {"competitive_cut_in": "yield"}}})).compete_with_sut is False
    # with the earlier entry rule too (traffic.entry_retry_s: 0, uniform's before evoscen 0.8)
    assert commands_digest({"bvs.driver": "learned", "bvs.makeup": "uniform", "models.learned.competitive_cut_in": "yield",
                            "traffic.entry_retry_s": 0}, 1000) == BEFORE_COMMANDS_SHA256
    # seed 3: MOBIL cuts in ahead of a competitive BV within the first 1,000 steps, so the default differs
    assert commands_digest({"bvs.driver": "learned", "bvs.makeup": "uniform"}, 1000) != BEFORE_COMMANDS_SHA256


def test_rule_based_bvs_ignore_the_key():
    for driver in ("level0", "mobil"):
        assert commands_digest({"bvs.driver": driver, "models.learned.competitive_cut_in": "yield"}, 200) \
            == commands_digest({"bvs.driver": driver, "models.learned.competitive_cut_in": "compete"}, 200), driver


def test_a_bad_value_is_one_line_naming_the_key():
    from evoscen_sim.config.scenario_config import config_from_dict

    with pytest.raises(InputError) as err:
        config_from_dict({"models": {"learned": {"competitive_cut_in": "always"}}})
    msg = str(err.value)
    assert "\n" not in msg and "models.learned.competitive_cut_in" in msg and "compete" in msg and "yield" in msg
