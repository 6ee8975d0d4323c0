"""The direct CDR encoders give exactly the canonical bytes of the same messages."""

from __future__ import annotations

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import PointCloud2

from evoscen_contract.cdr import OdometryEncoder, TableEncoder, encode_clock
from evoscen_contract.tables import table_array, table_message
from evoscen_contract.topics import (
    COMMAND_FIELDS, MAP_FRAME, ROSTER_FIELDS, SUT_BASE_FRAME, WORLD_FIELDS, clock_message, odometry_message,
)
from nav_msgs.msg import Odometry
from evoscen_record.canonical_cdr import CanonicalCdr

CANON = CanonicalCdr(["sensor_msgs/msg/PointCloud2", "rosgraph_msgs/msg/Clock", "nav_msgs/msg/Odometry"])


@pytest.mark.parametrize("fields", [WORLD_FIELDS, COMMAND_FIELDS, ROSTER_FIELDS, ("a",), ("ab", "abc", "abcd", "x")])
@pytest.mark.parametrize("rows", [0, 1, 21])
@pytest.mark.parametrize("frame_id", [MAP_FRAME, "", "odom_x"])
def test_table_encoder_equals_canonical_serialization(fields, rows, frame_id):
    rng = np.random.default_rng(rows + len(fields))
    data = rng.normal(size=(rows, len(fields))) * 1e3
    stamp_ns = 123_456_789_012 + rows
    ours = TableEncoder(fields, frame_id).encode(data, stamp_ns)
    rclpy_bytes = serialize_message(table_message(fields, data, stamp_ns, frame_id))
    assert ours == CANON("sensor_msgs/msg/PointCloud2", rclpy_bytes)
    back = deserialize_message(ours, PointCloud2)
    assert back.header.frame_id == frame_id
    assert back.header.stamp.sec == 123 and back.header.stamp.nanosec == 456_789_012 + rows
    assert np.array_equal(table_array(back), data)
    assert [f.name for f in back.fields] == list(fields)


def test_table_encoder_from_columns_equals_encode():
    """``encode_columns`` (one array of the columns, written out transposed; sizes cached per row
    count) gives :meth:`TableEncoder.encode`'s bytes of the rows × columns table (compared with the
    canonical serialization above): 0, 1, 21 and again 1 rows, int and float columns, stamps that
    repeat and change (the last stamp is remembered)."""
    rng = np.random.default_rng(11)
    enc = TableEncoder(WORLD_FIELDS, MAP_FRAME)
    for rows, stamp_ns in ((0, 5), (1, 5), (21, 5), (21, 100_000_000), (1, 7_300_000_001), (21, 0)):
        cols = [rng.integers(-5, 50, rows) if k % 3 == 0 else rng.normal(size=rows) * 1e3
                for k in range(len(WORLD_FIELDS))]
        table = np.column_stack(cols) if rows else np.zeros((0, len(WORLD_FIELDS)))
        assert enc.encode_columns(cols, stamp_ns) == enc.encode(table, stamp_ns), (rows, stamp_ns)
    with pytest.raises(ValueError, match="3 columns"):
        TableEncoder(("a", "b", "c"), MAP_FRAME).encode_columns([np.zeros(2), np.zeros(2)], 0)


def test_table_encoder_rejects_wrong_shape():
    with pytest.raises(ValueError, match="3"):
        TableEncoder(("a", "b", "c"), MAP_FRAME).encode(np.zeros((2, 2)), 0)


@pytest.mark.parametrize("stamp_ns", [0, 100_000_000, 299_900_000_000, 2**31 * 10**9 - 1])
def test_clock_encoder_equals_canonical_serialization(stamp_ns):
    ours = encode_clock(stamp_ns)
    assert ours == CANON("rosgraph_msgs/msg/Clock", serialize_message(clock_message(stamp_ns)))
    back = deserialize_message(ours, Clock)
    assert back.clock.sec * 10**9 + back.clock.nanosec == stamp_ns


@pytest.mark.parametrize("frames", [(MAP_FRAME, SUT_BASE_FRAME), ("m", "b"), ("", "")])
@pytest.mark.parametrize("pose", [(0.0, 0.0, 0.0, 0.0, 0.0), (1234.5, -17.25, 0.3, 31.2, -0.01), (-1.0, 2.0, -3.0, 0.0, 1.5)])
def test_odometry_encoder_equals_canonical_serialization(frames, pose):
    stamp_ns = 42_100_000_000
    x, y, yaw, speed, yaw_rate = pose
    ours = OdometryEncoder(*frames).encode(x, y, yaw, speed, yaw_rate, stamp_ns)
    msg = odometry_message(x, y, yaw, speed, yaw_rate, stamp_ns)
    msg.header.frame_id, msg.child_frame_id = frames
    assert ours == CANON("nav_msgs/msg/Odometry", serialize_message(msg))
    back = deserialize_message(ours, Odometry)
    assert back.pose.pose.position.x == x and back.twist.twist.linear.x == speed
    assert back.twist.twist.angular.z == yaw_rate and back.child_frame_id == frames[1]


@pytest.mark.parametrize("fields", [WORLD_FIELDS, COMMAND_FIELDS, ("a",)])
@pytest.mark.parametrize("rows", [0, 1, 21])
@pytest.mark.parametrize("frame_id", [MAP_FRAME, "", "abcde"])
def test_decode_table_reads_ours_and_rclpys(fields, rows, frame_id):
    from evoscen_contract.cdr import decode_table

    data = np.arange(rows * len(fields), dtype=float).reshape(rows, len(fields)) * 0.5
    for raw in (TableEncoder(fields, frame_id).encode(data, 7_000_000_123),
                serialize_message(table_message(fields, data, 7_000_000_123, frame_id))):
        for _ in range(2):  # parsed, then recognised from the cache
            stamp, frame, names, table = decode_table(raw)
            assert stamp == 7_000_000_123 and names == tuple(fields) and frame == frame_id
            assert np.array_equal(table, data)


def test_decode_table_rejects_non_tables():
    from evoscen_contract.cdr import TableDecodeError, decode_table

    with pytest.raises(TableDecodeError):
        decode_table(b"\x00\x01\x00\x00" + bytes(3))
    from sensor_msgs.msg import PointField

    cloud = table_message(("x",), np.zeros((2, 1)), 0, MAP_FRAME)
    cloud.fields = [PointField(name="x", offset=0, datatype=PointField.FLOAT32, count=1)]
    with pytest.raises(TableDecodeError, match="FLOAT64"):
        decode_table(serialize_message(cloud))


@pytest.mark.parametrize("frame_id", [MAP_FRAME, "", "abc"])
def test_empty_events_encoder_equals_canonical_serialization(frame_id):
    from diagnostic_msgs.msg import DiagnosticArray

    from evoscen_contract.cdr import EmptyEventsEncoder
    from evoscen_contract.topics import events_message

    msg = events_message([], 12_300_000_000)
    msg.header.frame_id = frame_id
    canon = CanonicalCdr(["diagnostic_msgs/msg/DiagnosticArray"])
    ours = EmptyEventsEncoder(frame_id).encode(12_300_000_000)
    assert ours == canon("diagnostic_msgs/msg/DiagnosticArray", serialize_message(msg))
    assert deserialize_message(ours, DiagnosticArray).status == []


@pytest.mark.parametrize("frame_id", [MAP_FRAME, "", "ab", "abcdef"])
def test_is_run_end_reads_the_count_and_names(frame_id):
    from evoscen_contract.cdr import is_run_end
    from evoscen_contract.topics import events_message

    def raw(events):
        msg = events_message(events, 5)
        msg.header.frame_id = frame_id
        return serialize_message(msg)

    assert not is_run_end(raw([]))
    assert not is_run_end(raw([{"name": "evoscen/collision", "ids": [1, 2]}]))
    assert is_run_end(raw([{"name": "evoscen/fault", "controller": "x"}, {"name": "evoscen/run_end", "kind": "completed"}]))


@pytest.mark.parametrize("frame_id", [MAP_FRAME, "", "ab", "abcdef"])
def test_diagnostic_array_encoder_equals_canonical_serialization(frame_id):
    """Events of every shape (no status, one, several; no values, several; text lengths that
    leave every alignment; non-ASCII text; every level) encode to the canonical bytes of rclpy's
    serialization."""
    from diagnostic_msgs.msg import DiagnosticArray

    from evoscen_contract.cdr import encode_diagnostic_array, encode_event_statuses
    from evoscen_contract.topics import event_statuses, events_message

    canon = CanonicalCdr(["diagnostic_msgs/msg/DiagnosticArray"])
    cases = [
        [],
        [{"name": "evoscen/collision", "ids": [1, 2]}],
        [{"name": "evoscen/fault", "controller": "x", "level": 0},
         {"name": "evoscen/run_end", "kind": "completed", "message": "run completed: 3 steps"}],
        [{"name": "evoscen/fault", "controller": "ü" * k, "message": "é" * k, "level": k % 4} for k in range(7)],
        [{"name": "evoscen/lane_change", "kind": "completed", "id": 3, "from_lane": 1, "to_lane": 2},
         {"name": "evoscen/exposure", "kind": "start", "ids": (4, 5), "level": 1, "note": 2.5}],
    ]
    for k, events in enumerate(cases):
        msg = events_message(events, 12_300_000_000 + k)
        msg.header.frame_id = frame_id
        ours = encode_diagnostic_array(msg)
        assert ours == canon("diagnostic_msgs/msg/DiagnosticArray", serialize_message(msg)), events
        assert len(deserialize_message(ours, DiagnosticArray).status) == len(events)
        # straight from the events, without the rclpy message: the same bytes
        assert encode_event_statuses(event_statuses(events), 12_300_000_000 + k, frame_id) == ours, events


def test_message_pieces_join_to_the_messages():
    """The pieces the in-process recorder hands to ``BagRecorder.write_parts`` join to the messages'
    bytes: world, commands, odometry (with its yaw-rate bookkeeping) and clock, several steps."""
    from evoscen_contract.messages import WorldMessages

    rng = np.random.default_rng(2)
    a, b = WorldMessages(0.1), WorldMessages(0.1)
    for k in range(5):
        n = (1, 21, 21, 3, 0)[k]
        cols = {f: rng.normal(size=n) * 100 if f not in ("id", "lane") else rng.integers(0, 9, n)
                for f in WORLD_FIELDS}
        t = 100_000_000 * k + 7
        assert b"".join(a.world_parts(cols, t)) == b.world(cols, t)
        assert b"".join(a.commands_parts(cols["id"], cols["x"], cols["lane"], t)) == \
            b.commands(cols["id"], cols["x"], cols["lane"], t)
        if n:
            assert b"".join(a.odometry_parts(cols, n - 1, t)) == b.odometry(cols, n - 1, t)
        assert b"".join(a.clock_parts(t)) == b.clock(t)
