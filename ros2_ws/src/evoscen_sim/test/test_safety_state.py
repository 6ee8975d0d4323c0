"""The compiled one-state SUT leader/TTC equals the numpy definitions bit for bit.

The simulation node's live exposure events use :func:`evoscen_sim.danger.safety.sut_leader_ttc_state`;
the evaluator scores with :func:`sut_leader` / :func:`sut_ttc` over whole runs. The live
events and the scores must never disagree, so the two are compared here on hand-placed
edge cases, random dense states and every state of a simulated run.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from evoscen_sim.danger.safety import (
    RearAttribution,
    attribution_steps,
    beside_dangerous,
    beside_gap,
    beside_gap_state,
    beside_severity,
    cut_in_dangerous,
    cut_in_gap,
    cut_in_gap_state,
    drac,
    drac_one,
    follower_ttc,
    headway_dangerous,
    held_longer_than,
    rear_attributed,
    sut_follower,
    sut_follower_ttc_state,
    sut_leader,
    sut_leader_ttc_state,
    sut_ttc,
)


def _numpy(s, d, v, length, width, sut):
    leader = int(sut_leader(s, d, length, width, sut)[0])
    return leader, float(sut_ttc(s, d, v, length, width, sut))


def _same(s, d, v, length, width, sut) -> tuple[int, float]:
    arrays = [np.ascontiguousarray(x, dtype=float) for x in (s, d, v, length, width)]
    want = _numpy(*arrays, sut)
    got = sut_leader_ttc_state(*arrays, sut)
    assert got[0] == want[0], f"leader {got[0]} != {want[0]}"
    # bit-identical, inf and signed zero included
    assert np.float64(got[1]).tobytes() == np.float64(want[1]).tobytes(), f"ttc {got[1]!r} != {want[1]!r}"
    return want


W, L = 1.8, 4.5


@pytest.mark.parametrize("case, svd, leader, ttc", [
    # the SUT is vehicle 0; svd = s, d, v of every vehicle
    ("no one ahead", ([0.0, -10.0], [0.0, 0.0], [20.0, 30.0]), -1, math.inf),
    ("ahead, closing", ([0.0, 24.5], [0.0, 0.0], [20.0, 10.0]), 1, 2.0),
    ("ahead, opening", ([0.0, 24.5], [0.0, 0.0], [20.0, 25.0]), 1, math.inf),
    ("ahead, same speed", ([0.0, 24.5], [0.0, 0.0], [20.0, 20.0]), 1, math.inf),
    ("bodies overlap: gap < 0 -> 0", ([0.0, 2.0], [0.0, 0.0], [20.0, 10.0]), 1, 0.0),
    ("beside, no lateral overlap", ([0.0, 24.5], [0.0, 1.8], [20.0, 10.0]), -1, math.inf),
    ("cutting in: lateral overlap", ([0.0, 24.5], [0.0, 1.79], [20.0, 10.0]), 1, 2.0),
    ("level with the SUT is not ahead", ([0.0, 0.0], [0.0, 0.0], [20.0, 10.0]), -1, math.inf),
    ("nearest of several", ([0.0, 60.0, 30.0, 45.0], [0.0, 0.0, 0.5, -0.5], [20.0, 0.0, 10.0, 0.0]), 2, 2.55),
    ("equal distances: the first", ([0.0, 30.0, 30.0], [0.0, 0.4, -0.4], [20.0, 10.0, 5.0]), 1, 2.55),
])
def test_edge_cases(case: str, svd: tuple, leader: int, ttc: float) -> None:
    s, d, v = (np.array(x) for x in svd)
    got = _same(s, d, v, np.full(s.size, L), np.full(s.size, W), 0)
    assert got[0] == leader, case
    assert got[1] == pytest.approx(ttc), case


def test_sut_not_first_and_nan() -> None:
    s = np.array([30.0, 0.0, 24.5, np.nan])
    d = np.array([0.0, 0.0, 0.2, 0.0])
    v = np.array([10.0, 20.0, 12.0, 10.0])
    assert _same(s, d, v, np.full(4, L), np.full(4, W), 1)[0] == 2


def test_random_dense_states() -> None:
    rng = np.random.default_rng(7)
    for _ in range(3000):
        n = int(rng.integers(2, 30))
        s = np.round(rng.uniform(0.0, 120.0, n), int(rng.integers(0, 3)))  # rounding makes ties and overlaps
        d = rng.choice([-3.75, 0.0, 3.75], n) + rng.normal(0.0, 0.8, n)
        v = rng.uniform(0.0, 35.0, n)
        length = rng.uniform(3.5, 12.0, n)
        width = rng.uniform(1.6, 2.6, n)
        _same(s, d, v, length, width, int(rng.integers(0, n)))


def test_every_state_of_a_run() -> None:
    from evoscen_bringup.scenario import build_scenario
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.scenario_builders import SUT_INDEX

    sc = build_scenario(load_scenario_config(None, {"steps": 1500, "sut.model": "mobil"}))
    w = sc.world
    leaders = set()
    for _ in range(1500):
        leaders.add(_same(w.s, w.d, w.v, w.length, w.width, SUT_INDEX)[0])
        sc.step()
    assert len(leaders) > 1  # the SUT had leaders (and maybe none) during the run


# ---------------------------------------------------------------------- the follower (rear conflicts)


def _same_follower(s, d, v, length, width, sut) -> tuple[int, float]:
    arrays = [np.ascontiguousarray(x, dtype=float) for x in (s, d, v, length, width)]
    f, ttc = follower_ttc(*arrays, sut)
    want = int(f), float(ttc)
    assert want[0] == int(sut_follower(arrays[0], arrays[1], arrays[3], arrays[4], sut)[0])
    got = sut_follower_ttc_state(*arrays, sut)
    assert got[0] == want[0], f"follower {got[0]} != {want[0]}"
    assert np.float64(got[1]).tobytes() == np.float64(want[1]).tobytes(), f"ttc {got[1]!r} != {want[1]!r}"
    return want


@pytest.mark.parametrize("case, svd, follower, ttc", [
    # the SUT is vehicle 0
    ("no one behind", ([0.0, 10.0], [0.0, 0.0], [20.0, 30.0]), -1, math.inf),
    # SUT at s=100 v=25, follower at s=90 v=30 (length 4.8): gap 10 - 4.8 = 5.2 m, TTC 5.2 / 5 = 1.04 s
    ("closing at 5 m/s (docs/evaluation.md §3)", ([100.0, 90.0], [0.0, 0.0], [25.0, 30.0]), 1, 1.04),
    ("behind, falling back", ([100.0, 90.0], [0.0, 0.0], [25.0, 20.0]), 1, math.inf),
    ("bodies overlap: gap < 0 -> 0", ([100.0, 98.0], [0.0, 0.0], [25.0, 30.0]), 1, 0.0),
    ("beside, no lateral overlap", ([100.0, 90.0], [0.0, 1.9], [25.0, 30.0]), -1, math.inf),
    ("level is not behind", ([100.0, 100.0], [0.0, 0.0], [25.0, 30.0]), -1, math.inf),
    ("nearest of several", ([100.0, 60.0, 80.0, 70.0], [0.0, 0.0, 0.5, -0.5], [20.0, 40.0, 30.0, 40.0]), 2, 1.52),
    ("equal distances: the first", ([100.0, 80.0, 80.0], [0.0, 0.4, -0.4], [20.0, 30.0, 40.0]), 1, 1.52),
])
def test_follower_edge_cases(case: str, svd: tuple, follower: int, ttc: float) -> None:
    s, d, v = (np.array(x) for x in svd)
    got = _same_follower(s, d, v, np.full(s.size, 4.8), np.full(s.size, 1.9), 0)
    assert got[0] == follower, case
    assert got[1] == pytest.approx(ttc), case


def test_follower_random_dense_states() -> None:
    rng = np.random.default_rng(11)
    for _ in range(3000):
        n = int(rng.integers(2, 30))
        s = np.round(rng.uniform(0.0, 120.0, n), int(rng.integers(0, 3)))
        d = rng.choice([-3.75, 0.0, 3.75], n) + rng.normal(0.0, 0.8, n)
        v = rng.uniform(0.0, 35.0, n)
        length = rng.uniform(3.5, 12.0, n)
        width = rng.uniform(1.6, 2.6, n)
        _same_follower(s, d, v, length, width, int(rng.integers(0, n)))
    s = np.array([30.0, 0.0, 24.5, np.nan])  # nan positions never count
    assert _same_follower(s, np.array([0.0, 0.0, 0.2, 0.0]), np.full(4, 20.0), np.full(4, L), np.full(4, W), 0)[0] == 2


def test_follower_every_state_of_a_run() -> None:
    from evoscen_bringup.scenario import build_scenario
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.scenario_builders import SUT_INDEX

    sc = build_scenario(load_scenario_config(None, {"steps": 800}))
    w = sc.world
    followers = set()
    for _ in range(800):
        followers.add(_same_follower(w.s, w.d, w.v, w.length, w.width, SUT_INDEX)[0])
        sc.step()
    assert len(followers) > 1


def test_drac_by_hand() -> None:
    # SUT at s=100 v=25 followed at s=90 by v=30: gap 5.2 m, DRAC = 5^2 / (2 * 5.2) = 2.4038 m/s^2
    assert float(drac(np.float64(5.2), np.float64(30.0), np.float64(25.0))) == pytest.approx(25.0 / 10.4)
    assert float(drac(np.float64(5.2), np.float64(20.0), np.float64(25.0))) == 0.0  # opening
    assert float(drac(np.float64(0.0), np.float64(30.0), np.float64(25.0))) == math.inf  # closing at gap 0
    assert float(drac(np.float64(np.inf), np.float64(30.0), np.float64(np.nan))) == 0.0  # nobody


def test_rear_attribution_window_edges() -> None:
    lc = np.zeros(30, dtype=np.int64)
    lc[5:9] = 1  # a SUT lane change over states 5..8: attributed 5 .. 8 + 3 = 11 with 3 states after
    want = np.zeros(30, dtype=bool)
    want[5:12] = True
    assert (rear_attributed(lc, "after_lane_change", 3) == want).all()
    assert rear_attributed(lc, "all", 3).all() and not rear_attributed(lc, "none", 3).any()
    lc[20:22] = -1  # a second change: its own window 20..24
    want[20:25] = True
    assert (rear_attributed(lc, "after_lane_change", 3) == want).all()
    assert (rear_attributed(lc, "after_lane_change", 0) == (lc != 0)).all()
    live = RearAttribution("after_lane_change", 3)  # the monitor's one-state-at-a-time version agrees
    assert [live.observe(k, int(x)) for k, x in enumerate(lc)] == want.tolist()
    assert attribution_steps(5.0, 0.1) == 50 and attribution_steps(0.3, 0.1) == 3 and attribution_steps(0.0, 0.1) == 0


# ---------------------------------------------------------------------- the SUT's cut-ins


def _same_vehicle_and_gap(numpy_fn, state_fn, columns, sut: int, what: str) -> tuple[int, float]:
    """``numpy_fn`` (whole-run numpy definition) and ``state_fn`` (its compiled one-state twin) give the
    same vehicle and the same gap, bit for bit, on one state; returns them."""
    arrays = [np.ascontiguousarray(x, dtype=float) for x in columns]
    j, gap = numpy_fn(*arrays, sut)
    want = int(j), float(gap)
    got = state_fn(*arrays, sut)
    assert got[0] == want[0], f"{what} {got[0]} != {want[0]}"
    assert np.float64(got[1]).tobytes() == np.float64(want[1]).tobytes(), f"gap {got[1]!r} != {want[1]!r}"
    return want


def _same_cut_in(s, d, length, width, lane, target, lc, sut) -> tuple[int, float]:
    return _same_vehicle_and_gap(cut_in_gap, cut_in_gap_state, (s, d, length, width, lane, target, lc), sut,
                                 "new follower")


@pytest.mark.parametrize("case, sdl, lc, follower, gap", [
    # the SUT (vehicle 0) at s = 100, d = 2.1 (its body over the line), lane 2, changing left (+1) into lane 3;
    # bodies 4.8 x 1.9 m. sdl = s, d, lane of every vehicle.
    # vehicle 1 in lane 3 (d = 3.5) 10 m behind: |Δd| 1.4 < 1.9, gap 10 - 4.8 = 5.2 m
    ("new follower 5.2 m behind", ([100.0, 90.0], [2.1, 3.5], [2, 3]), 1, 1, 5.2),
    ("the SUT keeps its lane", ([100.0, 90.0], [2.1, 3.5], [2, 3]), 0, -1, math.inf),
    # the SUT's body not yet in lane 3: d = 1.4, |Δd| = 2.1 > 1.9
    ("body not yet over the line", ([100.0, 90.0], [1.4, 3.5], [2, 3]), 1, -1, math.inf),
    # vehicle 1 behind in the SUT's own lane (2), overlapping: the old follower, not a new one
    ("old lane's follower", ([100.0, 90.0], [2.1, 1.0], [2, 2]), 1, -1, math.inf),
    ("ahead is not a follower", ([100.0, 110.0], [2.1, 3.5], [2, 3]), 1, -1, math.inf),
    # two in lane 3: the nearer (s = 80) of 60 and 80; gap 20 - 4.8 = 15.2 m
    ("nearest of several", ([100.0, 60.0, 80.0], [2.1, 3.5, 3.4], [2, 3, 3]), 1, 2, 15.2),
    ("bodies overlap: gap < 0", ([100.0, 97.0], [2.1, 3.5], [2, 3]), 1, 1, -1.8),
])
def test_cut_in_edge_cases(case: str, sdl: tuple, lc: int, follower: int, gap: float) -> None:
    s, d, lane = (np.array(x, dtype=float) for x in sdl)
    n = s.size
    target = lane.copy()
    target[0] = 3.0
    lcs = np.zeros(n)
    lcs[0] = lc
    got = _same_cut_in(s, d, np.full(n, 4.8), np.full(n, 1.9), lane, target, lcs, 0)
    assert got[0] == follower, case
    assert got[1] == pytest.approx(gap), case
    # dangerous below cut_in_gap_m (10 m, the method's BV rule constraint); 0 turns the rule off
    assert bool(cut_in_dangerous(np.float64(got[1]), 10.0)) == (got[1] < 10.0)
    assert not cut_in_dangerous(np.float64(got[1]), 0.0)


def test_cut_in_threshold_by_hand() -> None:
    gap = np.array([5.2, 9.99, 10.0, 15.2, np.inf, -1.8])
    assert cut_in_dangerous(gap, 10.0).tolist() == [True, True, False, False, False, True]
    assert cut_in_dangerous(gap, 5.0).tolist() == [False, False, False, False, False, True]
    assert cut_in_dangerous(gap, 0.0).tolist() == [False] * 6


def test_cut_in_random_dense_states() -> None:
    rng = np.random.default_rng(13)
    for _ in range(3000):
        n = int(rng.integers(2, 30))
        s = np.round(rng.uniform(0.0, 120.0, n), int(rng.integers(0, 3)))
        lane = rng.integers(0, 5, n).astype(float)
        d = (lane - 2.0) * 3.5 + rng.normal(0.0, 0.8, n)
        target = np.clip(lane + rng.choice([-1.0, 0.0, 1.0], n), 0, 4)
        lc = rng.choice([-1.0, 0.0, 1.0], n)
        _same_cut_in(s, d, rng.uniform(3.5, 12.0, n), rng.uniform(1.6, 2.6, n), lane, target, lc,
                     int(rng.integers(0, n)))


def _same_beside(s, length, lane, target, lc, sut) -> tuple[int, float]:
    return _same_vehicle_and_gap(beside_gap, beside_gap_state, (s, length, lane, target, lc), sut, "vehicle beside")


@pytest.mark.parametrize("case, slt, lc, vehicle, gap", [
    # the SUT (vehicle 0) at s = 100 in lane 2, changing left (+1) into lane 3; bodies 4.8 m long.
    # slt = s, lane, target lane of every vehicle; gap = |Δs| - 4.8 (negative: beside)
    ("beside, 2 m behind: overlap 2.8 m", ([100.0, 98.0], [2, 3], [2, 3]), 1, 1, -2.8),
    ("beside, 1 m ahead: overlap 3.8 m", ([100.0, 101.0], [2, 3], [2, 3]), 1, 1, -3.8),
    ("level with the SUT: overlap 4.8 m", ([100.0, 100.0], [2, 3], [2, 3]), 1, 1, -4.8),
    ("5 m behind: 0.2 m clear", ([100.0, 95.0], [2, 3], [2, 3]), 1, 1, 0.2),
    ("the SUT keeps its lane", ([100.0, 98.0], [2, 3], [2, 3]), 0, -1, math.inf),
    # in the SUT's own lane (2), keeping it: not in the target lane
    ("own lane", ([100.0, 98.0], [2, 2], [2, 2]), 1, -1, math.inf),
    # lane 4 changing right into lane 3: heading for the same lane from the other side
    ("changing into the same lane", ([100.0, 97.0], [2, 4], [2, 3]), 1, 1, -1.8),
    # lane 4 keeping its lane: not in the target lane
    ("two lanes over", ([100.0, 100.0], [2, 4], [2, 4]), 1, -1, math.inf),
    # in lane 3 leaving it for lane 4 (the far side): it moves away as the SUT moves in
    ("leaving on the far side", ([100.0, 98.0], [2, 3], [2, 4]), 1, -1, math.inf),
    # in lane 3 changing into lane 2, the SUT's: the two swap lanes, towards each other
    ("swapping lanes", ([100.0, 98.0], [2, 3], [2, 2]), 1, 1, -2.8),
    # two in lane 3: the smaller gap (|Δs| 3 < 20) whether behind or ahead
    ("nearest of several", ([100.0, 80.0, 103.0], [2, 3, 3], [2, 3, 3]), 1, 2, -1.8),
])
def test_beside_edge_cases(case: str, slt: tuple, lc: int, vehicle: int, gap: float) -> None:
    s, lane, target = (np.array(x, dtype=float) for x in slt)
    target[0] = 3.0
    lcs = np.zeros(s.size)
    lcs[0] = lc
    got = _same_beside(s, np.full(s.size, 4.8), lane, target, lcs, 0)
    assert got[0] == vehicle, case
    assert got[1] == pytest.approx(gap), case
    assert bool(beside_dangerous(np.float64(got[1]), True)) == (got[1] < 0.0)
    assert not beside_dangerous(np.float64(got[1]), False)


def test_beside_severity_by_hand() -> None:
    # two 4.8 m bodies: half sum 4.8; touching 1, overlap 2.4 m 1.5, side by side 2
    assert beside_severity(np.array([0.0, -2.4, -4.8]), np.full(3, 9.6)).tolist() == [1.0, 1.5, 2.0]


def test_beside_random_dense_states() -> None:
    rng = np.random.default_rng(23)
    for _ in range(3000):
        n = int(rng.integers(2, 30))
        s = np.round(rng.uniform(0.0, 120.0, n), int(rng.integers(0, 3)))
        lane = rng.integers(0, 5, n).astype(float)
        target = np.clip(lane + rng.choice([-1.0, 0.0, 1.0], n), 0, 4)
        _same_beside(s, rng.uniform(3.5, 12.0, n), lane, target, rng.choice([-1.0, 0.0, 1.0], n),
                     int(rng.integers(0, n)))


def test_drac_one_is_drac_bit_for_bit() -> None:
    # docs/evaluation.md §3's example: 5 m/s closing at 5.2 m: 25 / 10.4 = 2.4038 m/s²; opening: 0; touching while closing: inf
    assert drac_one(5.2, 30.0, 25.0) == pytest.approx(25.0 / 10.4)
    assert drac_one(5.2, 25.0, 30.0) == 0.0 and drac_one(0.0, 30.0, 25.0) == math.inf
    rng = np.random.default_rng(17)
    gap = np.round(rng.uniform(-5.0, 120.0, 20000), int(rng.integers(0, 3)))
    v, vl = rng.uniform(0.0, 35.0, 20000), rng.uniform(0.0, 35.0, 20000)
    want = drac(gap, v, vl)
    got = np.array([drac_one(float(g), float(a), float(b)) for g, a, b in zip(gap, v, vl)])
    assert got.tobytes() == want.tobytes()


def test_headway_rule_by_hand():
    """Time headway gap / v_SUT below the threshold while not falling back (v_SUT >= v_leader)."""
    gap = np.array([20.0, 20.0, 20.0, 26.0, np.inf, 20.0, -1.0])
    v = np.array([25.0, 25.0, 24.0, 25.0, 25.0, 0.0, 10.0])
    vl = np.array([25.0, 26.0, 20.0, 20.0, np.nan, 0.0, 10.0])
    # 0.8 s level: yes; 0.8 s but the leader pulls away: no; 0.83 s closing: yes; 1.04 s: no; no leader: no;
    # at rest: no; bodies overlapping (negative gap), level: yes
    assert headway_dangerous(gap, v, vl, 1.0).tolist() == [True, False, True, False, False, False, True]
    assert not headway_dangerous(gap, v, vl, 0.0).any()  # off
    assert headway_dangerous(np.float64(20.0), np.float64(25.0), np.float64(25.0), 0.8).tolist() is False  # 0.8 < 0.8: no


def test_headway_grace_counts_unbroken_runs_across_blocks():
    cond = np.array([1, 1, 1, 0, 1, 1, 1, 1], dtype=bool)
    held, carry = held_longer_than(cond, 2)  # more than 2 states unbroken: the 3rd of a run on
    assert held.tolist() == [False, False, True, False, False, False, True, True] and carry == 4
    # the same states split into blocks of 3 and 5, the run carried over: the same answer
    a, c = held_longer_than(cond[:3], 2)
    b, c = held_longer_than(cond[3:], 2, c)
    assert np.concatenate([a, b]).tolist() == held.tolist() and c == 4
    # a run still unbroken at a block's end continues in the next
    a, c = held_longer_than(np.array([True, True]), 2)
    b, _ = held_longer_than(np.array([True, False]), 2, c)
    assert (a.tolist(), b.tolist()) == ([False, False], [True, False])


def test_one_value_test_and_the_scalar_paths_agree_with_the_arrays() -> None:
    from evoscen_sim.danger.safety import _one, follower_headway, headway_dangerous, held_longer_than

    for x in (1.0, 3, True, np.float64(2.5), np.int64(4), np.bool_(False), np.array(1.0), np.float32(1.0)):
        assert _one(x), x
    for x in (np.array([1.0]), [1.0], np.zeros((2, 2))):
        assert not _one(x), x
    # by hand: 20 m at 25 m/s is 0.8 s < 1 s while not slower than the leader; 30 m is 1.2 s
    assert bool(headway_dangerous(20.0, 25.0, 24.0, 1.0)) is True
    assert bool(headway_dangerous(30.0, 25.0, 24.0, 1.0)) is False
    assert bool(headway_dangerous(20.0, 25.0, 26.0, 1.0)) is False  # falling back
    assert bool(headway_dangerous(math.inf, 25.0, math.nan, 1.0)) is False
    gaps, v, vl = np.array([20.0, 30.0, 20.0, math.inf]), np.full(4, 25.0), np.array([24.0, 24.0, 26.0, math.nan])
    assert headway_dangerous(gaps, v, vl, 1.0).tolist() == [True, False, False, False]
    assert [bool(headway_dangerous(np.float64(g), np.float64(25.0), np.float64(u), 1.0))
            for g, u in zip(gaps, vl)] == [True, False, False, False]
    assert float(follower_headway(10.0, 20.0)) == 0.5 and float(follower_headway(10.0, 0.0)) == math.inf
    assert follower_headway(np.array([10.0, 10.0]), np.array([20.0, 0.0])).tolist() == [0.5, math.inf]
    # a run of 3 states held, grace 2: the third is past the grace; a scalar state continues a carry of 2
    held, run = held_longer_than(np.array([True, True, True]), 2)
    assert held.tolist() == [False, False, True] and run == 3
    assert held_longer_than(np.bool_(True), 2, carry=2) == (True, 3)
    assert held_longer_than(False, 2, carry=2) == (False, 0)
