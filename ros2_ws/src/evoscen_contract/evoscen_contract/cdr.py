"""Canonical CDR bytes for the per-step messages, straight from numpy.

``rclpy.serialization.serialize_message`` leaves CDR alignment padding uninitialised, so
the same message can serialize to different bytes; the recorder therefore re-encodes
messages with zeroed padding (:class:`evoscen_record.canonical_cdr.CanonicalCdr`), which costs
tens of microseconds per message. The encoders here write the *canonical* bytes (little
endian CDR, XCDR1 alignment relative to the payload, zero padding) of the messages the
simulation publishes every step — the flat tables (``sensor_msgs/PointCloud2``),
``/clock`` and the SUT's odometry — directly, padded to a multiple of 4 bytes as DDS
transports them (:func:`pad4`): a template with the constant part, patched with the stamp, the
row count and the numpy buffer. They decode with rclpy, ``rosbags`` and ``mcap_ros2``
like any other CDR message and equal the recorder's canonical form byte for byte (a test),
so bags stay identical whichever path a message took. ``publish(bytes)`` on an rclpy
publisher sends them as they are. The marker messages' encoders are in
:mod:`evoscen_contract.cdr_markers`.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from .contract import CELL_BYTES, EVENT_HARDWARE_ID, EVENT_RUN_END, FLOAT64, MAP_FRAME, stamp_parts

ENCAPSULATION_CDR_LE = b"\x00\x01\x00\x00"


def pad4(data: bytes) -> bytes:
    """``data`` followed by zero bytes up to a multiple of 4 bytes.

    DDS transports a serialized message padded to a multiple of 4 bytes, so that is what a
    raw subscription (and ``ros2 bag record``) sees; the canonical form includes it.
    """
    extra = -len(data) % 4
    return data + b"\x00" * extra if extra else data


class PayloadWriter:
    """Minimal CDR writer: primitives aligned to their size relative to the payload start."""

    def __init__(self) -> None:
        self.buf = bytearray()

    def tell(self) -> int:
        return len(self.buf)

    def _align(self, size: int) -> None:
        self.buf += b"\x00" * (-len(self.buf) % size)

    def pack(self, fmt: str, *values: object) -> None:
        size = struct.calcsize("<" + fmt.lstrip("0123456789")[0])  # alignment of the first value's type
        self._align(size)
        self.buf += struct.pack("<" + fmt, *values)

    def string(self, text: str) -> None:
        raw = text.encode("utf-8") + b"\x00"
        self.pack("I", len(raw))
        self.buf += raw


_LAST_STAMP: tuple = (None, b"")
"""The last stamp packed, ``(ns, bytes)``: a step's messages all carry the same stamp."""


def stamp_bytes(stamp_ns: int) -> bytes:
    global _LAST_STAMP
    last = _LAST_STAMP  # one read: safe with threads
    if type(stamp_ns) is int and last[0] == stamp_ns:
        return last[1]
    packed = struct.pack("<iI", *stamp_parts(stamp_ns))
    _LAST_STAMP = (stamp_ns, packed) if type(stamp_ns) is int else (None, b"")
    return packed


class TableEncoder:
    """Canonical CDR of a flat typed table (the layout of :func:`evoscen_contract.tables.table_message`).

    Args:
        fields: column names, in column order.
        frame_id: ``header.frame_id``.
    """

    def __init__(self, fields: Sequence[str], frame_id: str) -> None:
        self.fields = tuple(fields)
        self.point_step = CELL_BYTES * len(self.fields)
        w = PayloadWriter()
        w.pack("iI", 0, 0)  # header.stamp, patched per message
        w.string(frame_id)
        w.pack("I", 1)  # height
        self._width_at = w.tell()
        w.pack("I", 0)  # width, patched
        w.pack("I", len(self.fields))
        for k, name in enumerate(self.fields):
            w.string(name)
            w.pack("I", CELL_BYTES * k)  # offset
            w.pack("B", FLOAT64)  # datatype
            w.pack("I", 1)  # count
        w.pack("?", False)  # is_bigendian
        w.pack("I", self.point_step)
        self._row_step_at = w.tell()
        w.pack("I", 0)  # row_step, patched
        self._data_len_at = w.tell()
        w.pack("I", 0)  # len(data), patched
        self._template = bytes(w.buf)
        self._head = len(ENCAPSULATION_CDR_LE)
        self._heads: dict[int, tuple[bytes, bytes]] = {}  # rows -> template after the stamp (sizes patched), tail

    def encode_columns(self, columns: Sequence[np.ndarray], stamp_ns: int) -> bytes:
        """:meth:`encode` of the table whose columns are ``columns`` (equal-length 1-D arrays, one per
        field): the same bytes, without making the rows × columns array first (the columns go to
        float64 in one ``np.array`` and out in row order by ``tobytes`` of its transpose)."""
        return b"".join(self.parts_columns(columns, stamp_ns))

    def parts_columns(self, columns: Sequence[np.ndarray], stamp_ns: int) -> tuple[bytes, ...]:
        """:meth:`encode_columns`'s bytes in pieces (their join), for a writer that joins anyway."""
        table = np.array(columns, dtype=np.float64)
        if table.ndim != 2 or table.shape[0] != len(self.fields):
            raise ValueError(f"TableEncoder: expected {len(self.fields)} columns, got shape {table.shape}")
        rows = table.shape[1]
        cached = self._heads.get(rows)
        if cached is None:
            patched = bytearray(self._template)
            struct.pack_into("<I", patched, self._width_at, rows)
            struct.pack_into("<I", patched, self._row_step_at, rows * self.point_step)
            struct.pack_into("<I", patched, self._data_len_at, rows * self.point_step)
            head = bytes(patched[8:])
            size = len(ENCAPSULATION_CDR_LE) + 8 + len(head) + rows * self.point_step + 1
            cached = (head, b"\x01" + b"\x00" * (-size % 4))  # is_dense = True, then pad4's zeros
            if len(self._heads) < 64:
                self._heads[rows] = cached
        return ENCAPSULATION_CDR_LE, stamp_bytes(stamp_ns), cached[0], table.T.tobytes(), cached[1]

    def encode(self, data: np.ndarray, stamp_ns: int) -> bytes:
        """CDR bytes of the table ``data`` (rows × len(fields), converted to float64)."""
        table = np.ascontiguousarray(data, dtype="<f8")
        if table.ndim != 2 or table.shape[1] != len(self.fields):
            raise ValueError(f"TableEncoder: expected rows x {len(self.fields)} data, got shape {table.shape}")
        rows = table.shape[0]
        payload = table.tobytes()
        head = bytearray(self._template)
        head[0:8] = stamp_bytes(stamp_ns)
        struct.pack_into("<I", head, self._width_at, rows)
        struct.pack_into("<I", head, self._row_step_at, rows * self.point_step)
        struct.pack_into("<I", head, self._data_len_at, len(payload))
        return pad4(b"".join((ENCAPSULATION_CDR_LE, head, payload, b"\x01")))  # is_dense = True


def encode_clock(stamp_ns: int) -> bytes:
    """Canonical CDR of ``rosgraph_msgs/Clock`` at ``stamp_ns``."""
    return pad4(ENCAPSULATION_CDR_LE + stamp_bytes(stamp_ns))


def clock_parts(stamp_ns: int) -> tuple[bytes, bytes]:
    """:func:`encode_clock`'s bytes in pieces (their join: 12 bytes, no padding)."""
    return ENCAPSULATION_CDR_LE, stamp_bytes(stamp_ns)


class OdometryEncoder:
    """Canonical CDR of the SUT's ``nav_msgs/Odometry`` (as :func:`evoscen_contract.topics.odometry_message`)."""

    def __init__(self, frame_id: str, child_frame_id: str) -> None:
        w = PayloadWriter()
        w.pack("iI", 0, 0)  # header.stamp, patched
        w.string(frame_id)
        w.string(child_frame_id)
        w._align(8)  # the pose's doubles start 8-aligned; everything after is doubles
        self._template = bytes(w.buf)
        self._zeros36 = bytes(8 * 36)  # a zero covariance
        self._rest = self._template[8:]
        size = len(ENCAPSULATION_CDR_LE) + len(self._template) + 8 * (7 + 36 + 6 + 36)
        self._zeros36_pad = self._zeros36 + b"\x00" * (-size % 4)  # the last covariance, then pad4's zeros

    def encode(self, x: float, y: float, yaw: float, speed: float, yaw_rate: float, stamp_ns: int) -> bytes:
        """CDR bytes of the odometry at ``stamp_ns`` (pose in frame_id, twist in child_frame_id)."""
        head = bytearray(self._template)
        head[0:8] = stamp_bytes(stamp_ns)
        half = 0.5 * float(yaw)
        pose = struct.pack("<7d", float(x), float(y), 0.0, 0.0, 0.0, math.sin(half), math.cos(half))
        twist = struct.pack("<6d", float(speed), 0.0, 0.0, 0.0, 0.0, float(yaw_rate))
        return pad4(b"".join((ENCAPSULATION_CDR_LE, head, pose, self._zeros36, twist, self._zeros36)))

    def parts(self, x: float, y: float, yaw: float, speed: float, yaw_rate: float, stamp_ns: int) -> tuple[bytes, ...]:
        """:meth:`encode`'s bytes in pieces (their join), for a writer that joins anyway."""
        half = 0.5 * float(yaw)
        pose = struct.pack("<7d", float(x), float(y), 0.0, 0.0, 0.0, math.sin(half), math.cos(half))
        twist = struct.pack("<6d", float(speed), 0.0, 0.0, 0.0, 0.0, float(yaw_rate))
        return (ENCAPSULATION_CDR_LE, stamp_bytes(stamp_ns), self._rest, pose, self._zeros36, twist,
                self._zeros36_pad)


class TableDecodeError(ValueError):
    """Bytes that are not a flat typed table (all-FLOAT64 little-endian PointCloud2)."""


_FIELDS_CACHE: dict[int, list[tuple[bytes, tuple[str, ...], int]]] = {}
#: Field-list blocks remembered per offset: a flood of tables with ever new columns cannot grow the cache.
_FIELDS_CACHE_MAX: int = 8


class DecodedTable(NamedTuple):
    """A table message read by :func:`decode_table`."""

    stamp_ns: int
    frame_id: str
    fields: tuple[str, ...]
    data: np.ndarray
    """rows x fields float64 (a read-only view of the message bytes)."""

    def columns(self) -> dict[str, np.ndarray]:
        """The columns by name."""
        return {name: self.data[:, k] for k, name in enumerate(self.fields)}


def decode_table(data: bytes | memoryview) -> DecodedTable:
    """The stamp, frame id, field names and rows of a serialized table message.

    The fast path of every node that reads tables (the world, commands) from raw
    subscriptions: no rclpy deserialization; the (constant) field-list block is parsed once
    and recognised by its bytes afterwards. Accepts any valid CDR encoding of a table
    (rclpy's, ours, with any frame id). The array is a read-only view of ``data``.

    Raises:
        TableDecodeError: not little-endian CDR, not a table, or inconsistent sizes — for any
            input bytes, never another exception (text that is not UTF-8, a message cut short
            and a negative size all end here).
    """
    buf = bytes(data)
    if len(buf) < 16 or buf[0] != 0 or buf[1] != 1:
        raise TableDecodeError("not little-endian CDR")
    sec, nanosec = struct.unpack_from("<iI", buf, 4)
    pos = 12

    def align(p: int, n: int) -> int:
        return p + (-(p - 4) % n)

    try:
        (n,) = struct.unpack_from("<I", buf, pos)
        frame_id = buf[pos + 4:pos + 3 + n].decode("utf-8") if n else ""
        pos = align(pos + 4 + n, 4)
        height, width = struct.unpack_from("<II", buf, pos)
        pos += 8
        cached = None
        for block, fields, end in _FIELDS_CACHE.get(pos, ()):
            if buf.startswith(block, pos):
                cached = (fields, end)
                break
        if cached is None:
            start = pos
            (nf,) = struct.unpack_from("<I", buf, pos)
            pos += 4
            names = []
            for k in range(nf):
                (ln,) = struct.unpack_from("<I", buf, pos)
                name = buf[pos + 4:pos + 4 + ln - 1].decode("utf-8")
                pos = align(pos + 4 + ln, 4)
                offset, datatype = struct.unpack_from("<IB", buf, pos)
                pos = align(pos + 5, 4)
                (count,) = struct.unpack_from("<I", buf, pos)
                pos += 4
                if offset != CELL_BYTES * k or datatype != FLOAT64 or count != 1:
                    raise TableDecodeError(f"field {name!r} is not the FLOAT64 column {k}")
                names.append(name)
            cached = (tuple(names), pos)
            if len(_FIELDS_CACHE.get(start, ())) < _FIELDS_CACHE_MAX:
                _FIELDS_CACHE.setdefault(start, []).append((buf[start:pos], *cached))
        fields, pos = cached
        (big_endian,) = struct.unpack_from("<B", buf, pos)
        if big_endian != 0:
            raise TableDecodeError("big-endian table")
        pos = align(pos + 1, 4)
        point_step, row_step, n_data = struct.unpack_from("<III", buf, pos)
        pos += 12
    except struct.error as exc:
        raise TableDecodeError(f"truncated message ({exc})") from None
    except UnicodeDecodeError as exc:
        raise TableDecodeError(f"text is not UTF-8 ({exc.reason} at byte {exc.start})") from None
    nf = len(fields)
    if point_step != CELL_BYTES * nf or row_step != point_step * width or n_data != row_step * height \
            or pos + n_data > len(buf):
        raise TableDecodeError("table sizes are inconsistent")
    table = np.frombuffer(buf, dtype="<f8", count=height * width * nf, offset=pos).reshape(height * width, nf)
    return DecodedTable(sec * 1_000_000_000 + nanosec, frame_id, fields, table)


class EmptyEventsEncoder:
    """Canonical CDR of an empty ``diagnostic_msgs/DiagnosticArray`` (a step without events)."""

    def __init__(self, frame_id: str) -> None:
        w = PayloadWriter()
        w.pack("iI", 0, 0)  # header.stamp, patched
        w.string(frame_id)
        w.pack("I", 0)  # status: empty sequence
        self._template = bytes(w.buf)

    def encode(self, stamp_ns: int) -> bytes:
        """CDR bytes of the empty array stamped ``stamp_ns``."""
        return pad4(ENCAPSULATION_CDR_LE + stamp_bytes(stamp_ns) + self._template[8:])


def encode_diagnostic_array(msg) -> bytes:  # a DiagnosticArray (rclpy, or any with its fields)
    """Canonical CDR of a ``diagnostic_msgs/DiagnosticArray`` (``/evoscen/events``), any number of statuses.

    The same bytes as serializing the message with rclpy and canonicalizing it
    (:class:`evoscen_record.canonical_cdr.CanonicalCdr`; a test), without either: tens of µs for a
    few events instead of ~250 µs.
    """
    w = PayloadWriter()
    w.pack("iI", int(msg.header.stamp.sec), int(msg.header.stamp.nanosec))
    w.string(msg.header.frame_id)
    w.pack("I", len(msg.status))
    for status in msg.status:
        level = status.level
        w.buf += level if isinstance(level, (bytes, bytearray)) else bytes((int(level),))
        w.string(status.name)
        w.string(status.message)
        w.string(status.hardware_id)
        w.pack("I", len(status.values))
        for kv in status.values:
            w.string(kv.key)
            w.string(kv.value)
    return pad4(ENCAPSULATION_CDR_LE + bytes(w.buf))


def encode_event_statuses(statuses: Sequence[tuple[int, str, str, Sequence[tuple[str, str]]]], stamp_ns: int,
                          frame_id: str = MAP_FRAME, hardware_id: str = EVENT_HARDWARE_ID) -> bytes:
    """Canonical CDR of the ``DiagnosticArray`` with these statuses (``(level, name, message,
    [(key, value), ...])``, :func:`evoscen_contract.topics.event_statuses`): the bytes of
    :func:`encode_diagnostic_array` of the rclpy message :func:`~evoscen_contract.topics.events_message`
    builds from the same events (a test), without building it (~50 µs for a few events)."""
    sec, nanosec = stamp_parts(stamp_ns)
    w = PayloadWriter()
    w.pack("iI", sec, nanosec)
    w.string(frame_id)
    w.pack("I", len(statuses))
    for level, name, message, values in statuses:
        w.buf += bytes((level,))
        w.string(name)
        w.string(message)
        w.string(hardware_id)
        w.pack("I", len(values))
        for key, value in values:
            w.string(key)
            w.string(value)
    return pad4(ENCAPSULATION_CDR_LE + bytes(w.buf))


def events_count(data: bytes) -> int:
    """Number of statuses in serialized ``diagnostic_msgs/DiagnosticArray`` bytes."""
    (n,) = struct.unpack_from("<I", data, 12)  # header.frame_id length
    return struct.unpack_from("<I", data, 16 + n + (-(12 + n) % 4))[0]


def is_run_end(data: bytes) -> bool:
    """Whether serialized ``/evoscen/events`` bytes hold the ``evoscen/run_end`` event.

    Cheap for the common case: an empty array (a step without events) is recognised from its
    status count without deserializing.
    """
    if events_count(data) == 0:
        return False
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.serialization import deserialize_message

    return any(s.name == EVENT_RUN_END for s in deserialize_message(bytes(data), DiagnosticArray).status)
