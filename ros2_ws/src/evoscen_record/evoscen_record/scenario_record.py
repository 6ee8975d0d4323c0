"""The scenario's MCAP metadata record of a bag: its name, its keys and its content.

The resolved scenario configuration travels in the bag as the metadata record
:data:`SCENARIO_METADATA`, written first, before any message (the recorder's ``metadata``), so a
bag alone is enough to evaluate a run with the settings it ran with
(:mod:`evoscen_eval.scoring.rundata` reads it).
"""

from __future__ import annotations

from pathlib import Path

import yaml

SCENARIO_METADATA = "evoscen"
"""Name of the MCAP metadata record holding the scenario."""
SCENARIO_KEY = "scenario_yaml"
"""Key of the resolved scenario configuration (YAML text) in that record."""
MAP_HASH_KEY = "map_sha256"
"""Key of the SHA-256 (hex) of the map file's bytes in that record."""
SUT_SOURCE_KEY = "sut_source"
"""Key present (value ``external``) when the SUT was a user's node, not the configured model."""
EXTERNAL_SUT = "external"


def scenario_metadata(cfg, *, external_sut: bool = False) -> dict[str, str]:  # a ScenarioConfig
    """The metadata record content for ``cfg`` (the same YAML text in every runner).

    With ``external_sut`` the record also says that the SUT was a user's node, whatever the
    configuration's ``sut.model`` (which then drove nothing); without it the record is only the
    configuration, so a graph run's bag stays equal to the in-process one.
    """
    return metadata_record(recorded_scenario(cfg), portable_map_ref(cfg.map)[1], external_sut=external_sut)


def recorded_scenario(cfg) -> dict:  # a ScenarioConfig
    """The scenario as its bag records it (a plain dict: what :func:`metadata_record` writes as YAML
    and a reader of the bag loads back, equal): ``cfg``'s resolved configuration, the map named by its
    file name (:func:`portable_map_ref`), the keys that hold their defaults and were added after the
    first bags left out."""
    from evoscen_sim.config.scenario_config import config_to_dict

    scenario = _without_unset(config_to_dict(cfg))
    if scenario.get("bvs", {}).get("makeup") == "uniform":
        # [choice] absent = uniform: bags of the traffic before make-ups existed stay byte-identical
        # (docs/bv-profiles.md, "Traffic make-up"); a reader's default fills it in.
        del scenario["bvs"]["makeup"]
    if scenario.get("challenge", {}).get("mode") == "none":
        # [choice] absent = none: bags without the challenge layer stay byte-identical (docs/challenges.md)
        del scenario["challenge"]
    scenario["map"] = Path(cfg.map).name
    return scenario


def metadata_record(scenario: dict, map_sha256: str, *, external_sut: bool = False) -> dict[str, str]:
    """The metadata record content of a recorded scenario (:func:`recorded_scenario`) and its map's
    SHA-256 (hex); with ``external_sut`` it also says that the SUT was a user's node."""
    meta = {SCENARIO_KEY: yaml.safe_dump(scenario, sort_keys=False, default_flow_style=None),
            MAP_HASH_KEY: map_sha256}
    if external_sut:
        meta[SUT_SOURCE_KEY] = EXTERNAL_SUT
    return meta


def _without_unset(scenario: dict) -> dict:
    """``scenario`` without the ``evaluation`` keys of
    :data:`evoscen_sim.config.config_schema.RECORDED_WHEN_SET` that hold their defaults: those keys
    shape only the comparative score (docs/evaluation.md §10), so a run at the defaults records the
    bytes it recorded before they existed, and a set one is recorded (and scored again from the bag)."""
    from evoscen_sim.config.config_schema import RECORDED_WHEN_SET, EvaluationConfig

    section = scenario.get("evaluation")
    if isinstance(section, dict):
        defaults = EvaluationConfig()
        scenario["evaluation"] = {k: v for k, v in section.items()
                                  if not (k in RECORDED_WHEN_SET and v == getattr(defaults, k))}
    return scenario


def portable_map_ref(map_path: str | Path) -> tuple[str, str]:
    """``(reference, sha256 hex)`` of a resolved map file, with nothing machine-specific in it.

    The reference is the file name (``onramp.xodr``): a config's ``map: onramp.xodr`` finds
    it in evoscen_sim's share ``maps/`` wherever evoscen is installed, and for a map of the
    user's the directory is left out (it names a machine: the same run from another checkout
    gave another bag). The SHA-256 of the file's bytes identifies the map exactly (a shipped
    map edited in place, a user's map of the same name)."""
    import hashlib

    path = Path(map_path)
    try:
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        digest = ""
    return path.name, digest
