"""Vectorised road model of the evoscen highway, built from an OpenDRIVE map.

``load_road(path)`` parses the ``.xodr`` file with :mod:`evoscen_sim.road.opendrive` and returns a
:class:`RoadModel`. The shipped map is ``maps/onramp.xodr`` (see :data:`DEFAULT_MAP_PATH`):

* one road of reference-line length 2393.76 m: line 0..1000 m (heading 0), arc 1000..1600 m
  (curvature +0.0005 1/m, R = 2000 m, turning left), line 1600..2393.76 m (heading 0.3 rad);
* four mainline lanes V, IV, III, II (OpenDRIVE ids -1..-4, 3.5 m) over the whole road, and the
  merge/acceleration lane I (id -5) that the on-ramp feeds at s = 600 m: full 3.5 m width on
  [600, 900), then a cubic taper to 0 m on [900, 960) (zero slope at both ends);
* speed limits: 120 km/h max on every lane, 90 km/h min on the mainline lanes (from the evoscen
  extension ``<userData code="evoscen:minSpeed" value="90 km/h"/>``), no minimum on lane I.

Frames and conventions (docs/CONVENTIONS.md)
--------------------------------------------
* ``s``: arc length along the OpenDRIVE reference line (m). ``d``: lateral offset (m), positive to
  the LEFT (OpenDRIVE ``t``). The reference line is the carriageway's left edge, so lanes have d < 0.
* Lane index = OpenDRIVE id + N, N = the number of right lanes in the widest section (here 5):
  index 0 = lane I (id -5, rightmost), ..., 4 = lane V (id -1, leftmost). ``-1`` = no lane.
  A lane keeps its identity across lane sections through its id (lane ``link`` elements, where
  present between sections of this road, must name the same id; links to other roads are kept
  in the parsed map but not followed).
* x/y: OpenDRIVE inertial frame (m); headings in rad, counter-clockwise from +x, not wrapped.

Out-of-range ``s``
------------------
* Lane lookups (``lane_exists``, widths, lane bounds/centres, ``lane_of``, road edges, speed
  limits) clamp ``s`` to [0, length]: a vehicle slightly before s = 0 sees the lanes at s = 0, one
  past the end sees the lanes at the end. A lane exists on ``[lane_start_s, lane_end_s)``; a lane
  that runs to the end of the road also exists at ``s = length`` (and, by clamping, beyond).
* Reference-line geometry (``frenet_to_cartesian``, ``heading``, ``curvature``,
  ``cartesian_to_frenet``) does NOT clamp: before s = 0 and after the end it continues the first/
  last planView piece (a line is extended along its heading). This keeps ``cartesian_to_frenet``
  an exact inverse and lets callers see vehicles leave the map (s > length) or arrive (s < 0).
* ``distance_to_lane_end`` uses the raw s (negative once past the lane end).

Values for lanes that do not exist
----------------------------------
A lane index outside [0, num_lanes) gives width 0, NaN bounds/centre/speed limits and
``lane_exists`` False. An in-range lane where it does not exist (lane I at s = 500) has width 0,
degenerate bounds (both on the neighbouring border, i.e. where the lane would start) and NaN speed
limits.

``lane_of`` boundaries: a point exactly on the line between two lanes belongs to the lane on its
RIGHT (lower index); both road edges count as on the road; a lane must exist (and have positive
width) to contain a point.

Speed limits: ``<speed>`` of the lane section's lane (sOffset honoured); where a lane has no
applicable ``<speed>``, the road ``<type>``'s ``<speed>``; otherwise +inf. Minimum: the lane's
``evoscen:minSpeed`` userData for the whole lane section, else 0.

Performance: all per-s data is precomputed on a table of s breakpoints (every section, width,
speed, laneOffset and road-type start); a query is one ``searchsorted`` plus a few array ops,
broadcasting over any shape of (lane, s) or (s, d) inputs. Only ``cartesian_to_frenet`` loops, over
the (three) planView pieces, never over vehicles. Compiled kernels (driver models) read the
same tables through :meth:`RoadModel.kernel_tables` and :mod:`evoscen_sim.road.road_kernels`.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple, Optional, Union

import numpy as np

from evoscen_sim.errors import InputError
from evoscen_sim.road.lane_tables import DRIVABLE_LANE_TYPES, check_sections, lane_extents, lane_present, lane_table
from evoscen_sim.road.opendrive import Lane, LaneSection, OpenDriveMap, Poly3, parse_opendrive  # noqa: F401  (Lane, LaneSection, Poly3: names of the 0.4 evoscen_sim.road)
from evoscen_sim.road.road_kernels import BorderTables, RoadTables, frenet_to_cartesian_kernel, lane_lookup_kernel

ArrayLike = Union[float, int, np.ndarray, list, tuple]



def _find_default_map() -> Path:
    """The shipped map: ``<pkg source>/maps/onramp.xodr`` in a source checkout, else the installed
    ``<prefix>/share/evoscen_sim/maps/onramp.xodr`` (colcon/ament layout, installed by setup.py's
    data_files); the source path if neither exists (load_road then reports it as unreadable)."""
    package_dir = Path(__file__).resolve().parents[1]  # the evoscen_sim import package
    source = package_dir.parent / "maps" / "onramp.xodr"
    candidates = [source]
    for parent in package_dir.parents:
        if parent.name == "lib":  # <prefix>/lib/pythonX.Y/site-packages/evoscen_sim
            candidates.append(parent.parent / "share" / "evoscen_sim" / "maps" / "onramp.xodr")
            break
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    return source


#: The map shipped with the package.
DEFAULT_MAP_PATH = _find_default_map()

#: Spacing (m) of the samples of :meth:`RoadModel.lane_markings`.
MARKING_STEP_M = 5.0

MERGE_LANE = 0
"""Lane index of the merge (acceleration) lane, lane I: the rightmost lane (docs/CONVENTIONS.md); the
on-ramp feeds it. The one definition: the traffic, spawn, the level-0 driver and the scripts import it."""


@dataclass(frozen=True)
class LaneMarking:
    """One road mark polyline (for visualisation).

    ``kind``: ``"edge_left"`` (the reference line), ``"edge_right"`` (outer border of the outermost
    lane of its section) or ``"lane_line"``. ``lane_id`` is the OpenDRIVE lane whose outer border it
    is (0 = the reference line). ``type``/``color``/``width_m`` come from the ``<roadMark>``.
    """

    kind: str
    type: str
    color: str
    width_m: Optional[float]
    lane_id: int
    s_m: np.ndarray
    d_m: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


class LaneLookup(NamedTuple):
    """Lane data at ``N`` positions (:meth:`RoadModel.lane_lookup`); 2-D arrays are ``(N, num_lanes)``."""

    d_right: np.ndarray
    """d of each lane's right border (m)."""
    d_left: np.ndarray
    """d of each lane's left border (m)."""
    present: np.ndarray
    """Whether each lane exists there."""
    max_speed_mps: np.ndarray
    """Each lane's maximum speed there (m/s)."""
    lane: np.ndarray
    """Index of the lane containing each position's ``d``, -1 if off the road (as ``lane_of``)."""
    curvature: np.ndarray
    """Curvature of the reference line at each ``s`` (1/m, as ``curvature``)."""


class RoadModel:
    """Vectorised queries on one OpenDRIVE road (see the module docstring for conventions)."""

    def __init__(self, odr: OpenDriveMap) -> None:
        self.map = odr
        road = odr.road
        fname = odr.path
        self.length_m: float = float(road.length_m)
        if road.rule == "LHT":
            raise InputError(
                f"{fname}:{road.line}: <road> attribute 'rule'='LHT' is not supported "
                "(expected RHT or absent: evoscen traffic drives on the right)"
            )
        sections = road.lane_sections
        check_sections(fname, sections)
        n = max(len(sec.right) for sec in sections)
        self.num_lanes: int = n
        self.lane_ids: np.ndarray = _readonly(np.arange(-n, 0, dtype=np.int64))

        # ---------------- geometry ----------------
        g = road.geometries
        self._g_s0 = _readonly(np.array([p.s_m for p in g], dtype=float))
        self._g_x0 = _readonly(np.array([p.x_m for p in g], dtype=float))
        self._g_y0 = _readonly(np.array([p.y_m for p in g], dtype=float))
        self._g_h0 = _readonly(np.array([p.hdg_rad for p in g], dtype=float))
        self._g_len = _readonly(np.array([p.length_m for p in g], dtype=float))
        self._g_k = _readonly(np.array([p.curvature_per_m for p in g], dtype=float))

        sec_present = [[lane_present(l) for l in sec.right] for sec in sections]
        br, w_coef, w_origin, present, vmax, vmin, off_coef, off_origin = lane_table(road, sections, sec_present, n, self.length_m)
        self._breaks = _readonly(br)
        self._w_coef = _readonly(w_coef)
        self._w_origin = _readonly(w_origin)
        self._present = _readonly(present)
        self._vmax = _readonly(vmax)
        self._vmin = _readonly(vmin)
        self._off_coef = _readonly(off_coef)
        self._off_origin = _readonly(off_origin)
        # segments where every width and the lane offset are constant: borders tabulated
        seg_const = np.all(w_coef[:, :, 1:] == 0.0, axis=(1, 2)) & np.all(off_coef[:, 1:] == 0.0, axis=1)
        self._seg_const = _readonly(seg_const)
        self._dr_table, self._dl_table, _ = self._bounds_all(np.maximum(br, 0.0))
        self._dr_table = _readonly(self._dr_table)
        self._dl_table = _readonly(self._dl_table)

        start, end, full_end = lane_extents(fname, road, sections, sec_present, n)
        self.lane_start_s: np.ndarray = _readonly(start)
        self.lane_end_s: np.ndarray = _readonly(end)
        self.lane_full_width_end_s: np.ndarray = _readonly(full_end)
        self._mainline_lanes: tuple[int, ...] = tuple(k for k in range(n) if start[k] <= 0.0)
        self._reaches_end = _readonly(end >= self.length_m)
        widths0 = [lane.widths[0].value(0.0) for k, sec in enumerate(sections)
                   for lane in sec.right if sec_present[k][-lane.id - 1]]
        self.lane_width_m: float = float(np.median(widths0))
        self._kernel_tables = RoadTables(
            breaks=np.ascontiguousarray(self._breaks), present=np.ascontiguousarray(self._present),
            max_speed_mps=np.ascontiguousarray(self._vmax),
            lane_end_s=np.ascontiguousarray(self.lane_end_s, dtype=float),
            reaches_end=np.ascontiguousarray(self._reaches_end), length_m=float(self.length_m),
            width_coef=np.ascontiguousarray(self._w_coef), width_origin=np.ascontiguousarray(self._w_origin),
            offset_coef=np.ascontiguousarray(self._off_coef), offset_origin=np.ascontiguousarray(self._off_origin))

        self._border_tables = BorderTables(
            length_m=float(self.length_m), breaks=np.ascontiguousarray(self._breaks),
            seg_const=np.ascontiguousarray(self._seg_const), d_right=np.ascontiguousarray(self._dr_table),
            d_left=np.ascontiguousarray(self._dl_table), present=np.ascontiguousarray(self._present),
            width_coef=np.ascontiguousarray(self._w_coef), width_origin=np.ascontiguousarray(self._w_origin),
            offset_coef=np.ascontiguousarray(self._off_coef), offset_origin=np.ascontiguousarray(self._off_origin))

    # ------------------------------------------------------------------ road facts
    @property
    def mainline_lanes(self) -> tuple[int, ...]:
        """The mainline lanes: those that exist from the road's start (``lane_start_s <= 0``), rightmost
        first (on the shipped map II–V: ``(1, 2, 3, 4)``). The traffic's per-lane lists
        (``traffic.lane_density_per_km``, …) have one entry per mainline lane, in this order."""
        return self._mainline_lanes

    @property
    def merge_lane(self) -> int:
        """Lane index of the merge lane, :data:`MERGE_LANE` (0, lane I)."""
        return MERGE_LANE

    @property
    def has_merge_lane(self) -> bool:
        """Whether the map has a merge lane: lane I exists and starts after the road's start (is not a
        mainline lane)."""
        return self.num_lanes > 0 and MERGE_LANE not in self._mainline_lanes

    # ------------------------------------------------------------------ internal lookups
    def _seg(self, s_clamped: np.ndarray) -> np.ndarray:
        return np.searchsorted(self._breaks, s_clamped, side="right") - 1

    def _clamp(self, s: ArrayLike) -> np.ndarray:
        return np.clip(np.asarray(s, dtype=float), 0.0, self.length_m)

    def _widths_all(self, sc: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(widths (..., N), lane offset (...), segment index (...)) at clamped s."""
        j = self._seg(sc)
        c = self._w_coef[j]  # (..., N, 4)
        ds = sc[..., None] - self._w_origin[j]
        w = c[..., 0] + ds * (c[..., 1] + ds * (c[..., 2] + ds * c[..., 3]))
        w = np.maximum(w, 0.0)
        oc = self._off_coef[j]
        do = sc - self._off_origin[j]
        off = oc[..., 0] + do * (oc[..., 1] + do * (oc[..., 2] + do * oc[..., 3]))
        return w, off, j

    def _bounds_all(self, sc: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(d_right (..., N), d_left (..., N), segment index) at clamped s."""
        w, off, j = self._widths_all(sc)
        cs = np.cumsum(w[..., ::-1], axis=-1)[..., ::-1]  # cs[i] = sum_{k >= i} w[k]
        d_right = off[..., None] - cs
        d_left = d_right + w
        return d_right, d_left, j

    def _lane_s(self, lane: ArrayLike, s: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Broadcast (lane, s) -> (lane clipped to a valid index, clamped s, valid mask, raw s)."""
        lane_a, s_a = np.broadcast_arrays(np.asarray(lane), np.asarray(s, dtype=float))
        if lane_a.dtype.kind not in "iu":
            if lane_a.size and not np.all(np.equal(np.mod(lane_a, 1), 0)):
                raise ValueError("lane index must be an integer")
            lane_a = lane_a.astype(np.int64)
        valid = (lane_a >= 0) & (lane_a < self.num_lanes)
        li = np.where(valid, lane_a, 0)
        return li, np.clip(s_a, 0.0, self.length_m), valid, s_a

    # ------------------------------------------------------------------ lanes
    def existence_table(self) -> tuple[np.ndarray, np.ndarray, float]:
        """``(breaks, present, length_m)`` for compiled kernels: lane ``l`` exists at ``s`` iff
        ``0 <= l < num_lanes`` and ``present[searchsorted(breaks, clip(s, 0, length_m), 'right') - 1, l]``
        (what :meth:`lane_exists` computes; the arrays are read-only)."""
        return self._breaks, self._present, self.length_m

    def kernel_tables(self) -> RoadTables:
        """The lane tables for compiled kernels, read by :mod:`evoscen_sim.road.road_kernels`'s queries
        (:func:`~evoscen_sim.road.road_kernels.segment_index`, :func:`~evoscen_sim.road.road_kernels.lane_end_distance`,
        :func:`~evoscen_sim.road.road_kernels.lane_center_d`), which compute what this class's methods do."""
        return self._kernel_tables

    def border_tables(self) -> BorderTables:
        """The tables :meth:`lane_lookup` reads, for compiled kernels that need one lane's borders
        (:func:`~evoscen_sim.road.road_kernels.lane_borders`) or existence
        (:func:`~evoscen_sim.road.road_kernels.lane_present`) at one ``s``, bit-identical to this class's."""
        return self._border_tables

    def lane_exists(self, lane: ArrayLike, s: ArrayLike) -> np.ndarray:
        """True where lane index ``lane`` exists at ``s`` (s clamped to [0, length])."""
        li, sc, valid, _ = self._lane_s(lane, s)
        return valid & self._present[self._seg(sc), li]

    def lane_width(self, lane: ArrayLike, s: ArrayLike) -> np.ndarray:
        """Width (m) of lane ``lane`` at ``s``; 0 where the lane does not exist."""
        li, sc, valid, _ = self._lane_s(lane, s)
        j = self._seg(sc)
        c = self._w_coef[j, li]
        ds = sc - self._w_origin[j, li]
        w = c[..., 0] + ds * (c[..., 1] + ds * (c[..., 2] + ds * c[..., 3]))
        return np.where(valid, np.maximum(w, 0.0), 0.0)

    def lane_bounds_d(self, lane: ArrayLike, s: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """(d_right, d_left) of the lane's borders at ``s`` (NaN for an invalid index)."""
        li, sc, valid, _ = self._lane_s(lane, s)
        dr, dl, _ = self._bounds_all(sc)
        r = np.take_along_axis(dr, li[..., None], axis=-1)[..., 0]
        l = np.take_along_axis(dl, li[..., None], axis=-1)[..., 0]
        return np.where(valid, r, np.nan), np.where(valid, l, np.nan)

    def lane_center_d(self, lane: ArrayLike, s: ArrayLike) -> np.ndarray:
        """d of the lane's centre line at ``s`` (moves with the width in a taper)."""
        r, l = self.lane_bounds_d(lane, s)
        return 0.5 * (r + l)

    def lane_lookup(self, s: np.ndarray, d: np.ndarray) -> LaneLookup:
        """Every lane-related quantity the simulation needs per step, in one compiled pass.

        For ``N`` vehicles at ``(s, d)`` (``s`` clamped to the road for lane data): all lanes'
        borders, existence and speed limits, the lane containing ``d`` (as :meth:`lane_of`)
        and the reference line's curvature (as :meth:`curvature`). See :class:`LaneLookup`.
        """
        return LaneLookup(*lane_lookup_kernel(np.asarray(s, dtype=float), np.asarray(d, dtype=float),
                                              *self.lookup_tables()))

    def lookup_tables(self) -> tuple:
        """The arguments of :func:`~evoscen_sim.road.road_kernels.lane_lookup_kernel` after ``(s, d)``: the
        road's length and tables (read-only), for a compiled caller that looks lanes up itself (the world's
        step, :mod:`evoscen_sim.physics.world`). Made once."""
        tables = getattr(self, "_lookup_tables", None)
        if tables is None:
            tables = self._lookup_tables = (
                self.length_m, self._breaks, self._seg_const, self._dr_table, self._dl_table, self._present,
                self._vmax, self._w_coef, self._w_origin, self._off_coef, self._off_origin, self._g_s0, self._g_k)
        return tables

    def lane_of(self, s: ArrayLike, d: ArrayLike) -> np.ndarray:
        """Index of the lane containing lateral position ``d`` at ``s``, -1 if off the road."""
        s_a, d_a = np.broadcast_arrays(np.asarray(s, dtype=float), np.asarray(d, dtype=float))
        sc = np.clip(s_a, 0.0, self.length_m)
        dr, dl, j = self._bounds_all(sc)
        ex = self._present[j]
        dd = d_a[..., None]
        edge_r = dr[..., :1]
        inside = ex & (dl > dr) & (dd <= dl) & ((dd > dr) | ((dd >= dr) & (dr == edge_r)))
        return np.where(inside.any(axis=-1), np.argmax(inside, axis=-1), -1).astype(np.int64)

    def road_edges_d(self, s: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """(d of the right road edge, d of the left road edge) at ``s``."""
        sc = self._clamp(s)
        w, off, _ = self._widths_all(sc)
        return off - w.sum(axis=-1), off

    def distance_to_lane_end(self, lane: ArrayLike, s: ArrayLike) -> np.ndarray:
        """``lane_end_s[lane] - s`` (raw s); +inf for lanes that run to the road end, NaN if invalid."""
        li, _, valid, s_a = self._lane_s(lane, s)
        dist = np.where(self._reaches_end[li], np.inf, self.lane_end_s[li] - s_a)
        return np.where(valid, dist, np.nan)

    def speed_limit_max_mps(self, lane: ArrayLike, s: ArrayLike) -> np.ndarray:
        """Maximum speed (m/s) of the lane at ``s``; NaN where the lane does not exist."""
        li, sc, valid, _ = self._lane_s(lane, s)
        return np.where(valid, self._vmax[self._seg(sc), li], np.nan)

    def speed_limit_min_mps(self, lane: ArrayLike, s: ArrayLike) -> np.ndarray:
        """Minimum speed (m/s) of the lane at ``s`` (0 if none); NaN where the lane does not exist."""
        li, sc, valid, _ = self._lane_s(lane, s)
        return np.where(valid, self._vmin[self._seg(sc), li], np.nan)

    # ------------------------------------------------------------------ reference line
    def _piece(self, s: np.ndarray) -> np.ndarray:
        j = np.searchsorted(self._g_s0, s, side="right") - 1
        return np.clip(j, 0, len(self._g_s0) - 1)

    def heading(self, s: ArrayLike) -> np.ndarray:
        """Heading (rad) of the reference line at ``s`` (end pieces extended beyond the road)."""
        s_a = np.asarray(s, dtype=float)
        j = self._piece(s_a)
        return self._g_h0[j] + self._g_k[j] * (s_a - self._g_s0[j])

    def curvature(self, s: ArrayLike) -> np.ndarray:
        """Curvature (1/m, positive = turning left) of the reference line at ``s``."""
        s_a = np.asarray(s, dtype=float)
        return self._g_k[self._piece(s_a)].copy()

    def geometry_tables(self) -> tuple:
        """The planView pieces' start ``s``, ``x``, ``y``, heading and curvature (read-only), the arguments of
        :func:`~evoscen_sim.road.road_kernels.frenet_to_cartesian_kernel` after ``(s, d)``, for a compiled caller."""
        return self._g_s0, self._g_x0, self._g_y0, self._g_h0, self._g_k

    def frenet_to_cartesian(self, s: ArrayLike, d: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x_m, y_m, heading_rad): the point at lateral offset ``d`` from the reference line at ``s``,
        and the reference line's heading there. Exact for line and arc pieces."""
        if type(s) is np.ndarray and type(d) is np.ndarray and s.ndim == 1 and s.shape == d.shape \
                and s.dtype == np.float64 and d.dtype == np.float64 and s.flags.c_contiguous and d.flags.c_contiguous:
            # the world's columns (every step of a recorded run): the kernel as it is, half the calls
            return frenet_to_cartesian_kernel(s, d, self._g_s0, self._g_x0, self._g_y0, self._g_h0, self._g_k)
        s_a, d_a = np.broadcast_arrays(np.asarray(s, dtype=float), np.asarray(d, dtype=float))
        x, y, h = frenet_to_cartesian_kernel(
            np.ascontiguousarray(s_a).ravel(), np.ascontiguousarray(d_a).ravel(),
            self._g_s0, self._g_x0, self._g_y0, self._g_h0, self._g_k,
        )
        return x.reshape(s_a.shape), y.reshape(s_a.shape), h.reshape(s_a.shape)

    def cartesian_to_frenet(self, x: ArrayLike, y: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """(s_m, d_m) of the point (x, y): the projection onto the nearest planView piece.

        Exact inverse of :meth:`frenet_to_cartesian` for |d| below the arc radii (here up to far
        beyond the ±50 m needed); points before the start / after the end project onto the
        extended first / last piece (s < 0 or s > length).
        """
        x_a, y_a = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        best_dist = np.full(x_a.shape, np.inf)
        best_s = np.full(x_a.shape, np.nan)
        best_d = np.full(x_a.shape, np.nan)
        n_geo = len(self._g_s0)
        for j in range(n_geo):
            x0, y0, h0 = self._g_x0[j], self._g_y0[j], self._g_h0[j]
            k, ln = self._g_k[j], self._g_len[j]
            dx, dy = x_a - x0, y_a - y0
            if k == 0.0:
                ds = dx * math.cos(h0) + dy * math.sin(h0)
                d = -dx * math.sin(h0) + dy * math.cos(h0)
            else:
                r = 1.0 / k
                cx, cy = x0 - r * math.sin(h0), y0 + r * math.cos(h0)
                vx, vy = x_a - cx, y_a - cy
                rho = np.hypot(vx, vy)
                sg = math.copysign(1.0, k)
                h = np.arctan2(sg * vx, -sg * vy)
                mid = 0.5 * k * ln
                delta = mid + (np.mod(h - h0 - mid + np.pi, 2.0 * np.pi) - np.pi)
                ds = delta / k
                d = r - sg * rho
            lo = -np.inf if j == 0 else 0.0
            hi = np.inf if j == n_geo - 1 else ln
            ds_c = np.clip(ds, lo, hi)
            clamped = ds_c != ds
            if np.any(clamped):
                # nearest point is the piece's end: signed offset from the end's normal
                half = 0.5 * k * ds_c
                chord = ds_c * np.sinc(half / np.pi)
                rx = x0 + chord * np.cos(h0 + half)
                ry = y0 + chord * np.sin(h0 + half)
                hh = h0 + k * ds_c
                ex, ey = x_a - rx, y_a - ry
                dist = np.where(clamped, np.hypot(ex, ey), np.abs(d))
                d = np.where(clamped, -ex * np.sin(hh) + ey * np.cos(hh), d)
            else:
                dist = np.abs(d)
            better = dist < best_dist
            best_dist = np.where(better, dist, best_dist)
            best_s = np.where(better, self._g_s0[j] + ds_c, best_s)
            best_d = np.where(better, d, best_d)
        return best_s, best_d

    # ------------------------------------------------------------------ visualisation
    def lane_markings(self) -> list[LaneMarking]:
        """Road marks (type ``none`` skipped) as polylines sampled every ~5 m, per roadMark record."""
        out: list[LaneMarking] = []
        n = self.num_lanes
        for sec in self.map.road.lane_sections:
            lanes = [sec.center, *sec.right]
            outer_id = sec.right[-1].id
            for lane in lanes:
                marks = lane.road_marks
                for r, mark in enumerate(marks):
                    if mark.type == "none":
                        continue
                    sa = sec.s_m + mark.s_offset_m
                    sb = sec.s_m + marks[r + 1].s_offset_m if r + 1 < len(marks) else sec.end_s_m
                    num = max(2, int(math.ceil((sb - sa) / MARKING_STEP_M)) + 1)
                    s = np.linspace(sa, sb, num)
                    # evaluate inside this section (the last sample just before its end)
                    s_eval = s.copy()
                    if sb < self.length_m:
                        s_eval[-1] = np.nextafter(sb, -np.inf)
                    if lane.id == 0:
                        d = self.road_edges_d(s_eval)[1]
                        kind = "edge_left"
                    else:
                        d = self.lane_bounds_d(lane.id + n, s_eval)[0]
                        kind = "edge_right" if lane.id == outer_id else "lane_line"
                    x, y, _ = self.frenet_to_cartesian(s, d)
                    out.append(LaneMarking(kind, mark.type, mark.color, mark.width_m, lane.id,
                                           _readonly(s), _readonly(np.asarray(d, float)),
                                           _readonly(x), _readonly(y)))
        return out


def load_road(path: "str | os.PathLike[str]" = DEFAULT_MAP_PATH) -> RoadModel:
    """Parse an OpenDRIVE file and build its :class:`RoadModel` (InputError on any problem)."""
    return RoadModel(parse_opendrive(path))


__all__ = ["RoadModel", "LaneMarking", "load_road", "DEFAULT_MAP_PATH", "DRIVABLE_LANE_TYPES"]
