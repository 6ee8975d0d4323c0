"""The surrogate-safety profile of the SUT (report ``surrogate_safety``, docs/evaluation.md
"Surrogate safety"), on hand-built runs where every number follows from the definitions by hand.

``two_sided_run``: 40 states of 0.1 s, SUT (vehicle 0) at s = 1000 m, d = 0, 30 m/s all along
(SUT distance 40 · 0.1 · 30 m = 0.12 km); bodies 4.8 × 1.9 m, so a vehicle at s = 1000 + 4.8 + g
in the SUT's path is g metres ahead bumper to bumper.

Front (the SUT following):

* states 10..14: vehicle 1 at 25 m/s, gap 10 m: TTC 10/5 = 2 s, DRAC 5²/(2·10) = 1.25 m/s²;
* states 15..17: vehicle 1 leaves the path (d = 3.5); vehicle 2 at 25 m/s, gap 12.5 m: TTC 2.5 s,
  DRAC 1 m/s² (a new counterpart: a new episode with no state between);
* states 25..26: vehicle 1 back, gap 10 m at 25 m/s: TTC 2 s;
* states 30..33: vehicle 1 at 15 m/s, gap 30 m: TTC 30/15 = 2 s, DRAC 15²/(2·30) = 3.75 m/s².

So 4 TTC < 3 s episodes over 5 + 3 + 2 + 4 = 14 states: TET = 1.4 s; TIT = 0.1 · (5·1 + 3·0.5 +
2·1 + 4·1) = 1.25 s²; 1 DRAC > 3 m/s² episode (30..33). Per SUT-km: 33.33, 8.333, 11.667 s, 10.417 s².

Rear (the follower behind the SUT, vehicle 3, far behind at 30 m/s otherwise):

* states 5..8: 35 m/s, gap 5 m: TTC 5/5 = 1 s, DRAC 25/10 = 2.5 m/s²;
* states 20..21: 40 m/s, gap 10 m: TTC 1 s, DRAC 100/20 = 5 m/s².

So 2 TTC episodes over 6 states: TET 0.6 s, TIT 0.1 · 6 · 2 = 1.2 s²; 1 DRAC episode.
"""

from __future__ import annotations

from dataclasses import replace

import pytest
from evoscen_eval.scoring import streaming
from evoscen_eval.scoring.metrics import evaluate
from evoscen_eval.scoring.report import markdown
from evoscen_eval.scoring.run_fixtures import make_run, rear_run
from evoscen_sim.config.scenario_config import EvaluationConfig

EV = EvaluationConfig()
KM = 40 * 0.1 * 30.0 / 1000.0


def two_sided_run():
    run = make_run(40, 4)
    c = run.columns
    ahead = 1000.0 + 4.8
    # out of the way by default: vehicles 1 and 2 far ahead in another lane, vehicle 3 far behind
    c["s"][:, 1], c["d"][:, 1] = 1500.0, 3.5
    c["s"][:, 2], c["d"][:, 2] = 1600.0, 3.5
    c["s"][:, 3], c["speed"][:, 3] = 500.0, 30.0
    for ks, gap, v in ((slice(10, 15), 10.0, 25.0), (slice(25, 27), 10.0, 25.0), (slice(30, 34), 30.0, 15.0)):
        c["s"][ks, 1], c["d"][ks, 1], c["speed"][ks, 1] = ahead + gap, 0.0, v
    c["s"][15:18, 2], c["d"][15:18, 2], c["speed"][15:18, 2] = ahead + 12.5, 0.0, 25.0
    for ks, gap, v in ((slice(5, 9), 5.0, 35.0), (slice(20, 22), 10.0, 40.0)):
        c["s"][ks, 3], c["speed"][ks, 3] = 1000.0 - 4.8 - gap, v
    return run


def check_two_sided(ss):
    assert ss["sut_km"] == pytest.approx(KM, rel=1e-12)
    assert (ss["ttc_threshold_s"], ss["drac_threshold_mps2"], ss["pet_threshold_s"]) == (3.0, 3.0, 2.0)
    f, r = ss["front"], ss["rear"]
    assert (f["ttc_episodes"], f["ttc_states"], f["drac_episodes"], f["pet_events"]) == (4, 14, 1, None)
    assert f["tet_s"] == pytest.approx(1.4, rel=1e-12)
    assert f["tit_s2"] == pytest.approx(1.25, rel=1e-9)
    assert f["per_km"]["ttc_episodes"] == pytest.approx(4 / 0.12)
    assert f["per_km"]["drac_episodes"] == pytest.approx(1 / 0.12)
    assert f["per_km"]["tet_s"] == pytest.approx(1.4 / 0.12)
    assert f["per_km"]["tit_s2"] == pytest.approx(1.25 / 0.12)
    assert f["per_km"]["pet_events"] is None
    assert (r["ttc_episodes"], r["ttc_states"], r["drac_episodes"], r["pet_events"]) == (2, 6, 1, 0)
    assert r["tet_s"] == pytest.approx(0.6, rel=1e-12)
    assert r["tit_s2"] == pytest.approx(1.2, rel=1e-9)
    assert r["per_km"]["ttc_episodes"] == pytest.approx(2 / 0.12)
    assert r["per_km"]["pet_events"] == 0.0


def test_front_and_rear_by_hand():
    check_two_sided(evaluate(two_sided_run(), EV)["surrogate_safety"])


@pytest.mark.parametrize("block", [1, 2, 3, 5, 7, 11, 64])
def test_block_boundaries_change_nothing(block, monkeypatch):
    """Blocks of 3 and 5 end inside episodes (10..14, 30..33) and at the switch of counterpart
    (state 15), blocks of 1 at every state: the same counts, sums to 1e-12."""
    reference = evaluate(two_sided_run(), EV)["surrogate_safety"]
    monkeypatch.setattr(streaming, "BLOCK_STATES", block)
    ss = evaluate(two_sided_run(), EV)["surrogate_safety"]
    check_two_sided(ss)
    for side in ("front", "rear"):
        for d_ref, d_new in ((reference[side], ss[side]), (reference[side]["per_km"], ss[side]["per_km"])):
            for key, value in d_ref.items():
                if isinstance(value, float):
                    assert d_new[key] == pytest.approx(value, rel=1e-12, abs=1e-15)
                elif not isinstance(value, dict):
                    assert d_new[key] == value


def test_thresholds_are_the_evaluation_keys():
    """TTC* 2.4 s: the 2.5-s episode (15..17) is no longer below it, the others are: front 3
    episodes over 11 states, TIT = 0.1 · 11 · 0.4 = 0.44 s²; rear 2 over 6, TIT 0.1 · 6 · 1.4 =
    0.84 s². DRAC 2 m/s²: the rear's 2.5 and 5 m/s² states are one episode each (5..8, 20..21)."""
    ev = replace(EV, ssm_ttc_threshold_s=2.4, drac_threshold_mps2=2.0)
    ss = evaluate(two_sided_run(), ev)["surrogate_safety"]
    assert (ss["front"]["ttc_episodes"], ss["front"]["ttc_states"]) == (3, 11)
    assert ss["front"]["tit_s2"] == pytest.approx(0.44, rel=1e-9)
    assert (ss["rear"]["ttc_episodes"], ss["rear"]["ttc_states"], ss["rear"]["drac_episodes"]) == (2, 6, 2)
    assert ss["rear"]["tit_s2"] == pytest.approx(0.84, rel=1e-9)
    assert ss["front"]["drac_episodes"] == 1  # 1.25 and 1 m/s² stay below 2


def test_lane_change_pet_event_on_the_rear():
    """evoscen_eval.scoring.run_fixtures.rear_run: the SUT (25 m/s) changes into lane 3 ahead of vehicle 1 (30 m/s):
    PET 5.2/30 = 0.1733 s < 2 s, one PET event; vehicle 1 is in the SUT's path from state 7 to the
    end (33 states) at TTC 5.2/5 = 1.04 s: one rear TTC episode, TET 3.3 s, TIT 0.1·33·1.96 =
    6.468 s²; DRAC 2.404 m/s²: none. SUT distance 40 · 0.1 · 25 m = 0.1 km."""
    ss = evaluate(rear_run(), EV)["surrogate_safety"]
    r = ss["rear"]
    assert ss["sut_km"] == pytest.approx(0.1)
    assert (r["pet_events"], r["ttc_episodes"], r["ttc_states"], r["drac_episodes"]) == (1, 1, 33, 0)
    assert r["tet_s"] == pytest.approx(3.3)
    assert r["tit_s2"] == pytest.approx(6.468)
    assert r["per_km"]["pet_events"] == pytest.approx(10.0)
    assert r["per_km"]["tit_s2"] == pytest.approx(64.68)
    assert ss["front"]["ttc_episodes"] == 0 and ss["front"]["pet_events"] is None
    # PET threshold 0.17 s: 0.1733 s is no longer below it
    assert evaluate(rear_run(), replace(EV, ssm_pet_threshold_s=0.17))["surrogate_safety"]["rear"]["pet_events"] == 0


def test_the_profile_is_beside_the_score():
    """The score is the same whatever the SSM thresholds; report.md has the section."""
    a = evaluate(two_sided_run(), EV)
    b = evaluate(two_sided_run(), replace(EV, ssm_ttc_threshold_s=1.0, ssm_pet_threshold_s=0.5))
    assert a["intelligence"] == b["intelligence"] and a["safety"] == b["safety"]
    text = markdown(a, [])
    assert "## Surrogate safety" in text
    assert "| TTC < 3 s episodes | 4 | 2 | 33.33 | 16.67 | count (episodes) |" in text
    assert "| PET < 2 s lane changes | – | 0 | – | 0 | count (lane changes) |" in text
