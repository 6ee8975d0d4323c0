"""Canonical CDR bytes of the marker messages: the vehicles' ``visualization_msgs/MarkerArray``
(a compiled layout, with a Python path of the same bytes) and the road's lane markings.

Canonical as :mod:`evoscen_contract.cdr` writes the per-step tables (little endian CDR, XCDR1
alignment relative to the payload, zero padding, padded to a multiple of 4 bytes): the bytes
equal rclpy's message serialized and canonicalized by the recorder (a test).
"""

from __future__ import annotations

import math
import struct

import numpy as np

from .cdr import ENCAPSULATION_CDR_LE, PayloadWriter, pad4, stamp_bytes
from .contract import MAP_FRAME, stamp_parts


class _Writer(PayloadWriter):
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
    _write_no_colors_texture_uv(w)
    return bytes(w.buf), at


def _marker_tail(base: int) -> bytes:
    """The fields after ``text``, starting at payload offset ``base``."""
    w = _Writer(base)
    _write_no_mesh(w)
    return bytes(w.buf)


def _write_no_colors_texture_uv(w) -> None:  # a _Writer or PayloadWriter
    """A Marker's empty ``colors``, ``texture_resource``, ``texture`` and ``uv_coordinates``."""
    w.pack("I", 0)  # colors[]
    w.string("")  # texture_resource
    w.pack("iI", 0, 0)  # texture.header.stamp
    w.string("")  # texture.header.frame_id
    w.string("")  # texture.format
    w.pack("I", 0)  # texture.data[]
    w.pack("I", 0)  # uv_coordinates[]


def _write_no_mesh(w) -> None:  # a _Writer or PayloadWriter
    """A Marker's fields after ``text``: no mesh."""
    w.string("")  # mesh_resource
    w.string("")  # mesh_file.filename
    w.pack("I", 0)  # mesh_file.data[]
    w.pack("?", False)  # mesh_use_embedded_materials


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
        self._layout: tuple | None = None  # the compiled kernel's templates, made on first use
        self._colors: dict[tuple, bytes] = {}
        self._rows_cache: dict[tuple[str, bytes, bytes], np.ndarray] = {}
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

    def encode(self, columns, stamp_ns: int) -> bytes:
        """CDR bytes of ``/evoscen/markers`` for the world columns at ``stamp_ns``.

        The markers are laid out by a compiled kernel (:func:`_markers_kernel`) from arrays
        prepared here (poses, sizes, colours, label texts formatted by Python as before);
        :meth:`encode_python` is the earlier marker-by-marker path, the same bytes (a test).
        """
        kernel = _markers_kernel_or_none()
        if kernel is None:
            return self.encode_python(columns, stamp_ns)
        from .markers import VEHICLE_HEIGHT_M

        if self._layout is None:
            self._layout = self._kernel_layout()
        pre, at, tails, tail_len, per_vehicle = self._layout
        f64, asarray = np.float64, np.asarray
        ids, x, y = asarray(columns["id"], dtype=f64), asarray(columns["x"], dtype=f64), asarray(columns["y"], dtype=f64)
        yaw, length = asarray(columns["yaw"], dtype=f64), asarray(columns["length"], dtype=f64)
        width, speed = asarray(columns["width"], dtype=f64), asarray(columns["speed"], dtype=f64)
        n = len(ids)
        kmh = speed * 3.6
        out = np.zeros(8 + n * per_vehicle, np.uint8)
        end = kernel(out, np.frombuffer(stamp_bytes(stamp_ns), np.uint8), ids, x, y, yaw, length, width, kmh,
                     self._color_rows(columns["policy"], length, n), VEHICLE_HEIGHT_M, pre, at, tails, tail_len)
        if end < 0:  # text the kernel does not format (nan, inf, huge): the kernel checked first
            return self.encode_python(columns, stamp_ns)
        return pad4(out[:end].tobytes())

    def _color_rows(self, policy, length, n: int) -> np.ndarray:
        """The box colours (n × 16 bytes, four float32) of the vehicles with policy codes ``policy`` and
        lengths ``length`` (:func:`~evoscen_contract.markers.vehicle_color`), remembered per column (the
        policies and classes of a run's vehicles seldom change)."""
        from .contract import TRUCK_MIN_LENGTH_M
        from .markers import vehicle_color

        policy = np.asarray(policy)
        truck = np.asarray(length) > TRUCK_MIN_LENGTH_M
        key = (policy.dtype.str, policy.tobytes(), truck.tobytes())
        rows = self._rows_cache.get(key)
        if rows is None:
            colors = b"".join([self._color_bytes((code, bool(t)), vehicle_color(code, 1e9 if t else 0.0))
                               for code, t in zip(policy.tolist(), truck.tolist())])
            rows = np.frombuffer(colors, np.uint8).reshape(n, 16)
            if len(self._rows_cache) >= 64:
                self._rows_cache.clear()
            self._rows_cache[key] = rows
        return rows

    def _color_bytes(self, key: tuple, rgb: tuple) -> bytes:
        cached = self._colors.get(key)
        if cached is None:
            cached = self._colors[key] = struct.pack("<4f", *rgb, 1.0)
        return cached

    def _kernel_layout(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
        """The four marker prefixes (box, label × start 0 or 4 mod 8) as rows of one array, the label's
        constant scale and colour patched in; where stamp, id, pose, scale, colour go; the tails; the
        most bytes one vehicle's two markers take."""
        prefixes, offsets = [], []
        for kind in ("box", "label"):
            for a in (0, 4):
                prefix, at = self._prefix[(kind, a)]
                m = bytearray(prefix)
                if kind == "label":
                    struct.pack_into("<3d", m, at["scale"], 0.0, 0.0, 1.2)
                    struct.pack_into("<4f", m, at["color"], 1.0, 1.0, 1.0, 1.0)
                prefixes.append(bytes(m))
                offsets.append((len(m), at["stamp"], at["id"], at["pose"], at["scale"], at["color"]))
        pre = np.zeros((4, max(len(p) for p in prefixes)), np.uint8)
        for k, p in enumerate(prefixes):
            pre[k, :len(p)] = np.frombuffer(p, np.uint8)
        tails = np.zeros((4, max(len(t) for t in self._tails.values())), np.uint8)
        tail_len = np.zeros(4, np.int64)
        for a, t in self._tails.items():
            tails[a, :len(t)] = np.frombuffer(t, np.uint8)
            tail_len[a] = len(t)
        per_vehicle = 2 * (pre.shape[1] + 16 + int(tail_len.max()) + 48)  # bytes a vehicle's markers take at most
        return pre, np.array(offsets, dtype=np.int64), tails, tail_len, per_vehicle

    def encode_python(self, columns, stamp_ns: int) -> bytes:
        """:meth:`encode` marker by marker in Python (the earlier path; the same bytes)."""
        from .markers import VEHICLE_HEIGHT_M, vehicle_color

        stamp = stamp_bytes(stamp_ns)
        n = len(columns["id"])
        out = bytearray(ENCAPSULATION_CDR_LE)
        out += struct.pack("<I", 2 * n)
        ids, x, y, yaw = columns["id"], columns["x"], columns["y"], columns["yaw"]
        length, width, speed, policy = columns["length"], columns["width"], columns["speed"], columns["policy"]
        for i in range(n):
            vid = int(ids[i])
            half = 0.5 * float(yaw[i])
            xi, yi = float(x[i]), float(y[i])
            self._marker(out, "box", stamp, vid,
                         (xi, yi, 0.5 * VEHICLE_HEIGHT_M, 0.0, 0.0, math.sin(half), math.cos(half)),
                         (float(length[i]), float(width[i]), VEHICLE_HEIGHT_M),
                         (*vehicle_color(policy[i], length[i]), 1.0), "")
            self._marker(out, "label", stamp, vid, (xi, yi, VEHICLE_HEIGHT_M + 1.0, 0.0, 0.0, 0.0, 1.0),
                         (0.0, 0.0, 1.2), (1.0, 1.0, 1.0, 1.0), f"{vid}  {float(speed[i]) * 3.6:.0f} km/h")
        return pad4(bytes(out))


def encode_road_markers(road, stamp_ns: int = 0) -> bytes:  # an evoscen_sim Road
    """Canonical CDR of ``/evoscen/map_markers`` (:func:`evoscen_contract.markers.road_markers`).

    The same bytes as building the rclpy message, serializing it and canonicalizing it
    (:class:`evoscen_record.canonical_cdr.CanonicalCdr`; a test), without either: the ``LINE_LIST``
    points go in as one numpy block per marking (~3 ms for the shipped road). The rclpy path took
    ~15 ms a run, ~60 ms the first time in a process (building the message, then the
    recorder's re-encoding of its ~10,000 points object by object).
    """
    sec, nanosec = stamp_parts(stamp_ns)
    lines = road.lane_markings()
    w = PayloadWriter()
    w.pack("I", len(lines))
    for k, line in enumerate(lines):
        w.pack("iI", sec, nanosec)  # header.stamp
        w.string(MAP_FRAME)
        w.string(line.kind)  # ns
        w.pack("i", k)  # id
        w.pack("i", 5)  # type LINE_LIST
        w.pack("i", 0)  # action ADD
        w.pack("7d", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)  # pose: identity
        w.pack("3d", float(line.width_m), 0.0, 0.0)  # scale
        w.pack("4f", *((1.0, 1.0, 1.0) if line.color != "yellow" else (1.0, 0.85, 0.0)), 1.0)  # colour
        w.pack("iI", 0, 0)  # lifetime
        w.pack("?", False)  # frame_locked
        xs = np.asarray(line.x_m, dtype=np.float64)
        ys = np.asarray(line.y_m, dtype=np.float64)
        j = np.arange(max(len(xs) - 1, 0))  # the segments j -> j + 1 drawn: all, or every third if broken
        if line.type == "broken":
            j = j[j % 3 == 0]
        points = np.zeros((2 * len(j), 3))  # (x, y, 0) of each segment's two ends
        points[0::2, 0], points[0::2, 1] = xs[j], ys[j]
        points[1::2, 0], points[1::2, 1] = xs[j + 1], ys[j + 1]
        w.pack("I", len(points))
        if len(points):
            w._align(8)
            w.buf += points.tobytes()
        _write_no_colors_texture_uv(w)
        w.string("")  # text
        _write_no_mesh(w)
    return pad4(ENCAPSULATION_CDR_LE + bytes(w.buf))


_MARKERS_KERNEL: list = []


def _markers_kernel_or_none():
    """The compiled marker kernel (numba, compiled on first use and cached on disk); None without numba."""
    if not _MARKERS_KERNEL:
        try:
            import numba
        except ImportError:  # pragma: no cover - numba is a dependency of the simulation
            _MARKERS_KERNEL.append(None)
        else:
            global _put_int  # the kernel calls the compiled helper
            _put_int = numba.njit(cache=True, nogil=True)(_put_int)
            _MARKERS_KERNEL.append(numba.njit(cache=True, nogil=True)(_markers_kernel))
    return _MARKERS_KERNEL[0]


def _markers_kernel(out, stamp, ids, x, y, yaw, length, width, kmh, colors, height,
                    pre, at, tails, tail_len):
    """Write the ``MarkerArray`` of :meth:`VehicleMarkersEncoder.encode` into the zeroed ``out``; its
    length, or -1 (nothing written) if a label's numbers are not all finite and small enough for the
    kernel's formatting (|km/h| < 1e15, |id| < 2**31 - 1; the Python path writes those).

    Per vehicle a box then a label marker: 4-aligned (payload offsets), the prefix for the
    marker's start mod 8 (row ``2 * kind + start % 8 // 4`` of ``pre``; ``at`` holds its length
    and where stamp, id, pose, scale and colour go), its text (empty for the box; the label's
    ``f"{id}  {kmh:.0f} km/h"``: ``.0f`` rounds half to even, as ``np.rint``, and keeps the sign
    of a negative value rounding to 0) as a CDR string, then the tail for the alignment reached.
    """
    n = ids.shape[0]
    for i in range(n):
        if not (abs(kmh[i]) < 1e15 and abs(ids[i]) < 2147483647.0):  # NaN fails too
            return -1
    out[1] = 1  # little-endian CDR
    count = 2 * n
    for b in range(4):
        out[4 + b] = (count >> (8 * b)) & 0xFF
    pose = np.zeros(7)
    pose_bytes = pose.view(np.uint8)
    scale = np.zeros(3)
    scale_bytes = scale.view(np.uint8)
    vid_arr = np.zeros(1, np.int32)
    vid_bytes = vid_arr.view(np.uint8)
    digits = np.zeros(24, np.uint8)
    pos = 8
    for i in range(n):
        vid = int(ids[i])
        vid_arr[0] = vid
        for kind in range(2):
            pos += (-(pos - 4)) % 4
            row = 2 * kind + ((pos - 4) % 8) // 4
            size = at[row, 0]
            out[pos:pos + size] = pre[row, :size]
            out[pos + at[row, 1]:pos + at[row, 1] + 8] = stamp
            out[pos + at[row, 2]:pos + at[row, 2] + 4] = vid_bytes
            pose[0] = x[i]
            pose[1] = y[i]
            if kind == 0:
                half = 0.5 * yaw[i]
                pose[2] = 0.5 * height
                pose[5] = math.sin(half)
                pose[6] = math.cos(half)
                scale[0] = length[i]
                scale[1] = width[i]
                scale[2] = height
                out[pos + at[row, 4]:pos + at[row, 4] + 24] = scale_bytes
                out[pos + at[row, 5]:pos + at[row, 5] + 16] = colors[i]
            else:
                pose[2] = height + 1.0
                pose[5] = 0.0
                pose[6] = 1.0
            out[pos + at[row, 3]:pos + at[row, 3] + 56] = pose_bytes
            pos += size
            text_at = pos + 4
            t = text_at
            if kind == 1:  # f"{vid}  {kmh:.0f} km/h"
                t = _put_int(out, t, vid, False, digits)
                out[t] = 32
                out[t + 1] = 32
                v = kmh[i]
                r = np.rint(v)
                t = _put_int(out, t + 2, int(abs(r)), v < 0.0 or (v == 0.0 and math.copysign(1.0, v) < 0.0),
                             digits)
                out[t:t + 5] = np.array([32, 107, 109, 47, 104], np.uint8)  # " km/h"
                t += 5
            raw = t - text_at + 1  # the text and its NUL
            for b in range(4):
                out[pos + b] = (raw >> (8 * b)) & 0xFF
            pos = t + 1  # the NUL is the buffer's zero
            a = (pos - 4) % 4
            out[pos:pos + tail_len[a]] = tails[a, :tail_len[a]]
            pos += tail_len[a]
    return pos


def _put_int(out, t, value, minus, digits):
    """Write the decimal digits of ``value`` (with a leading ``-`` if negative or ``minus``) at ``t``; the end."""
    if value < 0:
        minus = True
        value = -value
    if minus:
        out[t] = 45
        t += 1
    k = 0
    while True:
        digits[k] = 48 + value % 10
        value //= 10
        k += 1
        if value == 0:
            break
    for j in range(k):
        out[t + j] = digits[k - 1 - j]
    return t + k
