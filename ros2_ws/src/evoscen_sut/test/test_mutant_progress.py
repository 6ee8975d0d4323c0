"""The progress and decision mutants ``timid`` and ``frozen`` (docs/mutants.md) and the library's
statement of which SUT bases each mutant applies to.

The frozen situation is test_mobil.py's: ego in lane 1 at s = 300 m, 25 m/s, a slow leader 25.2 m
ahead (bumper to bumper) at 20 m/s, lane 2 free: intact MOBIL changes left."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from evoscen_sim.config.scenario_config import load_scenario_config
from evoscen_sim.errors import InputError
from evoscen_sim.model_registry import create_driver
from evoscen_sim.loop.hand_built import hand_built_world
from evoscen_sim.road.road_model import load_road
from evoscen_sut import mutant as M
from evoscen_sut.krauss import KraussParams
from evoscen_sut.mobil import MobilParams
from evoscen_sut.mutants import KNOWN_BASES, LIBRARY, applicability, applicable_bases, mutant_overrides, mutants_for
from evoscen_sut.nilsson import NilssonParams

EGO = [0]


@pytest.fixture(scope="module")
def road():
    return load_road()


def mutant_of(base: str, operator: str, seed: int = 0):
    cfg = load_scenario_config(None, {"sut.model": "mutant", "models.mutant.base": base,
                                      "models.mutant.operator": operator})
    return cfg, create_driver("mutant", "sut", EGO, cfg, np.random.default_rng(seed))


# ------------------------------------------------------------------ timid
@pytest.mark.parametrize(("base", "own"), [("mobil", MobilParams().desired_speed_mps),
                                           ("nilsson", NilssonParams().desired_speed_mps), ("stackelberg", None)])
def test_timid_wants_60_percent_of_the_base_speed(base, own) -> None:
    cfg, drv = mutant_of(base, "timid")
    assert drv.params.speed_factor == 0.6
    follower = drv.base.car_following if base == "stackelberg" else drv.base.krauss
    assert follower.params.desired_speed_mps == pytest.approx(0.6 * KraussParams().desired_speed_mps, rel=1e-15)
    if own is not None:  # the decision model's own desired speed (MOBIL's IDM, Nilsson's v_des)
        assert drv.base.params.desired_speed_mps == pytest.approx(0.6 * own, rel=1e-15)
    assert cfg.models.get("krauss") is None  # the scenario (and every BV) keeps its car follower


def test_timid_level0_draws_its_desired_speed_from_the_scaled_range() -> None:
    cfg, drv = mutant_of("level0", "timid", seed=5)
    intact = create_driver("level0", "sut", EGO, cfg, np.random.default_rng(5))
    assert drv.base.desired_speed_mps == pytest.approx(0.6 * intact.desired_speed_mps, rel=1e-12)


def test_timid_scales_the_plugins_desired_speed() -> None:
    fiss = pytest.importorskip("fiss_sut")
    sumo = pytest.importorskip("sumo_sut")
    cfg = load_scenario_config(None)
    p, c, keys = M.timid_parameters("fiss", fiss.FissSutParams(), cfg, 0.6)
    assert p.desired_speed_mps == pytest.approx(0.6 * 30.0) and keys == ["models.fiss.desired_speed_mps"]
    assert c is cfg
    p, _, keys = M.timid_parameters("sumo_sut", sumo.SumoSutParams(), cfg, 0.6)
    assert p.speed_factor == pytest.approx(0.6) and keys == ["models.sumo_sut.speed_factor"]


def test_timid_without_a_desired_speed_is_one_line_error() -> None:
    @dataclasses.dataclass(frozen=True)
    class NoSpeed:
        gain: float = 1.0

    with pytest.raises(InputError, match=r"^models\.mutant\.operator 'timid': base model 'mine' has no desired speed"):
        M.timid_parameters("mine", NoSpeed(), load_scenario_config(None), 0.6)


# ------------------------------------------------------------------ frozen
def drive(road, driver, world, steps: int) -> list[tuple[int, int]]:
    """``steps`` steps of a hand-built world: the SUT (vehicle 0) by ``driver``, the others coasting
    in their lanes; the SUT's (lane, lane-change request) after each."""
    out = []
    n = world.n
    for _ in range(steps):
        throttle, request = driver.act(world)
        thr, lc = np.zeros(n), np.zeros(n, dtype=np.int64)
        thr[0], lc[0] = float(throttle[0]), int(request[0])
        world.step(thr, lc)
        out.append((int(world.lane[0]), int(request[0])))
    return out


@pytest.mark.parametrize("base", ["mobil", "nilsson"])
def test_frozen_stays_behind_the_slow_leader_the_intact_base_passes(road, base) -> None:
    slow = dict(s=[300.0, 330.0], lane=[1, 1], speed=[25.0, 20.0])
    cfg, frozen = mutant_of(base, "frozen")
    intact = create_driver(base, "sut", EGO, cfg, np.random.default_rng(0))
    ran_intact = drive(road, intact, hand_built_world(road, **slow), 40)
    ran_frozen = drive(road, frozen, hand_built_world(road, **slow), 40)
    assert any(req != 0 for _, req in ran_intact) and ran_intact[-1][0] == 2  # the intact base changed left
    assert all(req == 0 for _, req in ran_frozen) and all(lane == 1 for lane, _ in ran_frozen)


def test_frozen_still_merges(road) -> None:
    """On the merge lane (lane 0, ending at 960 m) the change out of it is mandatory: frozen MOBIL
    requests it as the intact model does."""
    world = hand_built_world(road, s=[860.0], lane=[0], speed=[25.0])
    cfg, frozen = mutant_of("mobil", "frozen")
    intact = create_driver("mobil", "sut", EGO, cfg, np.random.default_rng(0))
    ci, cf = intact.act(world)[1], frozen.act(world)[1]
    assert ci[0] == 1 and cf[0] == 1


# ------------------------------------------------------------------ applicability
def test_every_mutant_states_its_bases() -> None:
    table = applicability()
    assert set(table) == set(LIBRARY)
    for name, row in table.items():
        assert row["applies"] and set(row["bases"]) <= set(KNOWN_BASES) and row["bases"]
        assert applicable_bases(name) == row["bases"]
    assert applicable_bases("timid") == KNOWN_BASES
    assert "level0" not in applicable_bases("frozen") and {"fiss", "sumo_sut"} <= set(applicable_bases("frozen"))
    assert applicable_bases("over_eager") == ("mobil", "nilsson", "stackelberg")
    assert "frozen" in mutants_for("sumo_sut") and "frozen" not in mutants_for("level0")
    # two instances of the base driver: not for sumo_sut (one SUMO per process)
    assert applicable_bases("tailgating") == ("level0", "mobil", "nilsson", "stackelberg", "fiss")
    assert applicable_bases("ignores_new_follower") == ("mobil", "nilsson", "stackelberg", "fiss")
    assert len(mutants_for("sumo_sut")) == 9 and len(mutants_for("fiss")) == 11 and len(mutants_for("mobil")) == 12
    assert "timid" not in mutants_for("my_own_plugin") and "weak_braking" in mutants_for("my_own_plugin")
    with pytest.raises(InputError, match="mutant 'nosuch'"):
        applicable_bases("nosuch")
    assert mutant_overrides("fiss", "timid")["models.mutant.speed_factor"] == "0.6"
