"""The driver-model registry and the validation of ``models.<name>`` parameters."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from evoscen_sim.config.scenario_config import config_from_dict, integer, number
from evoscen_sim.errors import InputError
from evoscen_sim.model_registry import (
    ModelSpec,
    create_driver,
    get_model,
    model_names,
    register_model,
    unregister_model,
)


@dataclass(frozen=True)
class _ToyParams:
    gain: float = number(0.5, 0.0, 1.0)
    """A gain in [0, 1]."""
    horizon: int = integer(3, 1)
    """Steps, >= 1."""


class _ToyDriver:
    def __init__(self, vehicles, params):
        self.vehicles, self.params = vehicles, params

    def act(self, view):
        n = self.vehicles.size
        return np.full(n, self.params.gain), np.zeros(n, dtype=np.int64)


@pytest.fixture(autouse=True)
def toy_model():
    register_model(ModelSpec("toy_sut", ("sut",), lambda vehicles, params, cfg, rng: _ToyDriver(vehicles, params),
                             _ToyParams, "a test model"))
    yield
    unregister_model("toy_sut")


def test_builtin_level0_serves_both_roles():
    assert "level0" in model_names("sut") and "level0" in model_names("bv")
    assert "toy_sut" in model_names("sut") and "toy_sut" not in model_names("bv")


def test_models_section_is_validated_against_the_model_params():
    cfg = config_from_dict({"sut": {"model": "toy_sut"}, "models": {"toy_sut": {"gain": 0.25}}}, source="s.yaml")
    assert cfg.models["toy_sut"] == _ToyParams(gain=0.25, horizon=3)
    driver = create_driver("toy_sut", "sut", [0], cfg, np.random.default_rng(0))
    assert driver.act(None)[0].tolist() == [0.25]
    # a model not listed gets its defaults
    default = create_driver("toy_sut", "sut", [0], config_from_dict({}, source="s.yaml"), np.random.default_rng(0))
    assert default.params == _ToyParams()


@pytest.mark.parametrize(("models", "expected"), [
    ({"toy_sut": {"gain": 2.0}}, "s.yaml: key 'models.toy_sut.gain' = 2.0: expected a number in [0, 1]"),
    ({"toy_sut": {"horizon": 0}}, "s.yaml: key 'models.toy_sut.horizon' = 0: expected an integer >= 1"),
    ({"toy_sut": {"gian": 0.1}}, "s.yaml: key 'models.toy_sut.gian'"),
    ({"nosuch": {}}, "s.yaml: key 'models.nosuch'"),
    ("fast", "s.yaml: key 'models' = 'fast': expected a mapping"),
])
def test_bad_model_parameters_are_one_line_errors(models, expected):
    with pytest.raises(InputError) as err:
        config_from_dict({"models": models}, source="s.yaml")
    assert str(err.value).startswith(expected) and "\n" not in str(err.value)


def test_unknown_model_names_the_key_and_lists_choices():
    with pytest.raises(InputError, match=r"key 'sut.model' = 'nosuch': expected one of .*level0.*toy_sut"):
        config_from_dict({"sut": {"model": "nosuch"}}, source="s.yaml")
    with pytest.raises(InputError, match=r"unknown bvs.driver 'toy_sut': expected one of learned, level0"):
        get_model("toy_sut", "bv")


@dataclass(frozen=True)
class _SharedParams:
    speed: float = number(10.0, 0.0, 50.0, lo_open=True)
    """A speed in (0, 50]."""


def test_a_parameter_set_is_validated_under_models_but_is_no_model(monkeypatch):
    from evoscen_sim import model_registry as registry

    monkeypatch.setattr(registry, "_PARAMETER_SETS", dict(registry._PARAMETER_SETS))
    registry.register_parameter_set("toy_shared", _SharedParams)
    cfg = config_from_dict({"models": {"toy_shared": {"speed": 20}}}, source="s.yaml")
    assert cfg.models["toy_shared"] == _SharedParams(speed=20.0)
    assert "toy_shared" in registry.parameter_names() and "toy_sut" in registry.parameter_names()
    assert "toy_shared" not in model_names("sut") and "toy_shared" not in model_names("bv")
    with pytest.raises(InputError) as err:
        config_from_dict({"models": {"toy_shared": {"speed": 0}}}, source="s.yaml")
    assert str(err.value) == "s.yaml: key 'models.toy_shared.speed' = 0: expected a number in (0, 50]"
    with pytest.raises(InputError, match=r"key 'sut.model' = 'toy_shared': expected one of"):
        config_from_dict({"sut": {"model": "toy_shared"}}, source="s.yaml")
    # a name is either a model or a parameter set
    with pytest.raises(ValueError, match="taken by a model"):
        registry.register_parameter_set("toy_sut", _SharedParams)
    with pytest.raises(ValueError, match="taken by the parameter set"):
        register_model(ModelSpec("toy_shared", ("sut",), lambda *a: None))
