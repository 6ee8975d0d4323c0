"""What the report's plots read, bounded whatever the run's length: the bins of the SUT's TTC and
speed histograms, the snapshot scenes, the timeline of at most :data:`TIMELINE_POINTS` points, and
:class:`PlotSeries`, which gathers the histograms and the timeline block by block for
:class:`~evoscen_eval.scoring.streaming.ScoreStream`."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from evoscen_contract import contract as C

TIMELINE_POINTS = 20_000
"""Most points of the report's timeline; a longer run is drawn from buckets of 2^n states."""
TTC_BINS = np.linspace(0.0, 20.0, 41)
"""Bins of the SUT's TTC distribution (s); TTC above 20 s (and infinite TTC) is left out."""
SPEED_BINS = np.linspace(0.0, 40.0, 81)
"""Bins of the SUT's speed distribution (m/s)."""


@dataclass
class Scene:
    """One world state, for a bird's-eye snapshot: ``columns[f]`` is a ``[V]`` array."""

    state: int
    time_s: float
    columns: dict[str, np.ndarray]
    ids: np.ndarray
    sut_index: int
    sut_ttc: float = math.inf
    sut_accel: float = 0.0


_SCENE_FIELDS = ("x", "y", "yaw", "length", "width", "speed")
_F = {name: j for j, name in enumerate(C.WORLD_FIELDS)}


def scene_of(tables: np.ndarray, times: np.ndarray, r: int, k: int, ids: np.ndarray, sut: int) -> Scene:
    """The :class:`Scene` of state ``k``, row ``r`` of a block's ``tables`` ``[n, V, F]``."""
    return Scene(state=k, time_s=float(times[r]),
                 columns={f: tables[r, :, _F[f]].copy() for f in _SCENE_FIELDS},
                 ids=ids.copy(), sut_index=sut)


@dataclass
class PlotData:
    """What the report's plots and the experiments' distributions read (bounded in size)."""

    states: int
    ttc_hist: np.ndarray
    """Counts of the SUT's TTC over :data:`TTC_BINS` (finite TTC up to 20 s)."""
    speed_hist: np.ndarray
    """Counts of the SUT's speed over :data:`SPEED_BINS`."""
    timeline_time_s: np.ndarray
    timeline_speed: np.ndarray
    timeline_lane: np.ndarray
    timeline_ttc: np.ndarray
    """Lowest TTC of each timeline bucket."""
    timeline_stride: int
    """States per timeline point (1 up to :data:`TIMELINE_POINTS` states)."""
    timeline_bvs: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """BVs within :data:`~evoscen_eval.scoring.streaming.TRAFFIC_RANGE_M` of the SUT: the mean over each
    timeline bucket (the count itself with one state per point)."""
    collision_scenes: dict[int, Scene] = field(default_factory=dict)
    worst_scene: Scene | None = None
    lane_segments: np.ndarray | None = None
    frames: object | None = None
    """The animation's frames (:class:`~evoscen_eval.scoring.animation.FrameSeries`), None without them."""


class PlotSeries:
    """The SUT's TTC and speed histograms and the timeline, fed a block of states at a time."""

    def __init__(self) -> None:
        self.ttc_hist = np.zeros(len(TTC_BINS) - 1, dtype=np.int64)
        self.speed_hist = np.zeros(len(SPEED_BINS) - 1, dtype=np.int64)
        self._tl: dict[str, list] = {"bucket": [], "t": [], "speed": [], "lane": [], "ttc": [], "bvs": [], "n": []}
        self._stride = 1

    def add_block(self, ks, times, speed, lane, ttc, bvs) -> None:
        """A block's states ``ks``: the histograms, then the timeline."""
        finite = ttc[np.isfinite(ttc) & (ttc <= TTC_BINS[-1])]
        self.ttc_hist += np.histogram(finite, bins=TTC_BINS)[0]
        self.speed_hist += np.histogram(speed, bins=SPEED_BINS)[0]
        self._timeline(ks, times, speed, lane, ttc, bvs)

    def _timeline(self, ks, times, speed, lane, ttc, bvs) -> None:
        """Per bucket: the first state's time, speed and lane, the lowest TTC, and the sum of the
        BV counts near the SUT with the bucket's number of states (integers: their mean is exact)."""
        tl = self._tl
        buckets = ks // self._stride
        unique, first = np.unique(buckets, return_index=True)  # buckets ascend: each a contiguous run
        near_sums = np.add.reduceat(bvs, first).tolist()
        sizes = np.diff(np.append(first, buckets.size)).tolist()
        # per bucket at once (docs/performance.md "Per-step work of the scores"): the lowest TTC of each
        # contiguous run, the first state's values
        lows = np.minimum.reduceat(np.asarray(ttc, dtype=np.float64), first).tolist()
        bs = unique.tolist()
        i0 = 0
        if tl["bucket"] and bs and tl["bucket"][-1] == bs[0]:  # only a block's first bucket can go on
            tl["ttc"][-1] = min(tl["ttc"][-1], lows[0])
            tl["bvs"][-1] += near_sums[0]
            tl["n"][-1] += sizes[0]
            i0 = 1
        if i0 < len(bs):
            r = first[i0:]
            tl["bucket"] += bs[i0:]
            tl["t"] += np.asarray(times, dtype=np.float64)[r].tolist()
            tl["speed"] += np.asarray(speed, dtype=np.float64)[r].tolist()
            tl["lane"] += np.asarray(lane, dtype=np.float64)[r].tolist()
            tl["ttc"] += lows[i0:]
            tl["bvs"] += near_sums[i0:]
            tl["n"] += sizes[i0:]
        while len(tl["bucket"]) > TIMELINE_POINTS:
            self._stride *= 2
            merged: dict[str, list] = {key: [] for key in tl}
            for i, b in enumerate(tl["bucket"]):
                if merged["bucket"] and merged["bucket"][-1] == b // 2:
                    merged["ttc"][-1] = min(merged["ttc"][-1], tl["ttc"][i])
                    merged["bvs"][-1] += tl["bvs"][i]
                    merged["n"][-1] += tl["n"][i]
                    continue
                merged["bucket"].append(b // 2)
                for key in ("t", "speed", "lane", "ttc", "bvs", "n"):
                    merged[key].append(tl[key][i])
            self._tl = tl = merged

    def timeline_fields(self) -> dict:
        """The :class:`PlotData` fields of the histograms and the timeline."""
        tl = self._tl
        return dict(ttc_hist=self.ttc_hist.copy(), speed_hist=self.speed_hist.copy(),
                    timeline_time_s=np.asarray(tl["t"]), timeline_speed=np.asarray(tl["speed"]),
                    timeline_lane=np.asarray(tl["lane"]), timeline_ttc=np.asarray(tl["ttc"]),
                    timeline_stride=self._stride,
                    timeline_bvs=np.asarray(tl["bvs"], dtype=np.float64) / np.maximum(np.asarray(tl["n"]), 1))
