"""One definition of the SUT's dangerous state (:func:`evoscen_sim.danger.safety.danger_terms`).

The live monitor (:class:`evoscen_sim.danger.events.ExposureMonitor`, one state at a time) and the scorer
(:class:`evoscen_eval.scoring.streaming.ScoreStream`, blocks of states) both call it: shown here by
watching the calls, and the two paths agree state by state on hand-built runs whose dangerous
states are derived by hand.
"""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import evoscen_eval.scoring.streaming as streaming
import evoscen_sim.danger.events as events
import numpy as np
import pytest
from evoscen_eval.scoring.metrics import evaluate
from evoscen_eval.scoring.run_fixtures import make_run
from evoscen_sim.config.scenario_config import EvaluationConfig
from evoscen_sim.danger.safety import danger_terms

EV = EvaluationConfig()
DT = 0.1


# ---------------------------------------------------------------------- the function by hand


def test_ttc_below_the_threshold_is_dangerous():
    # TTC 1.9 s < 2 s: dangerous by the TTC term alone; 2.1 s is not
    terms, _ = danger_terms(EV, DT, ttc=1.9, sut_accel=0.0)
    assert bool(terms.low_ttc) and bool(terms.front) and bool(terms.danger)
    assert not (terms.braking or terms.rear or terms.cut_in or terms.beside or terms.tailgating)
    terms, _ = danger_terms(EV, DT, ttc=2.1, sut_accel=0.0)
    assert not terms.danger


def test_each_term_by_hand():
    ev = replace(EV, hard_braking="own", rear_conflicts="all")
    one = dict(ttc=np.inf, sut_accel=0.0)
    # own rule: acceleration -6.1 < -6 m/s^2
    assert bool(danger_terms(ev, DT, **(one | {"sut_accel": -6.1}))[0].braking)
    # conflict rule: DRAC 6.5 > 6 m/s^2 whatever the SUT does
    assert bool(danger_terms(EV, DT, **(one | {"drac_sut": 6.5}))[0].braking)
    # a follower 1.5 s behind in TTC: a rear conflict, dangerous only where attributed
    t, _ = danger_terms(ev, DT, **(one | {"follower_ttc_s": 1.5}))
    assert bool(t.rear_conflict) and not t.rear and not t.danger
    t, _ = danger_terms(ev, DT, **(one | {"follower_ttc_s": 1.5, "attributed": True}))
    assert bool(t.rear) and bool(t.danger) and not t.front
    # the new follower 9 m behind (< 10 m) and an overlap beside (gap -0.5 m)
    assert bool(danger_terms(EV, DT, **(one | {"cut_in_gap_m": 9.0}))[0].cut_in)
    assert not danger_terms(EV, DT, **(one | {"cut_in_gap_m": 11.0}))[0].danger
    assert bool(danger_terms(EV, DT, **(one | {"beside_gap_m": -0.5}))[0].beside)
    assert not danger_terms(replace(EV, beside_lane_change=False), DT, **(one | {"beside_gap_m": -0.5}))[0].danger


@pytest.mark.parametrize("held_states, dangerous_states", [(15, 0), (20, 0), (21, 1), (25, 5)])
def test_tailgating_grace_by_hand(held_states, dangerous_states):
    """Time headway 22.5 m / 25 m/s = 0.9 s < 1 s behind a leader as fast: the condition holds.
    With a 2 s grace (20 states at 0.1 s) a state is dangerous once it has held for more than 20
    states: held 1.5 s (15 states) or 2.0 s never, 2.1 s (21 states) from the 21st state on."""
    ev = replace(EV, headway_threshold_s=1.0, headway_grace_s=2.0)
    n = held_states + 3
    gap = np.where(np.arange(n) < held_states, 22.5, 30.0)  # then 1.2 s: the condition ends
    terms, run = danger_terms(ev, DT, ttc=np.full(n, np.inf), sut_accel=np.zeros(n), leader_gap_m=gap,
                              sut_speed=np.full(n, 25.0), leader_speed=np.full(n, 25.0))
    assert int(terms.tailgating.sum()) == dangerous_states == int(terms.danger.sum())
    assert np.flatnonzero(terms.danger).tolist() == list(range(20, held_states))
    assert run == 0
    # one state at a time, the run carried from call to call: the same states
    carry, one_by_one = 0, []
    for k in range(n):
        t, carry = danger_terms(ev, DT, ttc=np.inf, sut_accel=0.0, leader_gap_m=gap[k], sut_speed=25.0,
                                leader_speed=25.0, headway_run=carry)
        one_by_one.append(bool(t.danger))
    assert one_by_one == terms.danger.tolist()


# ---------------------------------------------------------------------- both paths


def _state(run, k: int) -> SimpleNamespace:
    """State ``k`` of a hand-built run as the monitor reads a world."""
    c = run.columns
    col = {f: np.ascontiguousarray(c[f][k], dtype=float) for f in c}
    return SimpleNamespace(s=col["s"], d=col["d"], v=col["speed"], accel=col["accel"], length=col["length"],
                           width=col["width"], lane=col["lane"], target_lane=col["target_lane"],
                           lane_change=col["lane_change"], ids=run.ids, dt_s=run.dt_s, step_index=k,
                           time_s=float(run.time_s[k]))


def _both_paths(run, ev, monkeypatch) -> tuple[list[bool], list[bool], dict]:
    """Per-state danger as the monitor and as the scorer found it (from the calls of
    :func:`danger_terms` each made), and the scorer's report."""
    calls: dict[str, list[np.ndarray]] = {"monitor": [], "scorer": []}

    def watched(who):
        def call(*args, **kwargs):
            terms, carry = danger_terms(*args, **kwargs)
            calls[who].append(np.atleast_1d(terms.danger))
            return terms, carry
        return call

    monkeypatch.setattr(events, "danger_terms", watched("monitor"))
    monkeypatch.setattr(streaming, "danger_terms", watched("scorer"))
    monitor = events.ExposureMonitor(ev, run.columns["role"][0])
    live = [e for k in range(len(run.time_s)) for e in monitor.observe(_state(run, k))]
    report = evaluate(run, ev)
    assert len(calls["monitor"]) == len(run.time_s)  # one call per state
    assert len(calls["scorer"]) >= 1  # one per block
    monitor_danger = np.concatenate(calls["monitor"]).tolist()
    scorer_danger = np.concatenate(calls["scorer"]).tolist()
    starts = [e["step"] for e in live if e["kind"] == "start"]
    assert starts == [x["start_state"] for x in report["safety"]["exposure_list"]]
    return monitor_danger, scorer_danger, report


def test_both_paths_agree_on_a_ttc_of_1_9_s(monkeypatch):
    """SUT (0) at 30 m/s, vehicle 1 ahead in its lane at 10 m/s: bumper gap 38 m in states 0..4
    (TTC 38 / 20 = 1.9 s, DRAC 20² / 76 = 5.3 m/s², headway 1.27 s), 42 m in states 5..9
    (TTC 2.1 s): dangerous in states 0..4 only."""
    run = make_run(10, 2)
    run.columns["speed"][:, 1] = 10.0
    run.columns["s"][:5, 1] = 1000.0 + 38.0 + 4.8
    run.columns["s"][5:, 1] = 1000.0 + 42.0 + 4.8
    monitor, scorer, report = _both_paths(run, EV, monkeypatch)
    assert monitor == scorer == [True] * 5 + [False] * 5
    ex = report["safety"]["exposure_list"]
    assert [(x["start_state"], x["states"]) for x in ex] == [(0, 5)]
    assert ex[0]["min_ttc_s"] == pytest.approx(1.9)


@pytest.mark.parametrize("held_states, expected", [(15, []), (21, [(20, 1)])])
def test_both_paths_agree_on_tailgating_with_a_grace(monkeypatch, held_states, expected):
    """SUT and vehicle 1 ahead both at 30 m/s; bumper gap 27 m (headway 0.9 s) for ``held_states``
    states from state 0, then 36 m (1.2 s). Grace 2 s = 20 states: held 1.5 s, no dangerous
    state; held 2.1 s, one (state 20, the 21st of the run)."""
    ev = replace(EV, headway_threshold_s=1.0, headway_grace_s=2.0)
    run = make_run(30, 2)
    run.columns["s"][:, 1] = 1000.0 + 36.0 + 4.8
    run.columns["s"][:held_states, 1] = 1000.0 + 27.0 + 4.8
    monitor, scorer, report = _both_paths(run, ev, monkeypatch)
    assert monitor == scorer
    assert [k for k, x in enumerate(scorer) if x] == [s for s, n in expected for s in range(s, s + n)]
    ex = report["safety"]["exposure_list"]
    assert [(x["start_state"], x["states"]) for x in ex] == expected
    assert report["safety"]["conflicts"]["headway_states"] == sum(n for _, n in expected)


def test_both_paths_agree_across_the_scorers_blocks(monkeypatch):
    """The tailgating run spans the scorer's block boundary (256 states): headway 0.9 s in states
    240..270 (31 states), grace 2 s: dangerous in states 260..270, one exposure of 11 states."""
    assert streaming.BLOCK_STATES == 256
    ev = replace(EV, headway_threshold_s=1.0, headway_grace_s=2.0)
    run = make_run(300, 2)
    run.columns["s"][:, 1] = 1000.0 + 36.0 + 4.8
    run.columns["s"][240:271, 1] = 1000.0 + 27.0 + 4.8
    monitor, scorer, report = _both_paths(run, ev, monkeypatch)
    assert monitor == scorer
    assert [k for k, x in enumerate(scorer) if x] == list(range(260, 271))
    assert [(x["start_state"], x["states"]) for x in report["safety"]["exposure_list"]] == [(260, 11)]


def test_one_state_equals_the_array_form_on_random_states():
    """The monitor gives floats (one state), the scorer arrays: the same terms, state by state,
    on random quantities around every threshold (gaps with inf, leader speeds with nan; the
    leader's quantities held over 8 states, so that the headway condition outlasts the grace)."""
    rng = np.random.default_rng(7)
    n = 2000
    ev = replace(EV, headway_grace_s=0.3, rear_conflicts="all")
    q = {"ttc": rng.choice([np.inf, 0.5, 1.99, 2.0, 3.0], n), "sut_accel": rng.uniform(-8.0, 2.0, n),
         "drac_sut": rng.choice([0.0, 5.9, 6.0, 6.1, np.inf], n), "follower_ttc_s": rng.choice([np.inf, 1.0, 2.5], n),
         "follower_accel": rng.uniform(-8.0, 1.0, n), "follower_thw_s": rng.choice([np.inf, 1.0, 3.0, -0.2], n),
         "attributed": rng.random(n) < 0.5, "leader_gap_m": rng.choice([np.inf, -1.0, 0.0, 10.0, 24.0, 26.0], n),
         "sut_speed": rng.choice([0.0, 20.0, 25.0], n), "leader_speed": rng.choice([np.nan, 19.0, 25.0, 30.0], n),
         "cut_in_gap_m": rng.choice([np.inf, 5.0, 10.0, 15.0], n), "beside_gap_m": rng.choice([np.inf, -1.0, 0.0], n)}
    for key in ("leader_gap_m", "sut_speed", "leader_speed"):  # held for 8 states: the grace (3 states) passes
        q[key] = np.repeat(q[key][::8], 8)
    whole, _ = danger_terms(ev, DT, **q)
    carry = 0
    for k in range(n):
        one, carry = danger_terms(ev, DT, **{key: (bool(x[k]) if x.dtype == bool else float(x[k]))
                                             for key, x in q.items()}, headway_run=carry)
        assert all(isinstance(v, bool) for v in one), k
        assert [bool(v) for v in one] == [bool(v[k]) for v in whole], k
    assert 0 < int(whole.tailgating.sum()) < int(whole.danger.sum()) < n
