"""Vehicle and road markers: what a tester sees in Foxglove or RViz."""

from __future__ import annotations

import math

import numpy as np
import pytest
from evoscen_contract.markers import POLICY_COLORS, road_markers, vehicle_markers
from evoscen_contract.topics import POLICY_CODES


def test_vehicle_markers_are_oriented_sized_coloured_boxes_with_labels():
    cols = {
        "id": np.array([0.0, 7.0]), "policy": np.array([POLICY_CODES["sut"], POLICY_CODES["competitive"]], float),
        "x": np.array([10.0, -3.5]), "y": np.array([2.0, 4.0]), "yaw": np.array([0.0, math.pi / 2]),
        "length": np.array([4.8, 5.5]), "width": np.array([1.9, 2.0]), "speed": np.array([25.0, 10.0]),
    }
    msg = vehicle_markers(cols, 1_500_000_000)
    boxes = [m for m in msg.markers if m.ns == "vehicles"]
    labels = [m for m in msg.markers if m.ns == "labels"]
    assert [b.id for b in boxes] == [0, 7] and [lb.id for lb in labels] == [0, 7]
    b = boxes[1]
    assert b.type == b.CUBE and b.header.frame_id == "map"
    assert (b.header.stamp.sec, b.header.stamp.nanosec) == (1, 500_000_000)
    assert (b.pose.position.x, b.pose.position.y) == (-3.5, 4.0)
    assert (b.scale.x, b.scale.y) == (5.5, 2.0)  # length along the heading, width across
    # yaw pi/2 -> quaternion (0, 0, sin(pi/4), cos(pi/4))
    assert b.pose.orientation.z == pytest.approx(math.sqrt(0.5)) and b.pose.orientation.w == pytest.approx(math.sqrt(0.5))
    assert (b.color.r, b.color.g, b.color.b) == pytest.approx(POLICY_COLORS["competitive"])
    assert (boxes[0].color.r, boxes[0].color.g, boxes[0].color.b) == pytest.approx(POLICY_COLORS["sut"])
    assert labels[0].text == "0  90 km/h" and labels[1].text == "7  36 km/h"


def test_road_markers_draw_every_marking_solid_lines_whole_broken_lines_dashed():
    from evoscen_sim.road.road_model import load_road

    road = load_road()
    lines = road.lane_markings()
    msg = road_markers(road)
    assert len(msg.markers) == len(lines)
    for line, m in zip(lines, msg.markers):
        segments = len(line.x_m) - 1
        assert m.type == m.LINE_LIST and m.ns == line.kind
        if line.type == "broken":  # every third segment of the ~5 m samples
            assert len(m.points) == 2 * len(range(0, segments, 3))
        else:
            assert len(m.points) == 2 * segments


@pytest.mark.parametrize("n", [1, 2, 21])
def test_vehicle_markers_encoder_equals_canonical_serialization(n):
    from evoscen_contract.cdr_markers import VehicleMarkersEncoder
    from evoscen_record.canonical_cdr import CanonicalCdr
    from rclpy.serialization import deserialize_message, serialize_message
    from visualization_msgs.msg import MarkerArray

    rng = np.random.default_rng(n)
    cols = {"id": np.arange(n, dtype=float) * 7, "policy": rng.integers(0, 8, n).astype(float),
            "x": rng.normal(size=n) * 500, "y": rng.normal(size=n) * 20, "yaw": rng.normal(size=n),
            "length": rng.uniform(4, 6, n), "width": rng.uniform(1.7, 2.1, n), "speed": rng.uniform(0, 40, n)}
    ours = VehicleMarkersEncoder("map").encode(cols, 3_700_000_000)
    canon = CanonicalCdr(["visualization_msgs/msg/MarkerArray"])
    assert ours == canon("visualization_msgs/msg/MarkerArray", serialize_message(vehicle_markers(cols, 3_700_000_000)))
    assert len(deserialize_message(ours, MarkerArray).markers) == 2 * n


def test_vehicle_markers_kernel_equals_the_python_path():
    """The compiled marker layout (``VehicleMarkersEncoder.encode``) gives the bytes of the
    marker-by-marker Python path (``encode_python``, itself compared with rclpy + canonicalization
    above): 0, 1 and 21 vehicles; ids up to 6 digits; every alignment the label texts leave; speeds
    whose km/h round half to even (0.5, 1.5, 2.5 km/h exactly), are negative, negative rounding to
    zero (-0.1 km/h gives "-0"), -0.0, or not finite (the Python path's text: nan, inf)."""
    from evoscen_contract.cdr_markers import VehicleMarkersEncoder

    enc = VehicleMarkersEncoder("map")
    rng = np.random.default_rng(3)
    special = np.array([0.0, -0.0, 0.5, 1.5, 2.5, -0.1, -0.5, -2.5, 1e6, 99.49, 99.5]) / 3.6
    for k in range(60):
        n = (0, 1, 21)[k % 3]
        speed = rng.choice(special, n) if k % 2 else rng.uniform(-10, 300, n)
        cols = {"id": rng.integers(0, 10 ** int(rng.integers(1, 7)), n).astype(float),
                "policy": rng.integers(0, 8, n).astype(float), "x": rng.normal(size=n) * 500,
                "y": rng.normal(size=n) * 20, "yaw": rng.normal(size=n) * 3, "length": rng.uniform(4, 6, n),
                "width": rng.uniform(1.7, 2.1, n), "speed": speed}
        assert enc.encode(cols, 3_700_000_000 + k) == enc.encode_python(cols, 3_700_000_000 + k), (k, cols)
    cols["speed"] = np.array([np.nan] + [np.inf] * 20)
    assert enc.encode(cols, 5) == enc.encode_python(cols, 5)
    assert b"nan km/h" in enc.encode(cols, 5)


def test_road_markers_encoder_equals_canonical_serialization():
    """``encode_road_markers`` gives the bytes of the rclpy message (:func:`road_markers`) serialized
    and canonicalized by the recorder: the shipped road at two stamps, and a made-up road with
    every case of a marking — solid, broken (every third segment) with 2 to 8 samples, a single
    sample (no segment: an empty point list), yellow and white, edges and lane lines, -0.0 and
    huge coordinates — so every alignment of a marker's start and of its points occurs."""
    from types import SimpleNamespace

    from evoscen_contract.cdr_markers import encode_road_markers
    from evoscen_record.canonical_cdr import CanonicalCdr
    from evoscen_sim.road.road_model import load_road
    from rclpy.serialization import serialize_message

    canon = CanonicalCdr(["visualization_msgs/msg/MarkerArray"])

    def reference(road, t_ns: int) -> bytes:
        return canon("visualization_msgs/msg/MarkerArray", serialize_message(road_markers(road, t_ns)))

    road = load_road()
    for t_ns in (0, 1_700_000_123):
        assert encode_road_markers(road, t_ns) == reference(road, t_ns)
    rng = np.random.default_rng(5)
    lines = []
    for k in range(24):
        n = (1, 2, 3, 4, 5, 7, 8)[k % 7]
        lines.append(SimpleNamespace(kind=("edge_left", "lane_line", "edge_right", "x")[k % 4],
                                     type=("solid", "broken")[k % 2], color=("white", "yellow", "standard")[k % 3],
                                     width_m=(0.12, 0.15, 0.3)[k % 3], x_m=rng.normal(size=n) * 10 ** (k % 9),
                                     y_m=np.where(rng.random(n) < 0.3, -0.0, rng.normal(size=n))))
    made_up = SimpleNamespace(lane_markings=lambda: lines)
    for t_ns in (0, 42):
        assert encode_road_markers(made_up, t_ns) == reference(made_up, t_ns)
    empty = SimpleNamespace(lane_markings=lambda: [])
    assert encode_road_markers(empty, 0) == reference(empty, 0)
