"""The traffic against highD's aggregates (evoscen_eval.naturalistic.fidelity_highd, docs/fidelity.md), on hand-built
runs with values derived by hand.

Lanes 3.5 m wide, lane i's centre at d = -(4 - i)*3.5 - 1.75 (the virtual road's laneId = 12 - i);
dt = 1 s. Pieces are 100 m long in the hand-built cases (``piece_m`` is a setting; 420 m by default),
so the arithmetic stays small.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from evoscen_eval.naturalistic.fidelity_highd import (Measures, PieceConfig, compare, histogram_similarity, lane_change_rates,
                                         load_reference, markdown_table, run_density, run_measures)
from evoscen_eval.naturalistic.highd_export import VirtualRoad
from evoscen_eval.naturalistic.similarity import js_divergence

ROAD = VirtualRoad(length_m=20000.0)
CAR, TRUCK, WIDTH = 4.5, 12.0, 1.9


def lane_centre(i: int) -> float:
    return -(4 - i) * 3.5 - 1.75


def make_run(vehicles: list[dict], states: int, events: list[dict] | None = None, scenario: dict | None = None):
    """A RunData-shaped run (dt 1 s) from per-vehicle dicts: id, role, s(t), lane(t), speed(t), length."""
    t = np.arange(states, dtype=float)
    names = ("id", "role", "s", "d", "speed", "accel", "heading_rel", "length", "width", "lane")
    cols = {name: np.zeros((states, len(vehicles))) for name in names}
    for j, v in enumerate(vehicles):
        lane = np.broadcast_to(np.asarray(v["lane"], dtype=float), t.shape)
        cols["id"][:, j] = v["id"]
        cols["role"][:, j] = v.get("role", 0)
        cols["s"][:, j] = v["s"]
        cols["lane"][:, j] = lane
        cols["d"][:, j] = [lane_centre(int(i)) for i in lane]
        cols["speed"][:, j] = v["speed"]
        cols["length"][:, j] = v.get("length", CAR)
        cols["width"][:, j] = WIDTH
    sut = [j for j, v in enumerate(vehicles) if v.get("role", 0) == 1][0]
    return SimpleNamespace(time_s=t, columns=cols, ids=np.array([v["id"] for v in vehicles]), sut_index=sut,
                           events=events if events is not None else [], scenario=scenario, warnings=[], states=states,
                           dt_s=1.0)


# ---------------------------------------------------------------- similarity over the reference's bins


def test_identical_histograms_have_similarity_one():
    h = histogram_similarity([1, 2, 1], [0, 1, 2, 3], [0.5, 1.5, 1.5, 2.5])
    assert h["js"] == pytest.approx(0.0, abs=1e-12)
    assert h["similarity"] == pytest.approx(1.0)
    assert h["sim_counts"] == [1, 2, 1]


def test_disjoint_histograms_have_similarity_zero():
    h = histogram_similarity([5, 0], [0, 1, 2], [1.5, 1.7])
    assert h["js"] == pytest.approx(1.0)
    assert h["similarity"] == pytest.approx(0.0, abs=1e-12)


def test_two_bin_case_by_hand():
    # P = (1/2, 1/2), Q = (1, 0), M = (3/4, 1/4):
    # KL(P||M) = 1/2 log2(2/3) + 1/2 log2 2 = 1 - 1/2 log2 3;  KL(Q||M) = log2(4/3) = 2 - log2 3
    # JS = 1/2 (3 - 3/2 log2 3) = 1.5 - 0.75 log2 3 = 0.311278...
    expected = 1.5 - 0.75 * math.log2(3.0)
    h = histogram_similarity([10, 10], [0.0, 1.0, 2.0], [0.2, 0.4, 0.9])
    assert h["js"] == pytest.approx(expected, rel=1e-12)
    assert h["similarity"] == pytest.approx(1.0 - expected, rel=1e-12)
    assert js_divergence(np.array([0.5, 0.5]), np.array([1.0, 0.0])) == pytest.approx(expected, rel=1e-12)


def test_values_outside_the_bins_are_left_out_and_counted():
    # bins [0, 1), [1, 2]: -1 below, 2 lands in the closed last bin, 3 and NaN above / left out
    h = histogram_similarity([1, 1], [0, 1, 2], [-1.0, 0.5, 2.0, 3.0, float("nan")])
    assert h["sim_counts"] == [1, 1]
    assert (h["n"], h["n_in_bins"], h["n_below"], h["n_above"]) == (4, 2, 1, 1)
    assert h["similarity"] == pytest.approx(1.0)
    assert math.isnan(histogram_similarity([1, 1], [0, 1, 2], [5.0])["similarity"])


# ---------------------------------------------------------------- pieces, minima and classes


def traffic_run():
    """26 states (t = 0..25 s):

    * A (BV, car) lane 2, s = 10 t (10 m/s), behind the SUT B (lane 2, s = 80 + 8 t, 8 m/s): bumper gap
      80 + 8t - 10t - 4.5 = 75.5 - 2t, closing at 2 m/s. Pieces of 100 m: t = 0..9, 10..19 (full);
      t = 20..25 (50 m, a remainder).
    * C (BV, truck 12 m) lane 3 alone, s = 20 t: pieces t = 0..4, 5..9, 10..14, 15..19, 20..24; t = 25
      (u = 500) starts a piece of 0 m. No leader.
    * E (BV, car) lane 1, s = 10 t, behind F (BV, car, lane 1, s = 30 + 12 t): gap 25.5 + 2t, opening.
    * F: u = 12 t: pieces t = 0..8, 9..16, 17..24 (u_last 300 reaches the third's end: full), no leader.
    """
    t = np.arange(26.0)
    return make_run([
        {"id": 1, "s": 10 * t, "lane": 2, "speed": 10.0},
        {"id": 0, "role": 1, "s": 80 + 8 * t, "lane": 2, "speed": 8.0},
        {"id": 2, "s": 20 * t, "lane": 3, "speed": 20.0, "length": TRUCK},
        {"id": 3, "s": 10 * t, "lane": 1, "speed": 10.0},
        {"id": 4, "s": 30 + 12 * t, "lane": 1, "speed": 12.0},
    ], 26)


def by_piece(m):
    return [(bool(tr), round(float(v), 9), mt, md, mc) for tr, v, mt, md, mc in
            zip(m.truck, m.mean_speed_mps, m.min_thw_s, m.min_dhw_m, m.min_ttc_s)]


def test_pieces_and_their_minima_by_hand():
    m = run_measures(traffic_run(), PieceConfig(piece_m=100.0, min_piece_m=100.0), road=ROAD)
    assert m.pieces == 2 + 5 + 2 + 3  # A, C, E, F; the SUT left out, remainders dropped
    nan = float("nan")
    rows = by_piece(m)
    # tracks in order of (first frame, id): A (1), C (2), E (3), F (4)
    expected = [
        # A: piece 0 ends at t = 9: gap 75.5 - 18 = 57.5 m, THW 5.75 s, TTC 57.5 / 2 = 28.75 s
        (False, 10.0, 5.75, 57.5, 28.75),
        # piece 1 ends at t = 19: gap 37.5 m, THW 3.75 s, TTC 18.75 s
        (False, 10.0, 3.75, 37.5, 18.75),
        *[(True, 20.0, nan, nan, nan)] * 5,
        # E: piece 0 starts at t = 0 with the smallest gap 25.5 m (THW 2.55 s), piece 1 at t = 10 (45.5 m);
        # the gap opens: no TTC
        (False, 10.0, 2.55, 25.5, nan),
        (False, 10.0, 4.55, 45.5, nan),
        *[(False, 12.0, nan, nan, nan)] * 3,
    ]
    assert len(rows) == len(expected)
    for got, want in zip(rows, expected):
        assert got[:2] == want[:2]
        np.testing.assert_allclose(got[2:], want[2:], rtol=1e-12, equal_nan=True)


def test_a_remainder_counts_when_long_enough_and_the_sut_on_request():
    run = traffic_run()
    m = run_measures(run, PieceConfig(piece_m=100.0, min_piece_m=50.0), road=ROAD)
    # A's remainder t = 20..25 (u 200..250, 50 m) is a piece: gap at t = 25 is 25.5 m, THW 2.55, TTC 12.75;
    # so is E's (gap at t = 20: 65.5 m, opening: no TTC); C's and F's last state alone (0 m) is none
    assert m.pieces == 14
    np.testing.assert_allclose([m.min_dhw_m[2], m.min_thw_s[2], m.min_ttc_s[2]], [25.5, 2.55, 12.75])
    np.testing.assert_allclose([m.min_dhw_m[10], m.min_thw_s[10]], [65.5, 6.55])
    assert np.isnan(m.min_ttc_s[10])
    with_sut = run_measures(run, PieceConfig(piece_m=100.0, include_sut=True), road=ROAD)
    # the SUT: u = 8 t, pieces t = 0..12 and 13..24 (u_last 200 reaches the second's end), no leader
    # (tracks in order of first frame, then id: the SUT, id 0, first)
    assert with_sut.pieces == 12 + 2
    assert np.isnan(with_sut.min_thw_s[:2]).all() and (with_sut.mean_speed_mps[:2] == 8.0).all()


def test_class_split_by_length_and_the_table():
    m = run_measures(traffic_run(), PieceConfig(piece_m=100.0), road=ROAD)
    result = compare(m, load_reference())
    speed = {r["class"]: r for r in result["rows"] if r["quantity"] == "mean speed"}
    assert (speed["all"]["n"], speed["car"]["n"], speed["truck"]["n"]) == (12, 7, 5)
    assert speed["truck"]["sim_mean"] == 20.0
    assert speed["car"]["sim_mean"] == pytest.approx((4 * 10.0 + 3 * 12.0) / 7)
    # highD's 120 km/h figures beside them (shipped aggregates)
    assert speed["truck"]["highd_mean"] == 23.84 and speed["car"]["highd_median"] == 31.45
    thw = {r["class"]: r for r in result["rows"] if r["quantity"] == "min THW"}
    assert thw["all"]["n"] == 4 and thw["all"]["sim_median"] == pytest.approx((3.75 + 4.55) / 2)  # of 2.55, 3.75, 4.55, 5.75
    # a 12-m vehicle is a truck at the default 7 m, a car if trucks must be longer than 12 m
    assert int(run_measures(traffic_run(), PieceConfig(piece_m=100.0, truck_length_m=12.0), road=ROAD).truck.sum()) == 0
    text = markdown_table(result)
    assert "| mean speed (m/s) | truck | 5 | 20.00 |" in text


def test_similarity_of_the_pieces_uses_the_reference_bins():
    m = run_measures(traffic_run(), PieceConfig(piece_m=100.0), road=ROAD)
    ref = load_reference()
    h = compare(m, ref)["histograms"]["per_vehicle_min_thw_s"]
    r = ref["speed_limit_120_kmh"]["per_vehicle_min_thw_s"]
    # THW 5.75, 3.75, 2.55, 4.55 s in bins [5.75, 6], [3.75, 4), [2.5, 2.75), [4.5, 4.75)
    want = np.zeros(24)
    want[[23, 15, 10, 18]] = 1
    assert h["sim_counts"] == want.tolist()
    assert h["similarity"] == pytest.approx(1.0 - js_divergence(np.asarray(r["counts"], float), want))


# ---------------------------------------------------------------- lane changes per km, trips, density


def test_lane_changes_per_km_over_trips_split_at_entries():
    # H (BV): t = 0..10 s = 25 t (0..250 m), lane 2 -> 3 at t = 5; a new trip at t = 11 (reentry event):
    # s = 1000 + 25 (t - 11), lane 1 for t <= 15, lane 2 after. Trips of 250 m and 225 m, one change
    # each; the jump from lane 3 to lane 1 between the trips is no change. 2 / 0.475 km.
    t = np.arange(21.0)
    s_h = np.where(t <= 10, 25 * t, 1000 + 25 * (t - 11))
    lane_h = np.where(t <= 4, 2, np.where(t <= 10, 3, np.where(t <= 15, 1, 2)))
    run = make_run([
        {"id": 0, "role": 1, "s": 5000 + 25 * t, "lane": 4, "speed": 25.0},
        {"id": 5, "s": s_h, "lane": lane_h, "speed": 25.0},
    ], 21, events=[{"name": "evoscen/reentry", "time_s": 11.0, "ids": [5]}])
    m = run_measures(run, PieceConfig(piece_m=100.0), road=ROAD)
    assert m.trip_lane_changes.tolist() == [1, 1]
    np.testing.assert_allclose(m.trip_km, [0.25, 0.225])
    # pieces: trip 1 t = 0..3, 4..7 (u_last 250); trip 2 t = 11..14, 15..18 (u_last 225)
    assert m.pieces == 4
    rates = {r["group"]: r for r in lane_change_rates(m, load_reference())}
    assert rates["all"]["sim_rate"] == pytest.approx(2 / 0.475)
    assert rates["car"]["lane_changes"] == 2 and rates["truck"]["vehicle_km"] == 0.0
    assert math.isnan(rates["truck"]["sim_rate"])


def test_run_density_and_its_bin():
    # SUT at s = 1000 (lane 2); section [850, 1250] (0.4 km) x 4 mainline lanes. Inside, on lanes >= 1:
    # the SUT and BVs at 900 (lane 1) and 1200 (lane 4): 3; not counted: 1300 (beyond), 950 on the merge
    # lane (0). 3 / 0.4 / 4 = 1.875 veh/km/lane at every state.
    t = np.arange(3.0)
    run = make_run([
        {"id": 0, "role": 1, "s": 1000 + 0 * t, "lane": 2, "speed": 0.0},
        {"id": 1, "s": 900 + 0 * t, "lane": 1, "speed": 0.0},
        {"id": 2, "s": 1200 + 0 * t, "lane": 4, "speed": 0.0},
        {"id": 3, "s": 1300 + 0 * t, "lane": 3, "speed": 0.0},
        {"id": 4, "s": 950 + 0 * t, "lane": 0, "speed": 0.0},
    ], 3, scenario={"traffic": {"behind_m": 150.0, "ahead_m": 250.0, "lane_density_per_km": [12.5] * 4}})
    assert run_density(run) == pytest.approx(1.875)
    # 50 m behind, 100 ahead ([950, 1100]): the SUT only (the BV at 950 is on lane 0): 1 / 0.15 / 4
    assert run_density(run, PieceConfig(behind_m=50.0, ahead_m=100.0)) == pytest.approx(1 / 0.15 / 4)
    # 1.875 lies below the reference's first density bin (5-10): its trips count under "outside the bins"
    m = run_measures(run, PieceConfig(piece_m=100.0), road=ROAD)
    groups = [r["group"] for r in lane_change_rates(m, load_reference())]
    assert groups[-1] == "density outside the bins" and "density 10-15 veh/km/lane" in groups


def test_pooled_runs_keep_each_run_s_density():
    # the traffic run twice; density: all five vehicles stay inside the default section [s_SUT - 150,
    # s_SUT + 250] on lanes 1-3, and without a scenario the mainline lanes are 1..the highest lane index (3):
    # 5 / 0.4 km / 3 lanes = 4.17 veh/km/lane, below highD's bins. The second run is told to be denser:
    # each trip keeps its own run's density.
    a = run_measures(traffic_run(), PieceConfig(piece_m=100.0), road=ROAD)
    assert a.runs[0]["density_veh_per_km_per_lane"] == pytest.approx(5 / 0.4 / 3)
    b = run_measures(traffic_run(), PieceConfig(piece_m=100.0), road=ROAD)
    b.runs[0]["density_veh_per_km_per_lane"] = 12.0
    both = Measures.concat([a, b])
    assert both.pieces == 24 and both.run.tolist() == [0] * 12 + [1] * 12
    assert both.trip_density().tolist() == [a.runs[0]["density_veh_per_km_per_lane"]] * 4 + [12.0] * 4
    rates = {r["group"]: r for r in lane_change_rates(both, load_reference())}
    assert rates["density 10-15 veh/km/lane"]["vehicle_km"] == pytest.approx(0.25 + 0.5 + 0.25 + 0.3)
    assert rates["density outside the bins"]["vehicle_km"] == pytest.approx(1.3)


def test_shipped_reference_is_the_120_kmh_subset():
    ref = load_reference()
    r = ref["speed_limit_120_kmh"]
    assert r["vehicles"] == 86676 and r["lane_changes_per_vehicle_km"] == 0.295
    assert sum(r["per_vehicle_min_thw_s"]["counts"]) <= r["per_vehicle_min_thw_s"]["n"]
    assert ref["all_recordings"]["lane_changes_per_vehicle_km"]["by_density_veh_per_km_per_lane"]["10-15"] == 0.307
    assert "Krajewski" in ref["citation"]


def test_piece_config_from_the_options_text():
    """scripts/fidelity_highd.py's measurement options: the remainder defaults to the piece length; each
    bad length is one line naming its option."""
    from evoscen_eval.naturalistic.fidelity_highd import piece_config
    from evoscen_sim.errors import InputError

    assert piece_config("300", None, "7.5", True) == PieceConfig(piece_m=300.0, min_piece_m=300.0, truck_length_m=7.5,
                                                                 include_sut=True)
    assert piece_config("300", "150").min_piece_m == 150.0
    for args, message in ((("0",), "--piece-m '0': expected a length > 0 (m)"),
                          (("420", "inf"), "--min-piece-m 'inf': expected a length > 0 (m)"),
                          (("420", None, "x"), "--truck-length 'x': expected a length > 0 (m)"),
                          (("100", "200"), "--min-piece-m '200': expected a length <= --piece-m (100 m)")):
        with pytest.raises(InputError) as err:
            piece_config(*args)
        assert str(err.value) == message
