"""Our recorded runs as HighD-format recordings (bag → HighD export).

:func:`run_to_highd` turns a run's world states (steps × vehicles, as read from a bag by
:func:`evoscen_eval.scoring.rundata.read_run`) into a :class:`~evoscen_eval.naturalistic.highd.HighDRecording`
with every HighD column, either at the recorded states themselves (``frame_rate_hz=None``:
frame ``k + 1`` = world state ``k``) or resampled to HighD's 25 Hz; :func:`~evoscen_eval.naturalistic.highd.write_recording`
then writes the three CSV files. Behaviour extraction (:mod:`evoscen_eval.naturalistic.behaviour`) reads
such a recording exactly like a real HighD one, so a bag and a HighD recording go through
the same code.

Mapping **[choice]** (HighD films a straight road from above; ours is curved):

* A straight virtual road (:class:`VirtualRoad`): arc length ``s`` → image ``x`` (the box
  centre), lateral offset ``d`` (positive left) → image ``y = y_top − d`` (y points down),
  where ``y_top`` is the lower carriageway's top marking (our reference line, the left
  edge). Our traffic drives towards +x: drivingDirection 2, the LOWER lanes. An empty
  upper carriageway with the same lanes is declared in ``upperLaneMarkings`` (HighD tooling
  expects both); no vehicle drives there.
* Lane markings every ``lane_width_m`` (3.5 m); laneId follows HighD's rule from the box
  centre's y (1 + the number of markings above it), which is our ``lane`` column: lane V
  (index 4, leftmost) is the top lower lane, the merge lane I (index 0) the bottom one.
  With 5 lanes per carriageway: upper lanes 2..6, median 7, lower lanes 8 (V) .. 12 (I).
* Vehicles re-enter upstream with the same id (docs/method.md §1): each re-entry (``s`` jumping back
  by more than ``reentry_jump_m``) starts a NEW HighD track; ``evoscenVehicleId`` in
  tracksMeta keeps the simulator's id and ``evoscenRole`` marks the SUT (1) and the BVs (0)
  — two extra columns that HighD tooling, which reads columns by name, ignores. The SUT is
  exported like any vehicle.
* Resampling to ``frame_rate_hz``: frame ``f`` (from 1) is at ``t0 + (f − 1)/rate``; every
  state column is interpolated LINEARLY in time within a track (never across a re-entry);
  the neighbour relations, ``dhw``, ``thw``, ``ttc`` and ``laneId`` are then computed on the
  resampled states, as HighD computes them on its frames.
* Kinematics: ``xVelocity = speed·cos(heading_rel)``, ``yVelocity = −speed·sin(heading_rel)``
  (y down), ``xAcceleration = accel·cos(heading_rel)``, ``yAcceleration`` = the time
  derivative of ``yVelocity`` along the track. ``dhw`` = bumper-to-bumper gap to the
  preceding vehicle (same laneId, nearest centre ahead), ``thw = dhw / |xVelocity|``,
  ``ttc = dhw / (|xVelocity| − |precedingXVelocity|)`` (negative when the gap opens; ±inf
  when the speeds are equal, or thw at standstill), all three 0 without a preceding
  vehicle, like HighD. ``frontSightDistance`` / ``backSightDistance`` = the distance from the
  centre to the road's end / start.
* recordingMeta: ``locationId`` 0; ``month``, ``weekDay`` and ``startTime`` are empty (a
  simulated run has no date); tracksMeta ``class`` is ``Truck`` for vehicles of at least
  ``truck_length_m``, else ``Car``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from evoscen_contract.contract import EVENT_REENTRY, EVENT_SHIFT

from evoscen_eval.naturalistic.highd import HighDRecording, find_neighbours

#: State columns (WORLD_FIELDS) the export needs.
REQUIRED_COLUMNS: tuple[str, ...] = ("s", "d", "speed", "accel", "heading_rel", "length", "width")


@dataclass(frozen=True)
class VirtualRoad:
    """The straight road an export is drawn on (image coordinates, metres, y down)."""

    num_lanes: int = 5
    """Lanes per carriageway (ours: 4 mainline + the merge lane)."""
    lane_width_m: float = 3.5
    length_m: float = 2393.76
    """Road length (m): x of the road's end (sight distances)."""
    top_margin_m: float = 2.0
    """y of the upper carriageway's top marking."""
    median_m: float = 2.0
    """Gap between the two carriageways' inner markings."""
    speed_limit_mps: float = 120.0 / 3.6

    def upper_markings(self) -> np.ndarray:
        """y of the (empty) upper carriageway's markings, top to bottom."""
        return self.top_margin_m + self.lane_width_m * np.arange(self.num_lanes + 1)

    def lower_top_y(self) -> float:
        """y of the lower carriageway's top marking: where ``d = 0`` (our reference line)."""
        return float(self.upper_markings()[-1] + self.median_m)

    def lower_markings(self) -> np.ndarray:
        """y of our carriageway's markings, top (lane V's left edge) to bottom."""
        return self.lower_top_y() + self.lane_width_m * np.arange(self.num_lanes + 1)

    def y_center(self, d: np.ndarray) -> np.ndarray:
        """Image y of lateral offsets ``d`` (positive left = up)."""
        return self.lower_top_y() - np.asarray(d, dtype=np.float64)

    def lane_id(self, lane_index: np.ndarray) -> np.ndarray:
        """HighD laneId of our lane indices (0 = merge lane … num_lanes − 1 = leftmost)."""
        upper_markings = self.num_lanes + 1
        return (upper_markings + 2 + (self.num_lanes - 1 - np.asarray(lane_index))).astype(np.int32)


@dataclass(frozen=True)
class ExportOptions:
    """How a run becomes a HighD recording (see the module docstring)."""

    frame_rate_hz: float | None = 25.0
    """Frames per second of the export; None = one frame per recorded world state."""
    recording_id: int = 1
    reentry_jump_m: float = 10.0
    """A backward jump of ``s`` larger than this between two states is a re-entry (new track)."""
    truck_length_m: float = 8.0
    road: VirtualRoad = VirtualRoad()


def unshifted_s(s: np.ndarray, shifts: dict[int, float] | None = None) -> np.ndarray:
    """``s`` (states × vehicles) with the traffic window's shifts undone, so the arc length grows
    along a trip as on an endless road. ``shifts``: the ``shift_m`` of each ``evoscen/shift`` event by
    the state it led to (exact); without them a shift is recognised as a fall of the median step
    of more than 50 m (:func:`evoscen_sim.physics.window.common_shift`: exact to within the vehicles'
    differences of driving in that step)."""
    s = np.asarray(s, dtype=float)
    if s.shape[0] < 2:
        return s
    back = np.zeros(s.shape[0])
    if shifts is not None:
        for k, m in shifts.items():
            if 0 < k < s.shape[0]:
                back[k] = m
    elif s.shape[1] >= 3:  # one or two vehicles: a jump is a re-entry, not a shift
        med = np.median(np.diff(s, axis=0), axis=1)
        back[1:] = np.where(med < -50.0, -med, 0.0)
    return s + np.cumsum(back)[:, None]


def _segments(s: np.ndarray, jump_m: float, entries: dict[int, set[int]] | None = None) -> list[tuple[int, int, int]]:
    """(vehicle column, first state, last state) of every track: runs of ``s`` without re-entry.

    ``entries`` (vehicle column -> the states that begin a new trip, from the run's
    ``evoscen/reentry`` events) are exact; without them a jump of ``s`` backwards by more than
    ``jump_m``, or forwards by more than 40 m/s could drive in a second plus ``jump_m``, starts a track.
    """
    out = []
    k_count, v_count = s.shape
    ds = np.diff(s, axis=0)
    for v in range(v_count):
        if entries is not None:
            breaks = np.array(sorted(k for k in entries.get(v, ()) if 0 < k < k_count), dtype=np.int64)
        else:
            breaks = np.flatnonzero((ds[:, v] < -jump_m) | (ds[:, v] > 40.0 + jump_m)) + 1
        starts = np.concatenate([[0], breaks])
        stops = np.concatenate([breaks - 1, [k_count - 1]])
        out.extend((v, int(a), int(b)) for a, b in zip(starts, stops))
    return out


def _reduce_per_track(values: np.ndarray, valid: np.ndarray, starts: np.ndarray, how: str) -> np.ndarray:
    """min/max/mean of ``values`` over each track's valid rows (−1 where a track has none)."""
    if how == "mean":
        sums = np.add.reduceat(np.where(valid, values, 0.0), starts)
        counts = np.add.reduceat(valid.astype(np.float64), starts)
        return np.where(counts > 0, sums / np.maximum(counts, 1), -1.0)
    fill = np.inf if how == "min" else -np.inf
    red = (np.minimum if how == "min" else np.maximum).reduceat(np.where(valid, values, fill), starts)
    return np.where(np.isfinite(red), red, -1.0)


def run_to_highd(run: Any, options: ExportOptions = ExportOptions()) -> HighDRecording:
    """The run ``run`` as a HighD recording with every HighD column (module docstring).

    ``run`` needs ``time_s`` [K], ``columns`` (WORLD_FIELDS → [K, V] arrays; at least
    :data:`REQUIRED_COLUMNS`, and ``role`` if the SUT is to be marked), ``ids`` [V] and,
    optionally, ``sut_index`` and ``warnings`` — a :class:`evoscen_eval.scoring.rundata.RunData`.
    """
    road = options.road
    time_s = np.asarray(run.time_s, dtype=np.float64)
    cols = {c: np.asarray(run.columns[c], dtype=np.float64) for c in REQUIRED_COLUMNS}
    ids = np.asarray(run.ids, dtype=np.int64)
    events = getattr(run, "events", None)
    shifts = None
    if events is not None:
        shifts = {int(np.searchsorted(time_s, float(e["time_s"]) - 1e-9)): float(e["shift_m"])
                  for e in events if e.get("name") == EVENT_SHIFT}
    cols["s"] = unshifted_s(cols["s"], shifts)  # x grows along the road as if it had no end
    k_count, v_count = cols["s"].shape
    if "role" in run.columns:
        role = np.asarray(run.columns["role"], dtype=np.float64)[0].astype(np.int32)
    else:
        role = np.zeros(v_count, dtype=np.int32)
        if getattr(run, "sut_index", None) is not None:
            role[int(run.sut_index)] = 1
    t0 = float(time_s[0]) if k_count else 0.0
    rate = options.frame_rate_hz if options.frame_rate_hz is not None else (
        1.0 / float(np.median(np.diff(time_s))) if k_count > 1 else 1.0)

    # ---- tracks: segments between re-entries, sampled at their frames
    segs = []
    entries = None
    if events is not None:  # the run's own record of new trips (window entries, re-entries)
        entries = {}
        col_of = {int(x): j for j, x in enumerate(ids)}
        for e in events:
            if e.get("name") == EVENT_REENTRY:
                k = int(np.searchsorted(time_s, float(e["time_s"]) - 1e-9))
                for vid in e.get("ids", ()):
                    if int(vid) in col_of:
                        entries.setdefault(col_of[int(vid)], set()).add(k)
    for v, a, b in _segments(cols["s"], options.reentry_jump_m, entries):
        if options.frame_rate_hz is None:
            frames = np.arange(a, b + 1, dtype=np.int64) + 1
            t_f = time_s[a:b + 1]
        else:
            f_lo = int(np.ceil((time_s[a] - t0) * rate - 1e-6))
            f_hi = int(np.floor((time_s[b] - t0) * rate + 1e-6))
            if f_hi < f_lo:
                continue  # a track shorter than one frame interval, between two frames
            frames = np.arange(f_lo, f_hi + 1, dtype=np.int64) + 1
            t_f = t0 + (frames - 1) / rate
        segs.append((int(frames[0]), int(ids[v]), v, a, b, frames, t_f))
    segs.sort(key=lambda g: (g[0], g[1]))

    parts: dict[str, list[np.ndarray]] = {c: [] for c in (*REQUIRED_COLUMNS, "frame", "track", "t")}
    for track_no, (_, _, v, a, b, frames, t_f) in enumerate(segs, start=1):
        seg_t = time_s[a:b + 1]
        for c in REQUIRED_COLUMNS:
            parts[c].append(np.interp(t_f, seg_t, cols[c][a:b + 1, v]))
        parts["frame"].append(frames)
        parts["track"].append(np.full(frames.shape, track_no, dtype=np.int64))
        parts["t"].append(t_f)
    n_tracks = len(segs)
    if n_tracks == 0:
        raise ValueError("run_to_highd: the run has no vehicle state to export")
    st = {c: np.concatenate(p) for c, p in parts.items()}
    seg_vehicle = np.array([g[2] for g in segs], dtype=np.int64)
    track = st["track"]
    frame = st["frame"]

    # ---- geometry and kinematics in image coordinates
    cos_h, sin_h = np.cos(st["heading_rel"]), np.sin(st["heading_rel"])
    return build_recording(
        frame=frame, track=track, time_s=st["t"], x_center=st["s"], y_center=road.y_center(st["d"]),
        length=st["length"], width=st["width"], x_velocity=st["speed"] * cos_h, y_velocity=-st["speed"] * sin_h,
        x_acceleration=st["accel"] * cos_h, direction=np.full(track.shape, 2, dtype=np.int32),
        upper_markings=road.upper_markings(), lower_markings=road.lower_markings(), road_length_m=road.length_m,
        recording_id=options.recording_id, frame_rate_hz=rate, speed_limit_mps=road.speed_limit_mps,
        truck_length_m=options.truck_length_m,
        extra_meta={"evoscenVehicleId": ids[seg_vehicle].astype(np.int32),
                    "evoscenRole": role[seg_vehicle].astype(np.int32)},
        source=str(getattr(run, "source", "run")), warnings=list(getattr(run, "warnings", []) or []))


def _recording_meta(frame: np.ndarray, tracks_meta: dict[str, np.ndarray], n_tracks: int, recording_id: int,
                    rate: float, speed_limit_mps: float, upper_markings: np.ndarray,
                    lower_markings: np.ndarray) -> dict[str, str]:
    """HighD's recordingMeta of a recording (:func:`build_recording`): its text fields."""
    n_frames = int(frame.max())
    n_trucks = int(np.sum(tracks_meta["class"] == "Truck"))
    return {
        "id": str(recording_id),
        "frameRate": f"{rate:g}",
        "locationId": "0",
        "speedLimit": f"{speed_limit_mps:.2f}",
        "month": "",
        "weekDay": "",
        "startTime": "",
        "duration": f"{n_frames / rate:.2f}",
        "totalDrivenDistance": f"{float(np.sum(tracks_meta['traveledDistance'])):.2f}",
        "totalDrivenTime": f"{float(np.sum(tracks_meta['numFrames'])) / rate:.2f}",
        "numVehicles": str(n_tracks),
        "numCars": str(n_tracks - n_trucks),
        "numTrucks": str(n_trucks),
        "upperLaneMarkings": ";".join(f"{y:.2f}" for y in upper_markings),
        "lowerLaneMarkings": ";".join(f"{y:.2f}" for y in lower_markings),
    }


def build_recording(*, frame: np.ndarray, track: np.ndarray, time_s: np.ndarray, x_center: np.ndarray,
                    y_center: np.ndarray, length: np.ndarray, width: np.ndarray, x_velocity: np.ndarray,
                    y_velocity: np.ndarray, x_acceleration: np.ndarray, direction: np.ndarray,
                    upper_markings: np.ndarray, lower_markings: np.ndarray, road_length_m: float,
                    recording_id: int, frame_rate_hz: float, speed_limit_mps: float = -1.0,
                    truck_length_m: float = 8.0, extra_meta: dict[str, np.ndarray] | None = None,
                    source: str = "<memory>", warnings: list[str] | None = None) -> HighDRecording:
    """A complete HighD recording from per-row states (rows sorted by track, then frame).

    Everything HighD derives is computed here, the same way for every producer (the export,
    the benchmark's synthetic recording): box corners, laneId from the markings, the
    neighbour relations (:func:`~evoscen_eval.naturalistic.highd.find_neighbours`), ``dhw``/``thw``/``ttc``
    and ``precedingXVelocity`` (module docstring), ``yAcceleration`` as the time derivative of
    ``yVelocity`` along each track, sight distances (to the road's end in the direction of
    travel and to its start), tracksMeta and recordingMeta. ``track`` numbers the tracks
    1..N; ``direction`` is per row (1: towards −x, 2: towards +x).
    """
    x_c, y_c, x_vel = x_center, y_center, x_velocity
    rate = frame_rate_hz
    starts = np.flatnonzero(np.diff(track, prepend=track[0] - 1) != 0)
    ends = np.append(starts[1:], len(track)) - 1
    n_tracks = len(starts)
    y_acc = np.zeros_like(y_velocity)
    for a, b in zip(starts, ends + 1):
        if b - a > 1:
            y_acc[a:b] = np.gradient(y_velocity[a:b], time_s[a:b])
    marks = np.sort(np.concatenate([upper_markings, lower_markings]))
    lane_id = (1 + np.searchsorted(marks, y_c, side="right")).astype(np.int32)

    # ---- HighD relations on the frames
    nb = find_neighbours(frame, lane_id, x_c, length, direction)

    def ids_of(rows: np.ndarray) -> np.ndarray:
        return np.where(rows >= 0, track[np.maximum(rows, 0)], 0).astype(np.int32)

    p = nb.preceding
    has_p = p >= 0
    pc = np.maximum(p, 0)
    forward = np.where(direction == 1, -1.0, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        # bumper-to-bumper gap along the direction of travel
        dhw = np.where(has_p, forward * (x_c[pc] - x_c) - 0.5 * (length[pc] + length), 0.0)
        speed_abs = np.abs(x_vel)
        closing = speed_abs - np.abs(x_vel[pc])
        thw = np.where(has_p, np.where(speed_abs > 0, dhw / speed_abs, np.copysign(np.inf, dhw)), 0.0)
        ttc = np.where(has_p, np.where(closing != 0, dhw / closing, np.inf), 0.0)
    prec_xvel = np.where(has_p, x_vel[pc], 0.0)
    to_end = np.where(direction == 1, x_c, road_length_m - x_c)

    tracks = {
        "frame": frame.astype(np.int32),
        "id": track.astype(np.int32),
        "x": x_c - 0.5 * length,
        "y": y_c - 0.5 * width,
        "width": length,
        "height": width,
        "xVelocity": x_vel,
        "yVelocity": y_velocity,
        "xAcceleration": x_acceleration,
        "yAcceleration": y_acc,
        "frontSightDistance": to_end,
        "backSightDistance": road_length_m - to_end,
        "dhw": dhw,
        "thw": thw,
        "ttc": ttc,
        "precedingXVelocity": prec_xvel,
        "precedingId": ids_of(p),
        "followingId": ids_of(nb.following),
        "leftPrecedingId": ids_of(nb.left_preceding),
        "leftAlongsideId": ids_of(nb.left_alongside),
        "leftFollowingId": ids_of(nb.left_following),
        "rightPrecedingId": ids_of(nb.right_preceding),
        "rightAlongsideId": ids_of(nb.right_alongside),
        "rightFollowingId": ids_of(nb.right_following),
        "laneId": lane_id,
    }

    # ---- tracksMeta
    same_track = np.diff(track, prepend=track[0] - 1) == 0
    lane_changes = np.add.reduceat(same_track & (np.diff(lane_id, prepend=lane_id[0]) != 0), starts)
    track_length = length[starts]
    tracks_meta = {
        "id": track[starts].astype(np.int32),
        "width": track_length,
        "height": width[starts],
        "initialFrame": frame[starts].astype(np.int32),
        "finalFrame": frame[ends].astype(np.int32),
        "numFrames": (ends - starts + 1).astype(np.int32),
        "class": np.where(track_length >= truck_length_m, "Truck", "Car"),
        "drivingDirection": direction[starts].astype(np.int32),
        "traveledDistance": np.abs(x_c[ends] - x_c[starts]),
        "minXVelocity": np.minimum.reduceat(x_vel, starts),
        "maxXVelocity": np.maximum.reduceat(x_vel, starts),
        "meanXVelocity": np.add.reduceat(x_vel, starts) / (ends - starts + 1),
        "minDHW": _reduce_per_track(dhw, has_p & (dhw > 0), starts, "min"),
        "minTHW": _reduce_per_track(thw, has_p & (thw > 0) & np.isfinite(thw), starts, "min"),
        "minTTC": _reduce_per_track(ttc, has_p & (ttc > 0) & np.isfinite(ttc), starts, "min"),
        "numLaneChanges": lane_changes.astype(np.int32),
        **(extra_meta or {}),
    }

    recording_meta = _recording_meta(frame, tracks_meta, n_tracks, recording_id, rate, speed_limit_mps,
                                     upper_markings, lower_markings)
    return HighDRecording(
        recording_id=recording_id, frame_rate_hz=rate,
        upper_lane_markings=np.asarray(upper_markings, dtype=np.float64),
        lower_lane_markings=np.asarray(lower_markings, dtype=np.float64),
        recording_meta=recording_meta, tracks_meta=tracks_meta, tracks=tracks,
        source=source, warnings=list(warnings or []))
