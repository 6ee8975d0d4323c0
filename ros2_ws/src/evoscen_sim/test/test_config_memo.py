"""The memos that make an experiment's thousands of configurations cheap (docs/performance.md, "Start-up") give
what the plain computations give: override texts read as before, mutable values fresh each time, the share
directory of the AMENT_PREFIX_PATH in force, a config's plain dict equal to a reference built field by field."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

from evoscen_sim.config import config_load
from evoscen_sim.config.config_load import _parse_cli_scalar, config_to_dict
from evoscen_sim.config.scenario_config import load_scenario_config
from evoscen_sim.share import share_candidates


def test_override_texts_read_alike_twice_and_lists_fresh():
    for _ in range(2):
        assert _parse_cli_scalar("16") == 16 and _parse_cli_scalar("0x10") == "0x10"
        assert _parse_cli_scalar("true") is True and _parse_cli_scalar("2.5") == 2.5 and _parse_cli_scalar("~") is None
        assert _parse_cli_scalar("mobil") == "mobil"
    first = _parse_cli_scalar("[24, 30]")
    first.append(1)
    assert _parse_cli_scalar("[24, 30]") == [24, 30]
    assert "[24, 30]" not in config_load._CLI_SCALARS and config_load._CLI_SCALARS["16"] == 16


def _index(prefix, package="evoscen_sim"):
    (prefix / "share" / "ament_index" / "resource_index" / "packages").mkdir(parents=True)
    (prefix / "share" / "ament_index" / "resource_index" / "packages" / package).write_text("")
    (prefix / "share" / package).mkdir(parents=True)


def test_the_share_directory_follows_ament_prefix_path(tmp_path, monkeypatch):
    a, b = tmp_path / "a", tmp_path / "b"
    _index(a)
    _index(b)
    for prefix in (a, b, a):
        monkeypatch.setenv("AMENT_PREFIX_PATH", str(prefix))
        assert share_candidates("maps/x.xodr")[0] == prefix / "share" / "evoscen_sim" / "maps" / "x.xodr"
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(tmp_path / "none"))
    assert share_candidates("maps/x.xodr")[0].parts[-4:] == ("src", "evoscen_sim", "maps", "x.xodr")


def _reference(value):
    """config_to_dict as it was written first: every field through the generic checks."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _reference(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, Mapping):
        return {str(k): _reference(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_reference(v) for v in value]
    return value


def test_a_configs_plain_dict_equals_the_field_by_field_reference():
    for overrides in ({}, {"sut.model": "mobil", "bvs.makeup": "uniform", "traffic.entry_retry_s": "0"},
                      {"challenge.mode": "nade", "seed": "7"}):
        cfg = load_scenario_config(None, overrides)
        got, want = config_to_dict(cfg), _reference(cfg)
        assert got == want and list(got) == list(want)
        assert repr(got) == repr(want)  # the same types too (1 and 1.0 print alike in ==)
