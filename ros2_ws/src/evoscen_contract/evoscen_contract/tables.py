"""Flat typed tables: ``sensor_msgs/msg/PointCloud2`` used as a table of float64 rows.

Per-step bulk data (the world state, the controllers' commands, the roster) travels
as a PointCloud2 that is really a table: one *row* per vehicle, one named FLOAT64
*field* per column. The layout is fixed so that conversion is one buffer copy:

* ``height = 1``, ``width = rows``;
* ``fields[i] = PointField(name=<column i>, offset=8*i, datatype=FLOAT64 (8), count=1)``;
* ``point_step = 8 * nfields`` bytes, ``row_step = point_step * rows`` bytes;
* ``is_bigendian = False`` (little-endian IEEE-754 doubles), ``is_dense = True``;
* ``data`` = the C-contiguous ``rows x nfields`` float64 buffer, row-major;
* ``header.stamp`` = simulation time, ``header.frame_id`` as given (``"map"``).

Why PointCloud2: it is a standard type (no rosidl build), it has a header (stamp and
frame) and self-describing named columns, and its payload is one ``uint8[]`` blob, so
building it from numpy costs a memcpy instead of dozens of Python message objects
(measured 2,687 vs 438 lockstep steps/s, see docs/architecture.md §3).

The readers (:func:`table_array`, :func:`table_columns`) accept any object with the
PointCloud2 attributes: rclpy messages, ``mcap_ros2`` decoded messages and ``rosbags``
deserialized messages alike.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any, Sequence

import numpy as np
from builtin_interfaces.msg import Time
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import Header

from .contract import CELL_BYTES, FLOAT64, stamp_parts  # FLOAT64, CELL_BYTES re-exported

_NS_PER_S: int = 1_000_000_000


# --------------------------------------------------------------------------- time


def stamp_from_ns(ns: int) -> Time:
    """Return ``builtin_interfaces/msg/Time`` for a time in integer nanoseconds.

    ``sec = ns // 1e9``, ``nanosec = ns % 1e9`` (floor division, so ``nanosec`` is
    always in ``[0, 1e9)`` as ROS requires, also for negative times).

    Raises:
        ValueError: ``ns`` is not an integer or ``sec`` does not fit int32
            (:func:`evoscen_contract.contract.stamp_parts`).
    """
    sec, nanosec = stamp_parts(ns)
    return Time(sec=sec, nanosec=nanosec)


def ns_from_stamp(stamp: Any) -> int:
    """Return the integer nanoseconds of a ``builtin_interfaces/msg/Time`` (``sec*1e9+nanosec``)."""
    return int(stamp.sec) * _NS_PER_S + int(stamp.nanosec)


# --------------------------------------------------------------------------- writing


@lru_cache(maxsize=256)
def _point_fields(fields: tuple[str, ...]) -> tuple[PointField, ...]:
    """Return (cached) the PointField descriptors for a tuple of column names.

    The PointField objects are shared between all messages built for the same
    columns: treat table messages as immutable.
    """
    if len(set(fields)) != len(fields):
        dup = sorted({f for f in fields if fields.count(f) > 1})
        raise ValueError(f"table fields: duplicate column names {dup}")
    for name in fields:
        if not isinstance(name, str) or not name:
            raise ValueError(f"table fields: column name {name!r} is not a non-empty string")
    return tuple(
        PointField(name=name, offset=CELL_BYTES * i, datatype=FLOAT64, count=1)
        for i, name in enumerate(fields)
    )


def table_message(
    fields: Sequence[str],
    data: np.ndarray,
    stamp_ns: int,
    frame_id: str,
) -> PointCloud2:
    """Build a flat typed table message from a ``rows x nfields`` float64 array.

    Args:
        fields: column names, in column order (e.g. ``WORLD_FIELDS``).
        data: ``rows x len(fields)`` array; float64 C-contiguous is used without a
            conversion (anything else is converted once with ``np.ascontiguousarray``).
        stamp_ns: simulation time of the row data in integer nanoseconds.
        frame_id: ``header.frame_id`` (``"map"`` for all evoscen tables).

    Returns:
        The PointCloud2 (layout in the module docstring). Called every step: cost is
        one buffer copy plus the message objects, ~12 us for 21 x 17 cells
        (printed by ``test_contract_tables.py``).

    Raises:
        ValueError: ``data`` is not 2-D or its column count differs from ``len(fields)``,
            or the field names are duplicated/empty.
    """
    fields_t = fields if type(fields) is tuple else tuple(fields)
    pfields = _point_fields(fields_t)
    if type(data) is not np.ndarray or data.dtype != np.float64 or not data.flags.c_contiguous:
        data = np.ascontiguousarray(data, dtype=np.float64)
    if data.ndim != 2 or data.shape[1] != len(pfields):
        raise ValueError(
            f"table_message: data shape {data.shape} does not match {len(pfields)} fields "
            f"{list(fields_t)} (expected rows x {len(pfields)})"
        )
    rows = data.shape[0]
    point_step = CELL_BYTES * len(pfields)
    sec, nanosec = divmod(int(stamp_ns), _NS_PER_S)

    if np.little_endian:
        payload = data.tobytes()  # one memcpy (~0.5 us for 21 x 17 cells)
    else:  # pragma: no cover - big-endian hosts
        payload = data.astype("<f8").tobytes()
    # All fields as constructor kwargs: avoids building (and replacing) a default Header.
    msg = PointCloud2(
        header=Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id=frame_id),
        height=1,
        width=rows,
        fields=list(pfields),
        is_bigendian=False,
        point_step=point_step,
        row_step=point_step * rows,
        data=payload,
        is_dense=True,
    )
    return msg


# --------------------------------------------------------------------------- reading


def table_fields(msg: Any) -> tuple[str, ...]:
    """Return the column names of a table message, in column order."""
    return tuple(str(f.name) for f in msg.fields)


def table_array(msg: Any) -> np.ndarray:
    """Return the table as a ``rows x nfields`` float64 array.

    For rclpy messages the result is a read-only zero-copy view of ``msg.data``; copy
    it before modifying.

    Raises:
        ValueError: the message is not a flat float64 table: a field is not FLOAT64
            with count 1 at offset ``8*i``, or ``point_step``/``row_step``/``height``/
            ``width``/``len(data)``/``is_bigendian`` are inconsistent with that layout.
    """
    fields = list(msg.fields)
    nfields = len(fields)
    for i, f in enumerate(fields):
        if int(f.datatype) != FLOAT64 or int(f.count) != 1 or int(f.offset) != CELL_BYTES * i:
            raise ValueError(
                f"table_array: field {i} {f.name!r} has datatype={int(f.datatype)} "
                f"count={int(f.count)} offset={int(f.offset)}; a flat table needs "
                f"datatype=FLOAT64 (8), count=1, offset={CELL_BYTES * i}"
            )
    point_step = CELL_BYTES * nfields
    if int(msg.point_step) != point_step:
        raise ValueError(
            f"table_array: point_step {int(msg.point_step)} != 8 * {nfields} fields = {point_step}"
        )
    if bool(msg.is_bigendian):
        raise ValueError("table_array: is_bigendian is True; tables are little-endian")
    height, width = int(msg.height), int(msg.width)
    rows = height * width
    if height > 1:
        raise ValueError(f"table_array: height {height} must be 1 (or 0 for an empty table)")
    if int(msg.row_step) != point_step * width:
        raise ValueError(
            f"table_array: row_step {int(msg.row_step)} != point_step {point_step} * "
            f"width {width}"
        )
    nbytes = len(msg.data)
    if nbytes != point_step * rows:
        raise ValueError(
            f"table_array: data has {nbytes} bytes, expected {point_step * rows} "
            f"({rows} rows x {nfields} fields x 8)"
        )
    if rows == 0 or nfields == 0:
        return np.zeros((rows, nfields), dtype=np.float64)
    out = np.frombuffer(msg.data, dtype="<f8").reshape(rows, nfields)
    out.flags.writeable = False
    return out


def table_columns(msg: Any) -> dict[str, np.ndarray]:
    """Return ``{field name: column (rows,) float64}`` for a table message.

    Columns are views of :func:`table_array` (read-only). Raises ValueError like it.
    """
    arr = table_array(msg)
    return {name: arr[:, i] for i, name in enumerate(table_fields(msg))}
