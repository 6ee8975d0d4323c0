"""Canonical CDR bytes for the per-step messages, straight from numpy.

``rclpy.serialization.serialize_message`` leaves CDR alignment padding uninitialised, so
the same message can serialize to different bytes; the recorder therefore re-encodes
messages with zeroed padding (:class:`evoscen_eval.recorder.CanonicalCdr`), which costs
tens of microseconds per message. The encoders here write the *canonical* bytes (little
endian CDR, XCDR1 alignment relative to the payload, zero padding) of the messages the
simulation publishes every step — the flat tables (``sensor_msgs/PointCloud2``),
``/clock`` and the SUT's odometry — directly, padded to a multiple of 4 bytes as DDS
transports them (:func:`pad4`): a template with the constant part, patched with the stamp, the
row count and the numpy buffer. They decode with rclpy, ``rosbags`` and ``mcap_ros2``
like any other CDR message and equal the recorder's canonical form byte for byte (a test),
so bags stay identical whichever path a message took. ``publish(bytes)`` on an rclpy
publisher sends them as they are.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from .contract import CELL_BYTES, EVENT_RUN_END, FLOAT64, stamp_parts

_ENCAPSULATION_CDR_LE = b"\x00\x01\x00\x00"


def pad4(data: bytes) -> bytes:
    """``data`` followed by zero bytes up to a multiple of 4 bytes.

    DDS transports a serialized message padded to a multiple of 4 bytes, so that is what a
    raw subscription (and ``ros2 bag record``) sees; the canonical form includes it.
    """
    extra = -len(data) % 4
    return data + b"\x00" * extra if extra else data


class _PayloadWriter:
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


def _stamp_bytes(stamp_ns: int) -> bytes:
    return struct.pack("<iI", *stamp_parts(stamp_ns))


class TableEncoder:
    """Canonical CDR of a flat typed table (the layout of :func:`evoscen_contract.tables.table_message`).

    Args:
        fields: column names, in column order.
        frame_id: ``header.frame_id``.
    """

    def __init__(self, fields: Sequence[str], frame_id: str) -> None:
        self.fields = tuple(fields)
        self.point_step = CELL_BYTES * len(self.fields)
        w = _PayloadWriter()
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
        self._head = len(_ENCAPSULATION_CDR_LE)

    def encode(self, data: np.ndarray, stamp_ns: int) -> bytes:
        """CDR bytes of the table ``data`` (rows × len(fields), converted to float64)."""
        table = np.ascontiguousarray(data, dtype="<f8")
        if table.ndim != 2 or table.shape[1] != len(self.fields):
            raise ValueError(f"TableEncoder: expected rows x {len(self.fields)} data, got shape {table.shape}")
        rows = table.shape[0]
        payload = table.tobytes()
        head = bytearray(self._template)
        head[0:8] = _stamp_bytes(stamp_ns)
        struct.pack_into("<I", head, self._width_at, rows)
        struct.pack_into("<I", head, self._row_step_at, rows * self.point_step)
        struct.pack_into("<I", head, self._data_len_at, len(payload))
        return pad4(b"".join((_ENCAPSULATION_CDR_LE, head, payload, b"\x01")))  # is_dense = True


def encode_clock(stamp_ns: int) -> bytes:
    """Canonical CDR of ``rosgraph_msgs/Clock`` at ``stamp_ns``."""
    return pad4(_ENCAPSULATION_CDR_LE + _stamp_bytes(stamp_ns))


class OdometryEncoder:
    """Canonical CDR of the SUT's ``nav_msgs/Odometry`` (as :func:`evoscen_contract.topics.odometry_message`)."""

    def __init__(self, frame_id: str, child_frame_id: str) -> None:
        w = _PayloadWriter()
        w.pack("iI", 0, 0)  # header.stamp, patched
        w.string(frame_id)
        w.string(child_frame_id)
        w._align(8)  # the pose's doubles start 8-aligned; everything after is doubles
        self._template = bytes(w.buf)
        self._zeros36 = bytes(8 * 36)  # a zero covariance

    def encode(self, x: float, y: float, yaw: float, speed: float, yaw_rate: float, stamp_ns: int) -> bytes:
        """CDR bytes of the odometry at ``stamp_ns`` (pose in frame_id, twist in child_frame_id)."""
        head = bytearray(self._template)
        head[0:8] = _stamp_bytes(stamp_ns)
        half = 0.5 * float(yaw)
        pose = struct.pack("<7d", float(x), float(y), 0.0, 0.0, 0.0, math.sin(half), math.cos(half))
        twist = struct.pack("<6d", float(speed), 0.0, 0.0, 0.0, 0.0, float(yaw_rate))
        return pad4(b"".join((_ENCAPSULATION_CDR_LE, head, pose, self._zeros36, twist, self._zeros36)))


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
        w = _PayloadWriter()
        w.pack("iI", 0, 0)  # header.stamp, patched
        w.string(frame_id)
        w.pack("I", 0)  # status: empty sequence
        self._template = bytes(w.buf)

    def encode(self, stamp_ns: int) -> bytes:
        """CDR bytes of the empty array stamped ``stamp_ns``."""
        return pad4(_ENCAPSULATION_CDR_LE + _stamp_bytes(stamp_ns) + self._template[8:])


def encode_diagnostic_array(msg) -> bytes:  # noqa: ANN001 - a DiagnosticArray (rclpy, or any with its fields)
    """Canonical CDR of a ``diagnostic_msgs/DiagnosticArray`` (``/evoscen/events``), any number of statuses.

    The same bytes as serializing the message with rclpy and canonicalizing it
    (:class:`evoscen_eval.recorder.CanonicalCdr`; a test), without either: tens of µs for a
    few events instead of ~250 µs.
    """
    w = _PayloadWriter()
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
    return pad4(_ENCAPSULATION_CDR_LE + bytes(w.buf))


class _Writer(_PayloadWriter):
    """A payload writer starting at payload offset ``base`` (alignment is relative to the payload)."""

    def __init__(self, base: int) -> None:
        super().__init__()
        self.base = base

    def tell(self) -> int:
        return self.base + len(self.buf)

    def _align(self, size: int) -> None:
        self.buf += b"\x00" * (-(self.base + len(self.buf)) % size)


def _marker_prefix(base: int, frame_id: str, ns: str, marker_type: int) -> tuple[bytes, dict[str, int]]:
    """A ``visualization_msgs/Marker`` up to (not including) its ``text``, and where to patch it.

    Offsets are relative to the returned bytes. Fields after ``text`` (mesh_resource,
    mesh_file, mesh_use_embedded_materials) are written by :func:`_marker_tail`.
    """
    w = _Writer(base)
    at: dict[str, int] = {}
    w._align(4)
    at["stamp"] = len(w.buf)
    w.pack("iI", 0, 0)  # header.stamp
    w.string(frame_id)
    w.string(ns)
    at["id"] = len(w.buf) + (-w.tell() % 4)
    w.pack("i", 0)  # id
    w.pack("i", marker_type)
    w.pack("i", 0)  # action ADD
    w._align(8)
    at["pose"] = len(w.buf)
    w.pack("7d", 0, 0, 0, 0, 0, 0, 1)  # position, orientation
    at["scale"] = len(w.buf)
    w.pack("3d", 0, 0, 0)
    at["color"] = len(w.buf) + (-w.tell() % 4)
    w.pack("4f", 0, 0, 0, 0)
    w.pack("iI", 0, 0)  # lifetime
    w.pack("?", False)  # frame_locked
    w.pack("I", 0)  # points[]
    w.pack("I", 0)  # colors[]
    w.string("")  # texture_resource
    w.pack("iI", 0, 0)  # texture.header.stamp
    w.string("")  # texture.header.frame_id
    w.string("")  # texture.format
    w.pack("I", 0)  # texture.data[]
    w.pack("I", 0)  # uv_coordinates[]
    return bytes(w.buf), at


def _marker_tail(base: int) -> bytes:
    """The fields after ``text``, starting at payload offset ``base``."""
    w = _Writer(base)
    w.string("")  # mesh_resource
    w.string("")  # mesh_file.filename
    w.pack("I", 0)  # mesh_file.data[]
    w.pack("?", False)  # mesh_use_embedded_materials
    return bytes(w.buf)


class VehicleMarkersEncoder:
    """Canonical CDR of the vehicle markers (:func:`evoscen_contract.markers.vehicle_markers`).

    The same bytes as building the rclpy messages and canonicalizing them (a test), ~10×
    faster: every marker is a template for its alignment (a marker starts 4-aligned, its
    pose's doubles need 8) patched with the stamp, id, pose, size, colour, plus its text.
    """

    def __init__(self, frame_id: str) -> None:
        from .markers import CUBE, TEXT_VIEW_FACING

        self.frame_id = frame_id
        self._prefix = {(kind, a): _marker_prefix(a, frame_id, ns, t)
                        for kind, ns, t in (("box", "vehicles", CUBE), ("label", "labels", TEXT_VIEW_FACING))
                        for a in (0, 4)}
        self._tails = {a: _marker_tail(a) for a in range(4)}
        self._patched: dict[tuple, tuple[bytes, int, int]] = {}
        """(kind, alignment, id, scale, colour) -> the prefix with those patched, and where stamp and pose go."""

    def _marker(self, out: bytearray, kind: str, stamp: bytes, vid: int, pose: tuple, scale: tuple,
                color: tuple, text: str) -> None:
        pad = -(len(out) - 4) % 4  # payload offset = len(out) - 4 (CDR header)
        out += b"\x00" * pad
        start = len(out) - 4
        key = (kind, start % 8, vid, scale, color)
        cached = self._patched.get(key)
        if cached is None:  # the marker's constant fields patched once per vehicle, kind and alignment
            prefix, at = self._prefix[(kind, start % 8)]
            m = bytearray(prefix)
            struct.pack_into("<i", m, at["id"], vid)
            struct.pack_into("<3d", m, at["scale"], *scale)
            struct.pack_into("<4f", m, at["color"], *color)
            cached = self._patched[key] = (bytes(m), at["stamp"], at["pose"])
        m = bytearray(cached[0])
        m[cached[1]:cached[1] + 8] = stamp
        struct.pack_into("<7d", m, cached[2], *pose)
        out += m
        raw = text.encode("utf-8") + b"\x00"
        out += struct.pack("<I", len(raw)) + raw
        out += self._tails[(len(out) - 4) % 4]

    def encode(self, columns, stamp_ns: int) -> bytes:  # noqa: ANN001
        """CDR bytes of ``/evoscen/markers`` for the world columns at ``stamp_ns``."""
        from .markers import VEHICLE_HEIGHT_M, policy_color

        stamp = _stamp_bytes(stamp_ns)
        n = len(columns["id"])
        out = bytearray(_ENCAPSULATION_CDR_LE)
        out += struct.pack("<I", 2 * n)
        ids, x, y, yaw = columns["id"], columns["x"], columns["y"], columns["yaw"]
        length, width, speed, policy = columns["length"], columns["width"], columns["speed"], columns["policy"]
        for i in range(n):
            vid = int(ids[i])
            half = 0.5 * float(yaw[i])
            xi, yi = float(x[i]), float(y[i])
            self._marker(out, "box", stamp, vid,
                         (xi, yi, 0.5 * VEHICLE_HEIGHT_M, 0.0, 0.0, math.sin(half), math.cos(half)),
                         (float(length[i]), float(width[i]), VEHICLE_HEIGHT_M), (*policy_color(policy[i]), 1.0), "")
            self._marker(out, "label", stamp, vid, (xi, yi, VEHICLE_HEIGHT_M + 1.0, 0.0, 0.0, 0.0, 1.0),
                         (0.0, 0.0, 1.2), (1.0, 1.0, 1.0, 1.0), f"{vid}  {float(speed[i]) * 3.6:.0f} km/h")
        return pad4(bytes(out))


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
