"""Behaviour extraction for the fidelity comparison (docs/method.md §5.3): one code path for both sources.

Input is a :class:`~evoscen_eval.naturalistic.highd.HighDRecording` — a real HighD recording loaded by
:func:`~evoscen_eval.naturalistic.highd.load_recording`, or one of our runs converted by
:func:`~evoscen_eval.naturalistic.highd_export.run_to_highd` (at its own 10 Hz, or exported to 25 Hz and
loaded back). Only HighD's columns are read (``frame``, ``id``, ``xVelocity``, ``dhw``,
``thw``, ``ttc``, ``precedingXVelocity``, ``precedingId``, ``laneId``), so both sources get
exactly the same definitions and filters. Speeds are ``|xVelocity|`` (HighD's two
directions have opposite signs).

* **Car following** (per frame): a (DHW, speed) and a (THW, speed) sample from every row
  with a preceding vehicle (``precedingId ≠ 0``) within range (``0 < dhw ≤ leader_range_m``)
  and ``speed ≥ min_speed_mps`` **[choice: 100 m, 5 m/s]**.
* **Lane changes**: a change is a ``laneId`` change between two consecutive frames of a
  track, both lanes driving lanes of the track's direction (HighD's outer ids are not
  lanes). Its moment is the LAST frame in the original lane **[choice]**, where that lane's
  preceding vehicle is known. *Mandatory* when a slower vehicle is ahead in the original
  lane — preceding vehicle within ``leader_range_m`` and ``|precedingXVelocity| < speed``
  — sampled by its TTC (the ``ttc`` column, > 0 there); *voluntary* when there is none
  ahead within range, or it is not slower — sampled by the speed. TTC samples above
  ``max_ttc_s`` **[choice: 30 s]** are counted but not put in the distribution (a nearly
  equal speed gives an unbounded TTC that would stretch the KDE grid).
* Our runs: the SUT's tracks (tracksMeta ``evoscenRole`` = 1) are left out unless
  ``include_sut`` — docs/method.md §5.3 compares BVs with naturalistic vehicles.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from evoscen_eval.naturalistic.highd import HighDRecording


@dataclass(frozen=True)
class BehaviourConfig:
    """Filters of the extraction, the same for every source."""

    leader_range_m: float = 100.0
    """A preceding vehicle counts only within this DHW (m) (car following and lane-change class)."""
    min_speed_mps: float = 5.0
    """Car-following samples only from vehicles at least this fast (m/s); avoids THW at standstill."""
    max_ttc_s: float = 30.0
    """Mandatory lane changes with a TTC above this (s) are counted, not sampled."""
    include_sut: bool = False
    """Also take samples from the SUT's tracks (tracksMeta ``evoscenRole`` = 1) of our runs."""


@dataclass
class LaneChanges:
    """Every lane change found, one entry per change (arrays of equal length)."""

    track_id: np.ndarray
    frame: np.ndarray
    """The moment: the last frame in the original lane."""
    from_lane: np.ndarray
    to_lane: np.ndarray
    mandatory: np.ndarray
    """True: a slower vehicle was ahead in the original lane."""
    ttc_s: np.ndarray
    """TTC to that vehicle at the moment (mandatory changes; NaN for voluntary ones)."""
    speed_mps: np.ndarray


@dataclass
class BehaviourSamples:
    """The four distributions' samples of one or more recordings."""

    dhw_speed: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    """[N, 2]: (DHW m, speed m/s) of car-following rows."""
    thw_speed: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    """[N, 2]: (THW s, speed m/s) of the same rows."""
    mandatory_ttc_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """TTC (s) of mandatory lane changes (≤ max_ttc_s)."""
    voluntary_speed_mps: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """Speed (m/s) of voluntary lane changes."""
    num_mandatory: int = 0
    num_voluntary: int = 0
    num_rows: int = 0
    """Rows (track frames) looked at."""

    @staticmethod
    def concat(parts: list["BehaviourSamples"]) -> "BehaviourSamples":
        """All samples of ``parts`` together."""
        if not parts:
            return BehaviourSamples()
        return BehaviourSamples(
            dhw_speed=np.concatenate([p.dhw_speed for p in parts]),
            thw_speed=np.concatenate([p.thw_speed for p in parts]),
            mandatory_ttc_s=np.concatenate([p.mandatory_ttc_s for p in parts]),
            voluntary_speed_mps=np.concatenate([p.voluntary_speed_mps for p in parts]),
            num_mandatory=sum(p.num_mandatory for p in parts),
            num_voluntary=sum(p.num_voluntary for p in parts),
            num_rows=sum(p.num_rows for p in parts),
        )


def _row_mask(rec: HighDRecording, config: BehaviourConfig) -> np.ndarray:
    """Rows that take part: all, minus the SUT's tracks unless ``include_sut``."""
    if config.include_sut or "evoscenRole" not in rec.tracks_meta:
        return np.ones(rec.num_rows, dtype=bool)
    return rec.row_meta("evoscenRole") != 1


def car_following(rec: HighDRecording, config: BehaviourConfig = BehaviourConfig(),
                  rows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(DHW, speed) and (THW, speed) samples, [N, 2] each (module docstring for the filters)."""
    t = rec.tracks
    speed = np.abs(t["xVelocity"])
    keep = ((t["precedingId"] != 0) & (t["dhw"] > 0) & (t["dhw"] <= config.leader_range_m)
            & (speed >= config.min_speed_mps))
    if rows is not None:
        keep &= rows
    return (np.column_stack([t["dhw"][keep], speed[keep]]),
            np.column_stack([t["thw"][keep], speed[keep]]))


def lane_changes(rec: HighDRecording, config: BehaviourConfig = BehaviourConfig(),
                 rows: np.ndarray | None = None) -> LaneChanges:
    """Every lane change of ``rec``, classified (module docstring).

    Rows must be sorted by track id, then frame (as the loader and the export give them).
    """
    t = rec.tracks
    n = rec.num_rows
    if n < 2:
        empty = np.zeros(0)
        return LaneChanges(empty.astype(np.int32), empty.astype(np.int32), empty.astype(np.int32),
                           empty.astype(np.int32), empty.astype(bool), empty, empty)
    lane = t["laneId"]
    direction = rec.driving_direction()
    driving = np.where(direction == 1, np.isin(lane, rec.driving_lanes(1)), np.isin(lane, rec.driving_lanes(2)))
    i = np.arange(n - 1)
    change = ((t["id"][1:] == t["id"][:-1]) & (t["frame"][1:] == t["frame"][:-1] + 1)
              & (lane[1:] != lane[:-1]) & driving[1:] & driving[:-1])
    if rows is not None:
        change &= rows[:-1]
    at = i[change]  # the last frame in the original lane
    speed = np.abs(t["xVelocity"][at])
    has_leader = (t["precedingId"][at] != 0) & (t["dhw"][at] > 0) & (t["dhw"][at] <= config.leader_range_m)
    slower = np.abs(t["precedingXVelocity"][at]) < speed
    mandatory = has_leader & slower
    ttc = np.where(mandatory, t["ttc"][at], np.nan)
    return LaneChanges(track_id=t["id"][at], frame=t["frame"][at], from_lane=lane[at], to_lane=lane[at + 1],
                       mandatory=mandatory, ttc_s=ttc, speed_mps=speed)


def extract_behaviour(rec: HighDRecording, config: BehaviourConfig = BehaviourConfig()) -> BehaviourSamples:
    """The four distributions' samples of one recording (HighD or ours)."""
    rows = _row_mask(rec, config)
    dhw_speed, thw_speed = car_following(rec, config, rows)
    lc = lane_changes(rec, config, rows)
    ttc = lc.ttc_s[lc.mandatory]
    return BehaviourSamples(
        dhw_speed=dhw_speed,
        thw_speed=thw_speed,
        mandatory_ttc_s=ttc[ttc <= config.max_ttc_s],
        voluntary_speed_mps=lc.speed_mps[~lc.mandatory],
        num_mandatory=int(np.sum(lc.mandatory)),
        num_voluntary=int(np.sum(~lc.mandatory)),
        num_rows=int(np.sum(rows)),
    )
