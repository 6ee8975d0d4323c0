"""Scenario configuration: defaults, validation errors, overrides, round trip, mix split."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import yaml
from evoscen_sim import model_registry as registry
from evoscen_sim.config.scenario_config import (
    POLICIES,
    BvConfig,
    ScenarioConfig,
    config_from_dict,
    config_to_dict,
    dump_config,
    load_scenario_config,
    mix_counts,
    register_sut_model,
    resolve_map_path,
    share_path,
)
from evoscen_sim.errors import InputError

SHIPPED_DEFAULT = share_path("config/default_scenario.yaml")


@pytest.fixture
def scenario_dir(tmp_path: Path) -> Path:
    """A directory holding a (dummy) map next to where the test writes scenario.yaml."""
    (tmp_path / "onramp.xodr").write_text("<OpenDRIVE/>\n")
    return tmp_path


def write(directory: Path, text: str, name: str = "scenario.yaml") -> Path:
    path = directory / name
    path.write_text(text)
    return path


def load_error(directory: Path, text: str, overrides=None) -> str:
    path = write(directory, text)
    with pytest.raises(InputError) as info:
        load_scenario_config(path, overrides)
    message = str(info.value)
    assert "\n" not in message
    return message


# --- defaults -------------------------------------------------------------------------------


def test_shipped_default_loads_with_the_documented_defaults():
    cfg = load_scenario_config()
    expected = dataclasses.replace(ScenarioConfig(), map=cfg.map)
    assert cfg == expected
    assert Path(cfg.map).is_absolute() and Path(cfg.map).name == "onramp.xodr"
    assert Path(cfg.map).is_file()
    assert cfg.dt_s == 0.1 and cfg.steps == 3000 and cfg.seed == 0
    assert cfg.bvs.count == 20 and cfg.bvs.mix == {"competitive": 4, "mutual": 3, "cooperative": 3}
    assert cfg.spawn.speed_mps == (24.0, 30.0)
    assert cfg.level0.desired_speed_mps == (27.0, 33.0)
    assert cfg.recording.compression == "zstd" and cfg.recording.enabled is True


def test_shipped_default_lists_every_key():
    data = yaml.safe_load(SHIPPED_DEFAULT.read_text())
    assert data == config_to_dict(ScenarioConfig())


def test_missing_keys_take_defaults(scenario_dir):
    cfg = load_scenario_config(write(scenario_dir, "steps: 50\nbvs:\n  count: 5\n"))
    assert cfg.steps == 50 and cfg.bvs.count == 5
    assert cfg.dt_s == 0.1 and cfg.bvs.mix == {"competitive": 4, "mutual": 3, "cooperative": 3}
    assert cfg.vehicle == ScenarioConfig().vehicle
    assert cfg.map == str((scenario_dir / "onramp.xodr").resolve())  # relative to the file


def test_empty_section_means_defaults(scenario_dir):
    cfg = load_scenario_config(write(scenario_dir, "sut:\n  # model: level0\n"))
    assert cfg.sut == ScenarioConfig().sut


def test_ints_are_accepted_for_floats_and_stored_as_float(scenario_dir):
    cfg = load_scenario_config(write(scenario_dir, "sut: {s_m: 100}\nspawn: {speed_mps: [20, 25]}\n"))
    assert cfg.sut.s_m == 100.0 and isinstance(cfg.sut.s_m, float)
    assert cfg.spawn.speed_mps == (20.0, 25.0)


def test_yaml_quirks_mix_string_unquoted_and_exponent_floats(scenario_dir):
    # YAML 1.1 would read 3:4:3 as the base-60 integer 11043 and 1e-2 as a string
    cfg = load_scenario_config(write(scenario_dir, "dt_s: 1e-2\nbvs:\n  mix: 3:4:3\n"))
    assert cfg.dt_s == 0.01
    assert cfg.bvs.mix == {"competitive": 3, "mutual": 4, "cooperative": 3}


def test_mix_mapping_missing_policies_are_zero(scenario_dir):
    cfg = load_scenario_config(write(scenario_dir, "bvs:\n  mix: {mutual: 1}\n"))
    assert cfg.bvs.mix == {"competitive": 0, "mutual": 1, "cooperative": 0}
    assert list(cfg.bvs.mix) == list(POLICIES)


# --- errors ---------------------------------------------------------------------------------


def test_wrong_type(scenario_dir):
    message = load_error(scenario_dir, 'steps: "ten"\n')
    assert message == (f"{scenario_dir / 'scenario.yaml'}: key 'steps' = 'ten': "
                       "expected an integer in [1, 1000000] (line 1)")
    assert "'dt_s' = 'fast'" in load_error(scenario_dir, "dt_s: fast\n")
    assert "'name' = 5" in load_error(scenario_dir, "name: 5\n")


def test_negative_steps_names_file_key_value_line(scenario_dir):
    message = load_error(scenario_dir, "name: x\nsteps: -5\n")
    assert message == (f"{scenario_dir / 'scenario.yaml'}: key 'steps' = -5: "
                       "expected an integer in [1, 1000000] (line 2)")


def test_bool_is_not_an_int(scenario_dir):
    message = load_error(scenario_dir, "bvs:\n  count: true\n")
    assert "scenario.yaml" in message and "'bvs.count' = True" in message
    assert "expected an integer in [0, 200]" in message


def test_number_where_bool_expected(scenario_dir):
    message = load_error(scenario_dir, "recording: {enabled: 1}\n")
    assert "'recording.enabled' = 1" in message and "boolean" in message


def test_out_of_range_values(scenario_dir):
    assert "'dt_s' = 0" in load_error(scenario_dir, "dt_s: 0\n")
    assert "[1e-06, 1]" in load_error(scenario_dir, "dt_s: 1.5\n")
    assert "'sut.lane' = 0" in load_error(scenario_dir, "sut: {lane: 0}\n")
    assert "'bvs.count' = 201" in load_error(scenario_dir, "bvs: {count: 201}\n")
    assert "'reentry.ramp_share' = 1.2" in load_error(scenario_dir, "reentry: {ramp_share: 1.2}\n")
    assert "'vehicle.length_m' = 0" in load_error(scenario_dir, "vehicle: {length_m: 0}\n")
    assert "'seed' = nan" in load_error(scenario_dir, "seed: .nan\n")


def test_unknown_key_lists_allowed_and_suggests(scenario_dir):
    message = load_error(scenario_dir, "bvs:\n  cuont: 3\n")
    assert "scenario.yaml" in message and "'bvs.cuont'" in message
    assert "allowed keys: count, mix, driver" in message
    assert "did you mean 'count'?" in message
    assert "(line 2)" in message


def test_unknown_top_level_key(scenario_dir):
    message = load_error(scenario_dir, "stpes: 10\n")
    assert "'stpes'" in message and "did you mean 'steps'?" in message


def test_unknown_sut_model_lists_valid_choices(scenario_dir):
    message = load_error(scenario_dir, "sut:\n  model: mobli\n")
    assert "scenario.yaml" in message and "'sut.model' = 'mobli'" in message
    assert "expected one of level0" in message


def test_registered_models_become_valid(scenario_dir, monkeypatch):
    monkeypatch.setattr(registry, "SUT_MODELS", registry.SUT_MODELS)
    register_sut_model("my_sut")
    assert load_scenario_config(write(scenario_dir, "sut: {model: my_sut}\n")).sut.model == "my_sut"
    message = load_error(scenario_dir, "sut: {model: my_stu}\n")
    assert "expected one of level0" in message and "my_sut; did you mean 'my_sut'?" in message


def test_bad_mix_string(scenario_dir):
    message = load_error(scenario_dir, 'bvs:\n  mix: "4:3"\n')
    assert "scenario.yaml" in message and "'bvs.mix' = '4:3'" in message
    assert "'4:3:3'" in message


def test_bad_mix_entries(scenario_dir):
    message = load_error(scenario_dir, "bvs:\n  mix: {competitive: -1}\n")
    assert "'bvs.mix.competitive' = -1" in message and "non-negative integer" in message
    message = load_error(scenario_dir, "bvs:\n  mix: {competetive: 1}\n")
    assert "'bvs.mix.competetive'" in message and "did you mean 'competitive'?" in message


def test_mix_all_zero_with_vehicles(scenario_dir):
    message = load_error(scenario_dir, 'bvs: {mix: "0:0:0"}\n')
    assert "'bvs.mix'" in message and "bvs.count = 20" in message
    # no vehicles: an all-zero mix is fine
    cfg = load_scenario_config(write(scenario_dir, 'bvs: {count: 0, mix: "0:0:0"}\nspawn: {ramp_vehicles: 0}\n'))
    assert mix_counts(cfg) == {"competitive": 0, "mutual": 0, "cooperative": 0}


def test_ramp_vehicles_at_most_count(scenario_dir):
    message = load_error(scenario_dir, "bvs: {count: 2}\nspawn: {ramp_vehicles: 3}\n")
    assert "'spawn.ramp_vehicles' = 3" in message and "bvs.count = 2" in message
    assert "(line 2)" in message
    message = load_error(scenario_dir, "bvs: {count: 2}\n")  # default ramp_vehicles 3 > 2
    assert "'spawn.ramp_vehicles' = 3 (default)" in message


def test_speed_range_must_be_ordered_and_bounded(scenario_dir):
    message = load_error(scenario_dir, "spawn:\n  speed_mps: [30, 24]\n")
    assert "'spawn.speed_mps' = [30, 24]" in message and "lo <= hi" in message
    assert "'spawn.speed_mps'" in load_error(scenario_dir, "spawn: {speed_mps: [10, 50]}\n")
    assert "'spawn.speed_mps'" in load_error(scenario_dir, "spawn: {speed_mps: 25}\n")
    assert "'level0.desired_speed_mps'" in load_error(
        scenario_dir, "level0: {desired_speed_mps: [0, 30]}\n")


def test_section_must_be_a_mapping(scenario_dir):
    message = load_error(scenario_dir, "vehicle: 5\n")
    assert "'vehicle' = 5" in message and "length_m" in message


def test_yaml_syntax_error_names_file_and_line(scenario_dir):
    message = load_error(scenario_dir, "name: x\nsteps: 10\nbvs:\n  count: [1, 2\n  mix: x\n")
    assert "scenario.yaml" in message and "YAML syntax error at line" in message
    message = load_error(scenario_dir, "name: x\nsteps: 10\n  bad: 1\n")
    assert "scenario.yaml: YAML syntax error at line 3" in message


def test_duplicate_key(scenario_dir):
    message = load_error(scenario_dir, "steps: 1\nsteps: 2\n")
    assert "'steps' appears twice (line 2)" in message


def test_top_level_not_a_mapping(scenario_dir):
    assert "top level" in load_error(scenario_dir, "- 1\n- 2\n")
    assert "top level" in load_error(scenario_dir, "")
    assert "scenario.yaml" in load_error(scenario_dir, "just text\n")


def test_missing_map_file(scenario_dir):
    message = load_error(scenario_dir, "map: nowhere.xodr\n")
    assert "scenario.yaml" in message and "'map' = 'nowhere.xodr'" in message
    assert "file not found" in message and "(line 1)" in message


def test_missing_config_file(tmp_path):
    with pytest.raises(InputError, match="missing.yaml: scenario config file not found"):
        load_scenario_config(tmp_path / "missing.yaml")


def test_map_resolution_order(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "local.xodr").write_text("")
    assert resolve_map_path("sub/local.xodr", tmp_path) == (tmp_path / "sub" / "local.xodr").resolve()
    absolute = str((tmp_path / "sub" / "local.xodr").resolve())
    assert resolve_map_path(absolute, "/nonexistent") == Path(absolute)
    # not next to the config: found under the package's maps/
    assert resolve_map_path("onramp.xodr", tmp_path) == share_path("maps/onramp.xodr")
    with pytest.raises(InputError, match="map 'nope.xodr': file not found"):
        resolve_map_path("nope.xodr", tmp_path)


def test_share_path_missing_file():
    with pytest.raises(InputError, match="'config/nope.yaml': not found"):
        share_path("config/nope.yaml")


# --- overrides ------------------------------------------------------------------------------


def test_overrides_apply_before_validation(scenario_dir):
    path = write(scenario_dir, "steps: 10\n")
    cfg = load_scenario_config(path, {"steps": 200, "bvs.count": 10, "bvs.mix": "3:4:3",
                                      "spawn.speed_mps": [20, 22], "sut.lane": 4})
    assert cfg.steps == 200 and cfg.bvs.count == 10 and cfg.sut.lane == 4
    assert cfg.bvs.mix == {"competitive": 3, "mutual": 4, "cooperative": 3}
    assert cfg.spawn.speed_mps == (20.0, 22.0)
    assert mix_counts(cfg) == {"competitive": 3, "mutual": 4, "cooperative": 3}


def test_overrides_as_command_line_text(scenario_dir):
    path = write(scenario_dir, "steps: 10\n")
    cfg = load_scenario_config(path, {"steps": "200", "recording.enabled": "false",
                                      "spawn.speed_mps": "[20, 22]", "name": "123"})
    assert cfg.steps == 200 and cfg.recording.enabled is False
    assert cfg.spawn.speed_mps == (20.0, 22.0) and cfg.name == "123"


def test_override_on_the_shipped_default():
    cfg = load_scenario_config(None, {"steps": 200})
    assert cfg.steps == 200 and cfg.bvs.count == 20


def test_override_errors_name_the_command_line(scenario_dir):
    path = write(scenario_dir, "steps: 10\n")
    with pytest.raises(InputError) as info:
        load_scenario_config(path, {"sut.model": "foo"})
    message = str(info.value)
    assert message.startswith("command line: key 'sut.model' = 'foo': expected one of level0")
    assert "scenario.yaml" in message

    with pytest.raises(InputError, match=r"command line: key 'steps' = -1: expected an integer in \[1, 1000000\]"):
        load_scenario_config(path, {"steps": -1})
    with pytest.raises(InputError, match=r"command line: key 'steps' = 'ten'"):
        load_scenario_config(path, {"steps": "ten"})
    with pytest.raises(InputError, match=r"command line: key 'bvs.mix' = '4:3'"):
        load_scenario_config(path, {"bvs.mix": "4:3"})
    with pytest.raises(InputError, match=r"command line: key 'sut.modle'.*did you mean 'model'"):
        load_scenario_config(path, {"sut.modle": "level0"})
    with pytest.raises(InputError, match=r"command line: key 'steps.x'.*not a mapping"):
        load_scenario_config(path, {"steps.x": 1})
    with pytest.raises(InputError, match=r"command line: override key '' "):
        load_scenario_config(path, {"": 1})
    with pytest.raises(InputError, match=r"command line: key 'map' = 'zz.xodr'"):
        load_scenario_config(path, {"map": "zz.xodr"})


def test_override_causing_cross_field_error_says_so(scenario_dir):
    path = write(scenario_dir, "spawn:\n  ramp_vehicles: 3\n")
    with pytest.raises(InputError) as info:
        load_scenario_config(path, {"bvs.count": 1})
    message = str(info.value)
    assert "'spawn.ramp_vehicles' = 3" in message
    assert "bvs.count = 1 (set on the command line)" in message


def test_file_errors_are_not_blamed_on_the_command_line(scenario_dir):
    path = write(scenario_dir, "steps: -5\n")
    with pytest.raises(InputError, match=r"scenario.yaml: key 'steps' = -5"):
        load_scenario_config(path, {"seed": 3})


# --- round trip ----------------------------------------------------------------------------


def test_dump_load_round_trip(scenario_dir, tmp_path_factory):
    original = load_scenario_config(
        write(scenario_dir, "name: rt\nsteps: 123\ndt_s: 0.05\nbvs: {count: 7, mix: '1:1:1'}\n"
                            "spawn: {ramp_vehicles: 2, speed_mps: [21.5, 29.25]}\n"
                            "recording: {enabled: false, compression: lz4}\n"))
    out_dir = tmp_path_factory.mktemp("bag")
    dump_config(original, out_dir / "scenario.yaml")
    reloaded = load_scenario_config(out_dir / "scenario.yaml")
    assert reloaded == original
    assert config_to_dict(reloaded) == config_to_dict(original)


def test_config_to_dict_is_plain_yaml():
    data = config_to_dict(ScenarioConfig())
    assert data["spawn"]["speed_mps"] == [24.0, 30.0]
    assert data["bvs"]["mix"] == {"competitive": 4, "mutual": 3, "cooperative": 3}
    assert yaml.safe_load(yaml.safe_dump(data)) == data


def test_config_from_dict(scenario_dir):
    cfg = config_from_dict({"steps": 5}, source="params.yaml", base_dir=scenario_dir)
    assert cfg.steps == 5
    with pytest.raises(InputError, match=r"params.yaml: key 'steps' = 0"):
        config_from_dict({"steps": 0}, source="params.yaml", base_dir=scenario_dir)


# --- mix split (largest remainder) ---------------------------------------------------------


def mix(count: int, c: int, m: int, k: int) -> dict[str, int]:
    return mix_counts(BvConfig(count=count, mix={"competitive": c, "mutual": m, "cooperative": k}))


def test_mix_counts_largest_remainder():
    # 20 * 4/10 = 8, 20 * 3/10 = 6, 6: exact
    assert mix(20, 4, 3, 3) == {"competitive": 8, "mutual": 6, "cooperative": 6}
    # 10 * (3, 4, 3)/10 = 3, 4, 3: exact
    assert mix(10, 3, 4, 3) == {"competitive": 3, "mutual": 4, "cooperative": 3}
    # 7/3 = 2.33 each: floors 2/2/2, the one left over goes to competitive (tie order)
    assert mix(7, 1, 1, 1) == {"competitive": 3, "mutual": 2, "cooperative": 2}
    # 8/3: floors 2/2/2, two left: competitive then mutual
    assert mix(8, 1, 1, 1) == {"competitive": 3, "mutual": 3, "cooperative": 2}
    # 21 at 4:3:3: quotas 8.4, 6.3, 6.3 -> 8/6/6 + 1 to the largest remainder (competitive)
    assert mix(21, 4, 3, 3) == {"competitive": 9, "mutual": 6, "cooperative": 6}
    # 5 at 1:2:2: quotas 1, 2, 2
    assert mix(5, 1, 2, 2) == {"competitive": 1, "mutual": 2, "cooperative": 2}
    # 3 at 0:1:5: quotas 0, 0.5, 2.5 -> floors 0/0/2, one left, remainders tie -> mutual
    assert mix(3, 0, 1, 5) == {"competitive": 0, "mutual": 1, "cooperative": 2}
    # 4 at 1:0:0: everything competitive
    assert mix(4, 1, 0, 0) == {"competitive": 4, "mutual": 0, "cooperative": 0}


def test_mix_counts_sum_to_count():
    for count in range(0, 60):
        for weights in [(4, 3, 3), (3, 4, 3), (1, 1, 1), (7, 0, 2), (1, 5, 9)]:
            counts = mix(count, *weights)
            assert sum(counts.values()) == count
            assert list(counts) == list(POLICIES)


def test_mix_counts_of_scenario_default():
    assert mix_counts(ScenarioConfig()) == {"competitive": 8, "mutual": 6, "cooperative": 6}


def test_evaluation_section_defaults_and_errors(scenario_dir):
    from evoscen_sim.config.scenario_config import EvaluationConfig, evaluation_from_dict

    ev = load_scenario_config(None).evaluation
    assert ev == EvaluationConfig()
    assert (ev.ttc_threshold_s, ev.hard_brake_mps2, ev.collision_cap, ev.window_steps) == (2.0, 6.0, 10, 100)
    assert (ev.weight_safety, ev.weight_efficiency, ev.weight_interaction) == (0.6, 0.2, 0.2)
    assert (ev.k_exposure, ev.k_lane_change, ev.k_accel) == (25.0, 8.0, 1400.0)
    message = load_error(scenario_dir, "evaluation:\n  weight_safety: 0\n  weight_efficiency: 0\n  weight_interaction: 0\n")
    assert "'evaluation.weight_safety' = 0" in message and "not all 0" in message
    message = load_error(scenario_dir, "evaluation: {efficiency_density: sqrt}\n")
    assert "'evaluation.efficiency_density' = 'sqrt'" in message and "literal, normalised" in message
    message = load_error(scenario_dir, "evaluation: {ttc_treshold_s: 3}\n")
    assert "ttc_treshold_s" in message and "did you mean 'ttc_threshold_s'" in message
    assert evaluation_from_dict({"ttc_threshold_s": 3}, "bag").ttc_threshold_s == 3.0
    with pytest.raises(InputError, match=r"^bag: key 'evaluation.collision_cap' = 0: expected an integer >= 1$"):
        evaluation_from_dict({"collision_cap": 0}, "bag")


def test_evaluation_conflict_and_undefined_term_keys(scenario_dir):
    ev = load_scenario_config(None).evaluation
    assert (ev.rear_conflicts, ev.rear_attribution_s, ev.drac_threshold_mps2, ev.undefined_terms) == \
        ("after_lane_change", 5.0, 3.0, "exclude")
    message = load_error(scenario_dir, "evaluation: {rear_conflicts: always}\n")
    assert "'evaluation.rear_conflicts' = 'always'" in message and "after_lane_change, all, none" in message
    message = load_error(scenario_dir, "evaluation: {undefined_terms: zero}\n")
    assert "'evaluation.undefined_terms' = 'zero'" in message and "exclude, literal" in message
    message = load_error(scenario_dir, "evaluation: {rear_attribution_s: -1}\n")
    assert "'evaluation.rear_attribution_s' = -1" in message
    message = load_error(scenario_dir, "evaluation: {drac_threshold_mps2: 0}\n")
    assert "'evaluation.drac_threshold_mps2' = 0" in message
    assert "\n" not in message.strip()
    assert (ev.ssm_ttc_threshold_s, ev.ssm_pet_threshold_s) == (3.0, 2.0)  # SUMO SSM's defaults
    message = load_error(scenario_dir, "evaluation: {ssm_ttc_threshold_s: 0}\n")
    assert "'evaluation.ssm_ttc_threshold_s' = 0: expected a number > 0" in message
    message = load_error(scenario_dir, "evaluation: {ssm_pet_threshold_s: fast}\n")
    assert "'evaluation.ssm_pet_threshold_s' = 'fast': expected a number > 0" in message
    ok = load_scenario_config(None, {"evaluation.rear_conflicts": "none", "evaluation.undefined_terms": "literal"})
    assert (ok.evaluation.rear_conflicts, ok.evaluation.undefined_terms) == ("none", "literal")


def test_evaluation_count_normalisation_keys(scenario_dir):
    ev = load_scenario_config(None).evaluation
    assert (ev.count_normalisation, ev.count_reference_steps) == ("method_length", 3000)
    message = load_error(scenario_dir, "evaluation: {count_normalisation: per_step}\n")
    assert "'evaluation.count_normalisation' = 'per_step'" in message and "method_length, literal" in message
    message = load_error(scenario_dir, "evaluation: {count_reference_steps: 0}\n")
    assert "'evaluation.count_reference_steps' = 0" in message
    ok = load_scenario_config(None, {"evaluation.count_normalisation": "literal", "evaluation.count_reference_steps": 1500})
    assert (ok.evaluation.count_normalisation, ok.evaluation.count_reference_steps) == ("literal", 1500)
