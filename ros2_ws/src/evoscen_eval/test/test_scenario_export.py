"""The export's pure parts (docs/export.md): pieces, classes, the box collision check."""

from __future__ import annotations

import math

import numpy as np
from evoscen_eval.scenes.scenario_export import XoscTrack, _split, box_collisions, vehicle_class


def test_class_is_by_length_trucks_longer_than_7_m():
    assert vehicle_class(4.8) == "car" and vehicle_class(7.0) == "car" and vehicle_class(7.01) == "truck"
    assert vehicle_class(7.5, truck_min_length_m=8.0) == "car"


def test_pieces_begin_at_jumps_and_at_the_states_events_led_to():
    dt = 0.1
    x = 30.0 * dt * np.arange(10)  # 30 m/s along x
    y = np.zeros(10)
    v = np.full(10, 30.0)
    assert _split(x, y, v, dt, set()) == [0]
    shifted = x.copy()
    shifted[6:] -= 1700.0  # the traffic window's shift, in the state 6 led to
    assert _split(shifted, y, v, dt, set()) == [0, 6]
    # a re-entry 3.5 m to the side is within speed * dt + 5 m: only its event makes it a piece
    side = y.copy()
    side[4:] -= 3.5
    assert _split(x, side, v, dt, set()) == [0]
    assert _split(x, side, v, dt, {4}) == [0, 4]
    assert _split(x, side, v, dt, {0, 10, 4}) == [0, 4]  # outside (0, n): ignored


def _track(name: str, length: float, width: float, poses: list[tuple[float, float, float, float]]) -> XoscTrack:
    return XoscTrack(name, "car", length, width, {}, poses[0][1:], 0.0, poses)


def test_box_collisions_find_the_first_state_of_overlap_not_a_touch():
    dt = 0.1
    # a at the origin, 4 x 2; b, 4 x 2, coming from x = 5 at 3 m/s: centres 4 m apart at k = 10/3,
    # so the boxes first overlap (positive area) at k = 4; at x = 4 exactly they would only touch
    a = _track("a", 4.0, 2.0, [(k * dt, 0.0, 0.0, 0.0) for k in range(8)])
    b = _track("b", 4.0, 2.0, [(k * dt, 5.0 - 0.3 * k, 0.0, 0.0) for k in range(8)])
    (t, pair), = box_collisions({"a": a, "b": b}, dt)
    assert pair == ("a", "b") and math.isclose(t, 0.4)
    touch = _track("b", 4.0, 2.0, [(k * dt, 4.0, 0.0, 0.0) for k in range(3)])
    assert box_collisions({"a": a, "b": touch}, dt) == []
    # c across a, turned 90 degrees, 2 m wide and 4 m long: its half extent along y is 2, a's 1,
    # so it overlaps once its centre is below y = 3: at y = 3.5 - 0.2 k, k = 3
    c = _track("c", 4.0, 2.0, [(k * dt, 0.0, 3.5 - 0.2 * k, math.pi / 2) for k in range(6)])
    (t, pair), = box_collisions({"a": a, "c": c}, dt)
    assert pair == ("a", "c") and math.isclose(t, 0.3)
    # an overlap already at the first state is no collision beginning in the range
    d = _track("d", 4.0, 2.0, [(k * dt, 1.0, 0.0, 0.0) for k in range(4)])
    assert box_collisions({"a": a, "d": d}, dt) == []
