"""Detection through the real simulation: scripted situations driven by the world's dynamics.

Each scenario is run step by step as the runners do (world state -> scripted commands ->
``World.step`` -> events incl. the live :class:`ExposureMonitor`), collected by the
accumulator the runners use and scored. The expected counts are the situation's, so a wrong
detection (per-step counting, lane- instead of path-based TTC, a collision counted per
overlapping step) fails.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from evoscen_contract import topics as T
from evoscen_eval.scoring.run_fixtures import drive as drive_run
from evoscen_sim.config.scenario_config import EvaluationConfig
from evoscen_sim.loop.hand_built import hand_built_world
from evoscen_sim.road.road_model import load_road

EV = EvaluationConfig()


@pytest.fixture(scope="module")
def road():
    return load_road()


def drive(world, command, steps):
    """:func:`evoscen_eval.scoring.run_fixtures.drive` under ``EV``."""
    return drive_run(world, command, steps, EV)


def exposure_events(live, kind):
    return [e for e in live if e["name"] == T.EVENT_EXPOSURE and e["kind"] == kind]


def test_scripted_cut_in_yields_exactly_one_exposure(road):
    # SUT (id 0) at 30 m/s in lane 2; a BV 27 m ahead at 25 m/s in lane 3 cuts in at once.
    # Its body enters the SUT's path after ~3 s with a ~7 m gap: TTC ~1.4 s. The SUT brakes
    # moderately (-4 m/s^2, not a hard brake) until the gap opens again.
    world = hand_built_world(road, [300.0, 327.0], [2, 3], [30.0, 25.0], roles=[1, 0])
    report, live = drive(world, lambda k: ([-0.5 if 31 <= k < 45 else 0.0, 0.0], [0, -1 if k == 0 else 0]), 120)
    s = report["safety"]
    assert s["collisions_all"] == 0
    assert s["exposures"] == 1
    ex = s["exposure_list"][0]
    assert 1.0 < ex["min_ttc_s"] < 2.0 and ex["min_accel_mps2"] > -6.0
    # the live events say the same: one start (naming the cut-in vehicle), one end
    starts, ends = exposure_events(live, "start"), exposure_events(live, "end")
    assert len(starts) == 1 and len(ends) == 1
    assert starts[0]["ids"] == [0, 1] and starts[0]["step"] == ex["start_state"]
    assert ends[0]["steps"] == ex["states"]


def test_same_situation_without_the_cut_in_has_no_exposure(road):
    world = hand_built_world(road, [300.0, 327.0], [2, 3], [30.0, 25.0], roles=[1, 0])
    report, live = drive(world, lambda k: ([-0.5 if 31 <= k < 45 else 0.0, 0.0], [0, 0]), 120)
    assert report["safety"]["exposures"] == 0 and not exposure_events(live, "start")


def test_hard_brake_yields_exactly_one_exposure(road):
    # hard_braking: own (the method's words): the SUT's full braking alone is dangerous
    world = hand_built_world(road, [300.0, 900.0], [2, 2], [30.0, 30.0], roles=[1, 0])
    report, live = drive_run(world, lambda k: ([-1.0 if 10 <= k < 15 else 0.0, 0.0], [0, 0]), 40,
                             replace(EV, hard_braking="own"))
    s = report["safety"]
    assert s["exposures"] == 1
    assert s["exposure_list"][0]["states"] == 5  # -8 m/s^2 in the five states after the five full-brake commands
    assert s["min_accel_mps2"] == pytest.approx(-8.0)
    assert len(exposure_events(live, "start")) == 1


def test_hard_brake_counts_when_it_is_imposed_on_a_close_follower(road):
    # hard_braking: conflict (default). Alone on the road (the BV 600 m ahead) the same braking
    # endangers no one: no exposure.
    world = hand_built_world(road, [300.0, 900.0], [2, 2], [30.0, 30.0], roles=[1, 0])
    report, live = drive(world, lambda k: ([-1.0 if 10 <= k < 15 else 0.0, 0.0], [0, 0]), 40)
    assert report["safety"]["exposures"] == 0 and not exposure_events(live, "start")
    # a follower 15 m behind (centres) at 30 m/s: gap 15 - 4.8 = 10.2 m, headway 0.34 s < 2 s: the
    # SUT's full braking is imposed on it — the same five states
    world = hand_built_world(road, [300.0, 900.0, 285.0], [2, 2, 2], [30.0, 30.0, 30.0], roles=[1, 0, 0])
    # the follower brakes as hard two steps later (no collision)
    report, live = drive(world, lambda k: ([-1.0 if 10 <= k < 15 else 0.0, 0.0, -1.0 if 12 <= k < 17 else 0.0],
                                           [0, 0, 0]), 40)
    s = report["safety"]
    assert s["collisions_all"] == 0
    assert [(e["start_state"], e["states"]) for e in s["exposure_list"]] == [(11, 5)]
    assert [e["step"] for e in exposure_events(live, "start")] == [11]


def test_a_needed_hard_brake_counts_whatever_the_sut_does(road):
    # SUT at 30 m/s coasting towards a standing BV 80 m ahead (bumper to bumper), then braking fully
    # from step 3. DRAC = 30^2 / (2 gap): state 1, gap 77 m: 5.84 m/s^2; state 2, gap 74 m: 6.08 > 6.
    # TTC = gap / 30 < 2 s only from gap < 60 m. conflict (default): dangerous from state 2, while the
    # needed deceleration exceeds 6 m/s^2, before the SUT brakes at all; own: from its braking (state 4).
    def run(mode):
        world = hand_built_world(road, [300.0, 384.8], [2, 2], [30.0, 0.0], roles=[1, 0])
        return drive_run(world, lambda k: ([-1.0 if k >= 3 else 0.0, 0.0], [0, 0]), 60,
                         replace(EV, hard_braking=mode))
    report, live = run("conflict")
    ex = report["safety"]["exposure_list"]
    assert report["safety"]["collisions"] == 0
    assert ex[0]["start_state"] == 2 and exposure_events(live, "start")[0]["step"] == 2
    assert "needed deceleration (DRAC) 6.08" in exposure_events(live, "start")[0]["message"]
    assert [e["step"] for e in exposure_events(live, "start")] == [e["start_state"] for e in ex]
    own, _ = run("own")
    assert own["safety"]["exposure_list"][0]["start_state"] == 4


def test_moderate_brake_is_not_an_exposure(road):
    world = hand_built_world(road, [300.0, 900.0], [2, 2], [30.0, 30.0], roles=[1, 0])
    report, _ = drive(world, lambda k: ([-0.7 if 10 <= k < 15 else 0.0, 0.0], [0, 0]), 40)  # -5.6 m/s^2
    assert report["safety"]["exposures"] == 0


def test_collision_is_counted_once_not_per_overlapping_step(road):
    # SUT at 30 m/s runs into a BV at 20 m/s 10 m ahead and keeps overlapping for many steps
    world = hand_built_world(road, [300.0, 310.0], [2, 2], [30.0, 20.0], roles=[1, 0])
    report, live = drive(world, lambda k: ([0.0, 0.0], [0, 0]), 30)
    s = report["safety"]
    assert s["collisions"] == 1 and s["collisions_all"] == 1
    assert s["collision_list"][0]["ids"] == [0, 1]
    assert s["exposures"] == 1  # TTC fell below 2 s before the contact: one exposure, not one per step
    # 30 steps: each count enters I_s scaled to 3,000 steps (count_normalisation: method_length), C' = E' = 100
    assert (s["steps"], s["count_factor"], s["collisions_used"], s["exposures_used"]) == (30, 100.0, 100.0, 100.0)
    assert s["score"] == pytest.approx(0.7 * 0.0 + 0.3 * np.exp(-100.0))
