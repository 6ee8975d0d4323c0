"""The scores of a run in one pass over its states, in memory independent of the run's length.

:class:`ScoreStream` takes the world states one at a time (the evaluator node as they arrive,
a bag as it is read, the in-process runner after each step) and the events, and gives the
``report.json`` dict and what the report's plots need (:class:`~evoscen_eval.scoring.plot_inputs.PlotData`)
at the end. It holds no ``[K, V]`` array: states wait in a block of :data:`BLOCK_STATES` and each block is
reduced with the same broadcasting definitions the scores are written in
(:mod:`evoscen_sim.danger.safety`; they act row by row, so a block gives the same per-state values
as a whole run would) to

* running sums, counts, minima and maxima (efficiency, the conflict figures);
* the exposure in progress (an exposure is a run of dangerous states; one block's run can
  continue into the next) and the finished exposure list;
* the SUT lane change in progress with its interaction sums and its PET window (which runs
  ``rear_attribution_s`` past the change's end, so it can outlive the change by blocks;
  :mod:`evoscen_eval.scoring.sut_lane_changes`);
* per-window counts of the complexity windows;
* the surrogate-safety profile of the SUT (:data:`SSM_SIDES`: front = the SUT behind its leader,
  rear = its follower behind it): states and episodes below the SSM TTC threshold, their
  time-integrated TTC, episodes above the DRAC threshold (an episode is a maximal run of
  states below (above) the threshold with the same counterpart; the counterpart of the
  previous block's last state is carried, so an episode can continue into the next block);
* the traffic around the SUT: per state the BVs within :data:`TRAFFIC_RANGE_M` of it along
  the road, summed per :data:`TRAFFIC_WINDOW_S` window, and the states with none (integers);
* fixed-bin histograms of the SUT's TTC and speed, a timeline of at most
  :data:`~evoscen_eval.scoring.plot_inputs.TIMELINE_POINTS` points (a longer run is drawn from buckets of
  2^n states: the first speed and lane and the lowest TTC of each; :mod:`evoscen_eval.scoring.plot_inputs`),
  and the scenes of the report's snapshots (the states of the first collisions and of the worst exposure);
* what each SUT collision was (:mod:`evoscen_eval.scoring.sut_collisions`);
* per exposure the rules that made it one, their extreme values and vehicles, and each state's
  severity over those rules (:mod:`evoscen_eval.scoring.exposure_rules`);
* one state in every few with the vehicles near the SUT, for the animation (at most
  :data:`~evoscen_eval.scoring.animation.KEEP_FRAMES`; :mod:`evoscen_eval.scoring.animation`).

What stays proportional to the run is its output: the exposure, collision and lane-change
lists and the per-window counts (one entry per 100 states, one per traffic window). Blocks start at multiples of
:data:`BLOCK_STATES` from state 0 whoever feeds the stream, so the live evaluator, a bag read
offline and the in-process runner sum in the same order and agree to the last bit.

Definitions (docs/evaluation.md; formulas in :mod:`evoscen_eval.scoring.metrics`): a block's values
equal the whole-run definitions except for floating-point sums (the mean speed, the
interaction means and the trailing-window acceleration of AD are summed block by block).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from evoscen_contract import contract as C
from evoscen_sim.danger.safety import (
    attribution_steps,
    beside_gap,
    cut_in_gap,
    danger_terms,
    drac,
    exposure_runs,
    follower_headway,
    follower_ttc,
    sut_follower,
    sut_leader,
    sut_ttc,
)

from evoscen_eval.scoring.animation import FrameSeries
from evoscen_eval.scoring.exposure_rules import ExposureRules, RuleInputs
from evoscen_eval.scoring.exposure_rules import severity as rule_severity
from evoscen_eval.scoring.plot_inputs import PlotData, PlotSeries, Scene, scene_of
from evoscen_eval.scoring.sut_collisions import SutCollisions
from evoscen_eval.scoring.sut_lane_changes import SutLaneChanges

BLOCK_STATES = 256
"""States reduced together (the block size bounds the memory of the stream)."""

TRAFFIC_RANGE_M = 100.0
"""A BV is around the SUT when |s_BV − s_SUT| is at most this (m; same road, any lane)."""
TRAFFIC_WINDOW_S = 30.0
"""The traffic around the SUT is averaged over windows this long (s; 300 states at dt 0.1 s)."""

SSM_SIDES = ("front", "rear")
"""The sides of the surrogate-safety profile: front = the SUT following the vehicle ahead in its
path (its TTC and DRAC), rear = the vehicle behind in its path following the SUT (the follower's)."""

_F = {name: j for j, name in enumerate(C.WORLD_FIELDS)}


@dataclass
class _Exposure:
    start: int
    start_time_s: float
    min_ttc: float = math.inf
    min_accel: float = math.inf
    severity: float = -math.inf
    worst: int = -1
    rear_states: int = 0
    cut_in_states: int = 0
    beside_states: int = 0
    headway_states: int = 0
    rules: ExposureRules | None = None


class ScoreStream:
    """The scores of one run, fed state by state (see the module docstring).

    Args:
        ev: the evaluation settings (an :class:`~evoscen_sim.config.scenario_config.EvaluationConfig`).
        dt_s: the step; None: taken from the first two stamps (0.1 s for a single state).
    """

    def __init__(self, ev, dt_s: float | None = None, *, frames: bool = True) -> None:  # EvaluationConfig
        self.ev = ev
        self.dt_s = dt_s
        self.keep_frames = bool(frames)
        """Whether the animation's frames are collected (``frames``): only a report written with its plots
        draws them, so a run scored for its figures alone skips them (a few per cent of a scored step)."""
        self._block: list[np.ndarray] = []
        self._block_t: list[int] = []
        self.states = 0
        self.first_t_ns: int | None = None
        self.first_time_s = 0.0
        self.last_time_s = 0.0
        self.ids: np.ndarray | None = None
        self.first_lengths: np.ndarray | None = None
        self.sut: int | None = None
        self._events_before: list[dict] = []
        # events the scores read
        self.collisions_all = 0
        self.sut_collisions: list[dict] = []
        self.sut_lane_changes: list[dict] = []
        self.challenges: list[dict] = []
        """The challenge layer's events (``evoscen/challenge``: onsets, then the run's weight; docs/challenges.md)."""
        # carried between blocks
        self._prev_lc: np.ndarray | None = None
        self._accel_tail: np.ndarray | None = None
        self._rear_last = -1
        self._open: _Exposure | None = None
        self.changes = SutLaneChanges()
        self.collisions = SutCollisions(self.sut_collisions)  # their kinds and scenes
        # reductions
        self.exposures: list[dict] = []
        self._headway_run = 0  # states of the tailgating condition held unbroken up to the last state seen
        self.n = {key: 0 for key in ("danger", "front", "rear_conflict", "rear_danger", "rear_only", "attributed",
                                     "drac_sut", "drac_follower", "drac_follower_att", "in_view", "cut_in",
                                     "cut_in_only", "beside", "beside_only", "headway", "headway_only")}
        self.speed_sum = 0.0
        # the comparative score's progress reference (docs/evaluation.md §10): per state the mean
        # speed of the other vehicles in the SUT's view (v_max_mps with none in view), summed
        self.ref_speed_sum = 0.0
        self.ref_empty_states = 0
        self.min_ttc = math.inf
        self.min_accel = math.inf
        self.min_f_ttc = math.inf
        self.min_f_ttc_att = math.inf
        self.any_att = False
        self.min_f_accel = math.inf
        self.any_follower = False
        self.max_drac_sut = -math.inf
        self.max_drac_f = -math.inf
        self.min_cut_in_gap = math.inf
        # surrogate-safety profile per side: states below the SSM TTC threshold, their sum of
        # (threshold - TTC), TTC and DRAC episodes; the counterpart of the last state of the
        # previous block while it was below (above) the threshold, else -1
        self.ssm = {side: {"ttc_states": 0, "tit_sum_s": 0.0, "ttc_episodes": 0, "drac_episodes": 0}
                    for side in SSM_SIDES}
        self._ssm_last = {(side, m): -1 for side in SSM_SIDES for m in ("ttc", "drac")}
        self.min_beside_gap = math.inf
        self.windows: dict[str, list[int]] = {"lane_changes": [], "accel_decel": [], "exposures": []}
        # traffic around the SUT (report's "traffic"): per traffic window the sum of the per-state
        # counts and the time of its first state; the run's sum and its states with no BV near
        self.traffic_window_states: int | None = None
        self.traffic_window_sums: list[int] = []
        self.traffic_window_t0: list[float] = []
        self.traffic_sum = 0
        self.traffic_empty = 0
        # plots
        self.plots = PlotSeries()
        self.frames = FrameSeries()  # the animation's (evoscen_eval.scoring.animation)
        self._worst_sev = -math.inf
        self.worst_scene: Scene | None = None
        self._finished = False

    # ------------------------------------------------------------------ feeding

    def add_state(self, table: np.ndarray, t_ns: int, time_s: float | None = None) -> None:
        """One world state: the world table's rows ``[V, F]`` (float64, F = the contract's fields),
        its stamp and its time in seconds (default ``t_ns * 1e-9``, as :class:`RunData` has it)."""
        time_s = int(t_ns) * 1e-9 if time_s is None else float(time_s)
        if self._finished:
            raise ValueError("the stream has been finished")
        if self.ids is None:
            roles = table[:, _F["role"]]
            suts = np.flatnonzero(roles == C.ROLE_SUT)
            if len(suts) != 1:
                raise ValueError(f"the world table has {len(suts)} vehicles with role 1 (SUT), expected exactly 1")
            self.ids = table[:, _F["id"]].astype(np.int64)
            self.first_lengths = table[:, _F["length"]].copy()  # the BVs per class (report's run section)
            self.sut = int(suts[0])
            self.first_t_ns = int(t_ns)
            self.first_time_s = time_s
            pending, self._events_before = self._events_before, []
            self.add_events(pending)
        elif table.shape[0] != self.ids.shape[0]:
            raise ValueError(f"world table of {table.shape[0]} vehicles at t = {t_ns} ns, "
                             f"the run started with {self.ids.shape[0]}")
        if self.dt_s is None and self.states == 1:
            self.dt_s = (int(t_ns) - self.first_t_ns) * 1e-9
        self._block.append(np.array(table, dtype=np.float64))
        self._block_t.append(time_s)
        self.last_time_s = time_s
        self.states += 1
        if len(self._block) == BLOCK_STATES:
            self._reduce_block()

    def add_events(self, events) -> None:  # iterable of event dicts
        """Event dicts (``/evoscen/events``); the scores read collisions and the SUT's lane changes."""
        for event in events:
            name = event.get("name")
            if name == C.EVENT_CHALLENGE:
                self.challenges.append(dict(event))
                continue
            if name not in (C.EVENT_COLLISION, C.EVENT_LANE_CHANGE):
                continue
            if self.ids is None:
                self._events_before.append(dict(event))
                continue
            sut_id = int(self.ids[self.sut])
            ids = event.get("ids", [])
            if name == C.EVENT_COLLISION:
                self.collisions_all += 1
                if sut_id in ids:
                    self.sut_collisions.append(dict(event))
            elif ids and ids[0] == sut_id:
                self.sut_lane_changes.append(dict(event))

    # ------------------------------------------------------------------ one block

    def _reduce_block(self) -> None:
        if not self._block:
            return
        ev, sut = self.ev, self.sut
        dt = self.dt_s if self.dt_s is not None else 0.1
        tables = np.stack(self._block)  # [n, V, F]
        times = np.asarray(self._block_t, dtype=np.float64)
        self._block, self._block_t = [], []
        n = tables.shape[0]
        k0 = self.states - n
        ks = np.arange(k0, k0 + n)
        c = {f: tables[:, :, j] for f, j in _F.items()}
        rows = np.arange(n)
        s, d, v, a, length, width = c["s"], c["d"], c["speed"], c["accel"], c["length"], c["width"]

        # --- per-state quantities of the SUT (evoscen_sim.danger.safety, row by row)
        ttc = sut_ttc(s, d, v, length, width, sut)
        speed, accel, lane, lc_sut = v[:, sut], a[:, sut], c["lane"][:, sut], c["lane_change"][:, sut]
        follower, f_ttc = follower_ttc(s, d, v, length, width, sut)
        has_f = follower >= 0
        f_idx = np.maximum(follower, 0)
        f_accel = np.where(has_f, a[rows, f_idx], 0.0)
        attributed = self._attributed(lc_sut, ks, attribution_steps(ev.rear_attribution_s, dt))
        _, f_gap = sut_follower(s, d, length, width, sut)
        f_speed = np.where(has_f, v[rows, f_idx], np.nan)
        thw = follower_headway(f_gap, f_speed)
        leader, gap = sut_leader(s, d, length, width, sut)
        l_speed = np.where(leader >= 0, v[rows, np.maximum(leader, 0)], np.nan)
        drac_sut = drac(gap, speed, l_speed)
        cut_j, cut_gap = cut_in_gap(s, d, length, width, c["lane"], c["target_lane"], c["lane_change"], sut)
        beside_j, beside_g = beside_gap(s, length, c["lane"], c["target_lane"], c["lane_change"], sut)
        terms, self._headway_run = danger_terms(
            ev, dt, ttc=ttc, sut_accel=accel, drac_sut=drac_sut, follower_ttc_s=f_ttc, follower_accel=f_accel,
            follower_thw_s=thw, attributed=attributed, leader_gap_m=gap, sut_speed=speed, leader_speed=l_speed,
            cut_in_gap_m=cut_gap, beside_gap_m=beside_g, headway_run=self._headway_run)
        front, rear_conflict, rear_danger = terms.front, terms.rear_conflict, terms.rear
        cut_in, beside, tailgate, danger = terms.cut_in, terms.beside, terms.tailgating, terms.danger
        drac_f = drac(f_gap, f_speed, speed)
        ds = s - s[:, sut:sut + 1]
        in_view = (ds >= -ev.view_behind_m) & (ds <= ev.view_ahead_m)
        in_view[:, sut] = False
        near = np.abs(ds) <= TRAFFIC_RANGE_M  # within the state: a shift of every s alike changes nothing
        near[:, sut] = False
        bvs_near = near.sum(axis=1)  # [n] BVs within TRAFFIC_RANGE_M of the SUT

        # --- lane-change starts of every vehicle (a column becoming non-zero or switching sign)
        lc = c["lane_change"]
        prev = np.vstack([np.zeros((1, lc.shape[1])) if self._prev_lc is None else self._prev_lc[None], lc[:-1]])
        starts = (lc != 0) & (lc != prev)
        self._prev_lc = lc[-1].copy()

        ad_count = self._accel_activity_counts(a, dt)

        # --- counts and extremes
        nb = self.n
        nb["danger"] += int(danger.sum())
        nb["front"] += int(front.sum())
        nb["rear_conflict"] += int(rear_conflict.sum())
        nb["rear_danger"] += int(rear_danger.sum())
        nb["rear_only"] += int((rear_danger & ~front).sum())
        nb["cut_in"] += int(cut_in.sum())
        nb["cut_in_only"] += int((cut_in & ~front & ~rear_danger).sum())
        self.min_cut_in_gap = min(self.min_cut_in_gap, float(cut_gap.min()))
        nb["beside"] += int(beside.sum())
        nb["beside_only"] += int((beside & ~front & ~rear_danger & ~cut_in).sum())
        self.min_beside_gap = min(self.min_beside_gap, float(beside_g.min()))
        nb["headway"] += int(tailgate.sum())
        nb["headway_only"] += int((tailgate & ~front & ~rear_danger & ~cut_in & ~beside).sum())
        nb["attributed"] += int(attributed.sum())
        nb["drac_sut"] += int((drac_sut > ev.drac_threshold_mps2).sum())
        nb["drac_follower"] += int((drac_f > ev.drac_threshold_mps2).sum())
        nb["drac_follower_att"] += int(((drac_f > ev.drac_threshold_mps2) & attributed).sum())
        nb["in_view"] += int(in_view.sum())
        self.speed_sum += float(speed.sum())
        n_view = in_view.sum(axis=1)
        v_view = np.where(in_view, v, 0.0).sum(axis=1)
        self.ref_speed_sum += float(np.where(n_view > 0, v_view / np.maximum(n_view, 1), ev.v_max_mps).sum())
        self.ref_empty_states += int((n_view == 0).sum())
        self.min_ttc = min(self.min_ttc, float(ttc.min()))
        self.min_accel = min(self.min_accel, float(accel.min()))
        self.min_f_ttc = min(self.min_f_ttc, float(f_ttc.min()))
        if attributed.any():
            self.any_att = True
            self.min_f_ttc_att = min(self.min_f_ttc_att, float(f_ttc[attributed].min()))
        if has_f.any():
            self.any_follower = True
            self.min_f_accel = min(self.min_f_accel, float(f_accel[has_f].min()))
        self.max_drac_sut = max(self.max_drac_sut, float(drac_sut.max()))
        self.max_drac_f = max(self.max_drac_f, float(drac_f.max()))
        self._ssm_block("front", ttc, drac_sut, leader)
        self._ssm_block("rear", f_ttc, drac_f, follower)

        # --- exposures (maximal runs of dangerous states, continued across blocks); the severity and
        # the rule, measure and vehicle behind each state: evoscen_eval.scoring.exposure_rules
        with np.errstate(divide="ignore", invalid="ignore"):
            headway = gap / np.maximum(speed, 1e-3)
        rq = RuleInputs(ttc=ttc, accel=accel, drac_sut=drac_sut, leader=leader, follower=follower,
                        follower_ttc=f_ttc, follower_accel=f_accel, follower_thw=thw, cut_in_vehicle=cut_j,
                        cut_in_gap=cut_gap, beside_vehicle=beside_j, beside_gap=beside_g,
                        beside_length_sum=length[rows, np.maximum(beside_j, 0)] + length[:, sut], headway=headway)
        severity = rule_severity(ev, terms, rq)
        exposure_starts = self._exposures_of_block(k0, times, tables, danger, severity, terms, rq)

        # --- complexity windows (state k in window k // W; only whole windows count in the end)
        self._complexity_windows(ks, starts.sum(axis=1), ad_count, exposure_starts)

        self._traffic_windows(ks, times, bvs_near, dt)

        # --- the SUT's lane changes: interaction sums and PET windows
        self.changes.add_block(sut, self.ids, lc_sut, ks, c, in_view, starts, v, a,
                               attribution_steps(ev.rear_attribution_s, dt))

        # --- plots
        self.plots.add_block(ks, times, speed, lane, ttc, bvs_near)
        if self.keep_frames:
            self.frames.add_block(ks, times, tables, self.ids, sut)
        self.collisions.add_block(k0, ks, tables, times, lc, self.ids, sut, dt)

    def _accel_activity_counts(self, a: np.ndarray, dt: float) -> np.ndarray:
        """AD of each state of the block: the vehicles whose |acceleration| is above the threshold
        (the trailing mean for ``smoothed``, :func:`evoscen_eval.scoring.metrics.activity_accel`, its tail kept
        across blocks)."""
        ev = self.ev
        tail = self._accel_tail if self._accel_tail is not None else np.zeros((0, a.shape[1]))
        block = np.vstack([tail, a])
        act = activity_accel(block, dt, ev.accel_activity_form, ev.accel_activity_window_s)[tail.shape[0]:]
        keep = max(1, int(round(ev.accel_activity_window_s / dt))) - 1 if ev.accel_activity_form == "smoothed" else 0
        self._accel_tail = block[max(0, block.shape[0] - keep):] if keep else None
        return (np.abs(act) > ev.accel_activity_mps2).sum(axis=1)

    def _exposures_of_block(self, k0: int, times: np.ndarray, tables: np.ndarray, danger: np.ndarray,
                            severity: np.ndarray, terms, rq: RuleInputs) -> list[int]:
        """Add the block's dangerous states to the exposures (maximal runs of dangerous states, continued
        across blocks; the worst state by ``severity``, the rules behind each state): the states where
        an exposure starts."""
        ev, sut, n = self.ev, self.sut, danger.shape[0]
        ttc, accel = rq.ttc, rq.accel
        rear_danger, cut_in, beside, tailgate = terms.rear, terms.cut_in, terms.beside, terms.tailgating
        run_starts, run_ends = exposure_runs(danger)
        if self._open is not None and not (run_starts.size and run_starts[0] == 0):
            self._close_exposure(k0)
        exposure_starts = []
        for r0, r1 in zip(run_starts.tolist(), run_ends.tolist()):
            if r0 == 0 and self._open is not None:
                x = self._open
            else:
                x = self._open = _Exposure(start=k0 + r0, start_time_s=float(times[r0]), rules=ExposureRules())
                exposure_starts.append(k0 + r0)
            seg = slice(r0, r1)
            x.min_ttc = min(x.min_ttc, float(ttc[seg].min()))
            x.min_accel = min(x.min_accel, float(accel[seg].min()))
            m = int(np.argmax(severity[seg]))
            if severity[r0 + m] > x.severity:
                x.severity, x.worst = float(severity[r0 + m]), k0 + r0 + m
            x.rear_states += int(rear_danger[seg].sum())
            x.cut_in_states += int(cut_in[seg].sum())
            x.beside_states += int(beside[seg].sum())
            x.headway_states += int(tailgate[seg].sum())
            x.rules.add(seg, k0, times, ev, terms, rq, self.ids)
            if severity[r0 + m] > self._worst_sev:
                self._worst_sev = float(severity[r0 + m])
                self.worst_scene = scene_of(tables, times, r0 + m, k0 + r0 + m, self.ids, sut)
                self.worst_scene.sut_ttc, self.worst_scene.sut_accel = float(ttc[r0 + m]), float(accel[r0 + m])
            if r1 < n:
                self._close_exposure(k0 + r1)
        return exposure_starts

    def _complexity_windows(self, ks: np.ndarray, lane_change_starts: np.ndarray, ad_count: np.ndarray,
                            exposure_starts: list[int]) -> None:
        """Add the block's per-state counts to the complexity windows (state k in window k // W; only
        whole windows count in the end)."""
        ev = self.ev
        W = ev.window_steps
        w_idx = ks // W
        n_w = int(w_idx[-1]) + 1
        for key, per_state in (("lane_changes", lane_change_starts), ("accel_decel", ad_count)):
            sums = np.bincount(w_idx - w_idx[0], weights=per_state, minlength=n_w - int(w_idx[0]))
            self._add_windows(key, int(w_idx[0]), sums)
        e_w = np.bincount(np.asarray(exposure_starts, dtype=np.int64) // W - int(w_idx[0]),
                          minlength=n_w - int(w_idx[0]))
        self._add_windows("exposures", int(w_idx[0]), e_w)

    def _traffic_windows(self, ks: np.ndarray, times: np.ndarray, bvs_near: np.ndarray, dt: float) -> None:
        """Traffic around the SUT: per-window sums of the per-state counts (integers, so any block size
        gives the same), the time of each window's first state, the states with none."""
        if self.traffic_window_states is None:
            self.traffic_window_states = traffic_window_states(dt)
        TW = self.traffic_window_states
        t_idx = ks // TW
        t_sums = np.bincount(t_idx - t_idx[0], weights=bvs_near, minlength=int(t_idx[-1] - t_idx[0]) + 1)
        for i, value in enumerate(t_sums.tolist()):
            w = int(t_idx[0]) + i
            if w < len(self.traffic_window_sums):
                self.traffic_window_sums[w] += int(value)
            else:
                self.traffic_window_sums.append(int(value))
                self.traffic_window_t0.append(float(times[int(np.argmax(t_idx == w))]))
        self.traffic_sum += int(bvs_near.sum())
        self.traffic_empty += int((bvs_near == 0).sum())

    def _ssm_block(self, side: str, ttc: np.ndarray, drac_v: np.ndarray, other: np.ndarray) -> None:
        """Add a block's states to one side's surrogate-safety sums (``other``: the counterpart's
        index per state, -1 for none; a TTC below or a DRAC above its threshold has one)."""
        acc, thr = self.ssm[side], self.ev.ssm_ttc_threshold_s
        below = ttc < thr
        acc["ttc_states"] += int(below.sum())
        acc["tit_sum_s"] += float((thr - ttc[below]).sum())
        acc["ttc_episodes"] += self._episodes((side, "ttc"), below, other)
        acc["drac_episodes"] += self._episodes((side, "drac"), drac_v > self.ev.drac_threshold_mps2, other)

    def _episodes(self, key: tuple[str, str], on: np.ndarray, other: np.ndarray) -> int:
        """Episodes starting in this block: states ``on`` whose previous state was not, or was with
        another counterpart (the previous block's last state carried in ``_ssm_last``)."""
        cp = np.where(on, other, -1)
        prev = np.concatenate(([self._ssm_last[key]], cp[:-1]))
        self._ssm_last[key] = int(cp[-1])
        return int((on & (cp != prev)).sum())

    def _attributed(self, lc_sut: np.ndarray, ks: np.ndarray, after: int) -> np.ndarray:
        """:func:`evoscen_sim.danger.safety.rear_attributed`, continued from the previous block."""
        mode = self.ev.rear_conflicts
        if mode == "all":
            return np.ones(ks.shape[0], dtype=bool)
        if mode == "none":
            return np.zeros(ks.shape[0], dtype=bool)
        if mode != "after_lane_change":
            from evoscen_sim.danger.safety import rear_attributed

            rear_attributed(lc_sut, mode, after)  # raises the error naming the modes
        last = np.maximum(np.maximum.accumulate(np.where(lc_sut != 0, ks, -1)), self._rear_last)
        self._rear_last = int(last[-1])
        return (last >= 0) & (ks - last <= after)

    def _close_exposure(self, end: int) -> None:
        x, self._open = self._open, None
        self.exposures.append({
            "start_state": x.start, "end_state": end, "states": end - x.start, "start_time_s": x.start_time_s,
            "open_at_end": False, "min_ttc_s": _finite(x.min_ttc), "min_accel_mps2": x.min_accel,
            "worst_state": x.worst, "severity": x.severity, "rear_states": x.rear_states,
            "cut_in_states": x.cut_in_states, "beside_states": x.beside_states, "headway_states": x.headway_states,
            "rule_states": dict(x.rules.rule_states), "rules": x.rules.records(),
        })

    def _add_windows(self, key: str, first: int, sums: np.ndarray) -> None:
        lst = self.windows[key]
        for i, value in enumerate(sums.tolist()):
            w = first + i
            if w < len(lst):
                lst[w] += int(value)
            else:
                lst.append(int(value))

    # ------------------------------------------------------------------ the end

    def finish(self) -> None:
        """Reduce the last (partial) block and close what is still open; idempotent."""
        if self._finished:
            return
        if self.ids is None:
            raise ValueError("no world state (/evoscen/world) in the run")
        self._reduce_block()
        K = self.states
        if self._open is not None:
            self._close_exposure(K)
            self.exposures[-1]["open_at_end"] = True
        self.changes.close(K)
        self.collisions.finish(K, self.ids, self.sut, self.dt_s if self.dt_s is not None else 0.1)
        self._finished = True

    def plot_data(self, lane_segments: np.ndarray | None = None) -> PlotData:
        """The plots' inputs (after :meth:`finish`)."""
        self.finish()
        return PlotData(states=self.states, **self.plots.timeline_fields(),
                        collision_scenes=dict(self.collisions.scenes),
                        worst_scene=self.worst_scene, lane_segments=lane_segments, frames=self.frames)

    @property
    def collision_kinds(self) -> dict[int, str]:
        """What each SUT collision was, by its index in ``sut_collisions`` (:mod:`evoscen_eval.scoring.sut_collisions`)."""
        return self.collisions.kinds

    @property
    def finished_changes(self) -> list:  # [SutLaneChange]
        """The SUT's lane changes whose PET window has ended, in order after :meth:`finish`."""
        return self.changes.finished

    @property
    def duration_s(self) -> float:
        """Simulated time from the first state to the last (s)."""
        return self.last_time_s - self.first_time_s


def traffic_window_states(dt_s: float) -> int:
    """States per traffic window: :data:`TRAFFIC_WINDOW_S` over the step (300 at 0.1 s), at least 1."""
    return max(1, int(round(TRAFFIC_WINDOW_S / dt_s)))


def activity_accel(accel: np.ndarray, dt_s: float, form: str, window_s: float) -> np.ndarray:
    """The ``[K, V]`` acceleration AD compares with its threshold (docs/evaluation.md, "AD").

    ``literal``: the per-state acceleration as recorded. ``smoothed``: at state k the mean of
    the last ``n = max(1, round(window_s / dt_s))`` states' accelerations (k−n+1..k; fewer at
    the start of the run) — the speed change over the window divided by its length, so
    per-step noise that averages out (Krauss dawdling: i.i.d. speed draws just below the
    desired speed) is not counted as activity, while a manoeuvre (braking or accelerating
    for a second or more) is.
    """
    a = np.asarray(accel, dtype=float)
    if form == "literal":
        return a
    if form != "smoothed":
        raise ValueError(f"accel_activity_form {form!r}: expected 'smoothed' or 'literal'")
    n = max(1, int(round(window_s / dt_s)))
    csum = np.cumsum(np.vstack([np.zeros((1,) + a.shape[1:]), a]), axis=0)
    k = np.arange(1, a.shape[0] + 1)
    lo = np.maximum(k - n, 0)
    count = (k - lo).reshape((-1,) + (1,) * (a.ndim - 1))
    return (csum[k] - csum[lo]) / count


def _finite(x: float) -> float | None:
    """JSON has no infinity: ``None`` for a non-finite number."""
    return float(x) if math.isfinite(x) else None
