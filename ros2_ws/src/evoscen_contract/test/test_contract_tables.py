"""Tests of evoscen_contract.tables: flat float64 tables in PointCloud2."""

from __future__ import annotations

import time

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import PointCloud2, PointField

from evoscen_contract.tables import (
    ns_from_stamp,
    stamp_from_ns,
    table_array,
    table_columns,
    table_fields,
    table_message,
)
from evoscen_contract.topics import WORLD_FIELDS

FIELDS = ("id", "x", "speed")


def _data(rows: int = 4) -> np.ndarray:
    """Exactly representable and awkward values (negative zero, tiny, huge, inf)."""
    return np.array(
        [[1.0, -0.0, 33.5], [2.0, 1e-300, -1.25], [3.0, 1.7976931348623157e308, np.inf],
         [4.0, 0.1, 1.0 / 3.0]][:rows],
        dtype=np.float64,
    )  # fmt: skip


def test_layout_follows_the_contract() -> None:
    msg = table_message(FIELDS, _data(), stamp_ns=12_345_000_000_007, frame_id="map")
    assert msg.height == 1 and msg.width == 4
    assert msg.point_step == 24 and msg.row_step == 96 and len(msg.data) == 96
    assert msg.is_dense is True and msg.is_bigendian is False
    assert [f.name for f in msg.fields] == list(FIELDS)
    assert [f.offset for f in msg.fields] == [0, 8, 16]
    assert all(f.datatype == PointField.FLOAT64 == 8 and f.count == 1 for f in msg.fields)
    assert msg.header.frame_id == "map"
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (12_345, 7)


def test_round_trip_exact_through_cdr() -> None:
    data = _data()
    msg = table_message(list(FIELDS), data, stamp_ns=5, frame_id="map")
    back = deserialize_message(serialize_message(msg), PointCloud2)
    arr = table_array(back)
    assert arr.dtype == np.float64 and arr.shape == (4, 3)
    assert arr.tobytes() == data.tobytes()  # bit-exact, incl. -0.0
    cols = table_columns(back)
    assert list(cols) == list(FIELDS)
    np.testing.assert_array_equal(cols["speed"], data[:, 2])
    assert table_fields(back) == FIELDS
    assert ns_from_stamp(back.header.stamp) == 5


def test_non_contiguous_and_integer_input_converted() -> None:
    data = np.arange(12, dtype=np.int64).reshape(3, 4)[:, ::2]  # not C-contiguous, int
    msg = table_message(("a", "b"), data, 0, "map")
    np.testing.assert_array_equal(table_array(msg), data.astype(np.float64))


def test_empty_table() -> None:
    msg = table_message(WORLD_FIELDS, np.zeros((0, len(WORLD_FIELDS))), 0, "map")
    assert msg.width == 0 and msg.row_step == 0
    assert table_array(msg).shape == (0, len(WORLD_FIELDS))


def test_result_is_read_only_view() -> None:
    arr = table_array(table_message(FIELDS, _data(), 0, "map"))
    with pytest.raises(ValueError):
        arr[0, 0] = 9.0


@pytest.mark.parametrize(
    ("fields", "shape", "match"),
    [
        (("a", "b"), (3, 3), "does not match 2 fields"),
        (("a", "a"), (3, 2), "duplicate"),
        (("a",), (3,), "does not match"),
    ],
)
def test_table_message_rejects_bad_shapes(fields, shape, match) -> None:
    with pytest.raises(ValueError, match=match):
        table_message(fields, np.zeros(shape), 0, "map")


def test_table_array_rejects_non_float64_field() -> None:
    msg = table_message(FIELDS, _data(), 0, "map")
    msg.fields = [PointField(name=f.name, offset=f.offset, datatype=f.datatype, count=1)
                  for f in msg.fields]
    msg.fields[1].datatype = PointField.FLOAT32
    with pytest.raises(ValueError, match="field 1 'x'.*FLOAT64"):
        table_array(msg)


def test_table_array_rejects_inconsistent_sizes() -> None:
    msg = table_message(FIELDS, _data(), 0, "map")
    msg.width = 5
    with pytest.raises(ValueError, match="row_step"):
        table_array(msg)
    msg = table_message(FIELDS, _data(), 0, "map")
    msg.point_step = 32
    with pytest.raises(ValueError, match="point_step"):
        table_array(msg)
    msg = table_message(FIELDS, _data(), 0, "map")
    msg.data = msg.data[:-8]
    with pytest.raises(ValueError, match="data has 88 bytes"):
        table_array(msg)
    msg = table_message(FIELDS, _data(), 0, "map")
    msg.is_bigendian = True
    with pytest.raises(ValueError, match="bigendian"):
        table_array(msg)


def test_stamps() -> None:
    for ns in (0, 1, 999_999_999, 1_000_000_000, 123_456_789_012_345):
        st = stamp_from_ns(ns)
        assert 0 <= st.nanosec < 1_000_000_000
        assert ns_from_stamp(st) == ns
    st = stamp_from_ns(100_000_000)  # 0.1 s
    assert (st.sec, st.nanosec) == (0, 100_000_000)
    with pytest.raises(ValueError):
        stamp_from_ns(2**31 * 1_000_000_000)


def test_table_message_speed_is_reported() -> None:
    """Not asserted (timing in tests is flaky); printed for the record (pytest -s)."""
    data = np.random.default_rng(0).random((21, len(WORLD_FIELDS)))
    n = 2000
    t0 = time.perf_counter()
    for k in range(n):
        table_message(WORLD_FIELDS, data, k, "map")
    per_call_us = (time.perf_counter() - t0) / n * 1e6
    print(f"table_message 21 x {len(WORLD_FIELDS)}: {per_call_us:.1f} us/call")
