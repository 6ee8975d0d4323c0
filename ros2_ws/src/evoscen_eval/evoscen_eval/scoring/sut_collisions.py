"""The SUT's collisions as :class:`~evoscen_eval.scoring.streaming.ScoreStream` meets their states block by
block: what each collision was (:data:`COLLISION_KINDS`: who was changing lanes within
:data:`COLLISION_LOOKBACK_S` up to the contact, else who struck whom) and the scenes of the first
:data:`MAX_SNAPSHOTS`. A collision event may arrive after its state, so the previous block is kept
for both."""

from __future__ import annotations

import numpy as np

from evoscen_contract import contract as C

from evoscen_eval.scoring.plot_inputs import Scene, scene_of

MAX_SNAPSHOTS = 10
"""Collision scenes kept at most (the report lists every collision)."""
COLLISION_LOOKBACK_S = 2.0
"""How far back a vehicle's lane change makes it "changing lanes" at a collision (s)."""
COLLISION_KINDS = ("sut_cut_in", "other_cut_in", "both_changing", "sut_rear_end", "rear_ended_by_other")
"""What a SUT collision was (docs/evaluation.md §3.4); "unknown" if its state was not seen."""

_S = C.WORLD_FIELDS.index("s")


class SutCollisions:
    """The kinds and scenes of the SUT's collisions ``events`` (the stream's list, filled as the
    events come): ``kinds`` by index in ``events``, ``scenes`` by state."""

    def __init__(self, events: list[dict]) -> None:
        self.events = events
        self.kinds: dict[int, str] = {}
        self.scenes: dict[int, Scene] = {}
        self._prev_scene_block: tuple[int, np.ndarray, np.ndarray] | None = None
        self._last_lc = None  # [V]: the latest state with each vehicle's lane_change non-zero (-1: none)
        self._prev_lc_block: tuple[int, np.ndarray, np.ndarray] | None = None  # (k0, tables, last-lc rows)

    def add_block(self, k0: int, ks: np.ndarray, tables: np.ndarray, times: np.ndarray, lc: np.ndarray,
                  ids: np.ndarray, sut: int, dt_s: float) -> None:
        """A block of states ``ks`` (from ``k0``; ``lc``: every vehicle's ``lane_change``), the
        vehicles' ``ids``, the SUT's index and the step."""
        self._collision_scenes(k0, tables, times, ids, sut)
        self._prev_scene_block = (k0, tables, times)
        last = np.maximum.accumulate(np.where(lc != 0, ks[:, None], -1), axis=0)
        if self._last_lc is not None:
            last = np.maximum(last, self._last_lc)
        self._last_lc = last[-1].copy()
        self._classify_collisions(k0, tables, last, ids, sut, dt_s)
        self._prev_lc_block = (k0, tables, last)

    def finish(self, end: int, ids: np.ndarray, sut: int, dt_s: float) -> None:
        """The run ended at state ``end``: collisions stamped past the last state, as at the last state."""
        if self._prev_scene_block is not None:  # collisions stamped past the last state: the last state's scene
            k0, tables, times = self._prev_scene_block
            for event in self.events[:MAX_SNAPSHOTS]:
                k = min(int(event["step"]), end - 1)
                if k not in self.scenes and k0 <= k:
                    self.scenes[k] = scene_of(tables, times, k - k0, k, ids, sut)
        self._prev_scene_block = None
        if self._prev_lc_block is not None:  # collisions stamped past the last state: as at the last state
            self._classify_collisions(*self._prev_lc_block, ids, sut, dt_s, clamp=end - 1)
        self._prev_lc_block = None

    def _classify_collisions(self, k0: int, tables: np.ndarray, last: np.ndarray, ids: np.ndarray, sut: int,
                             dt_s: float, clamp: int | None = None) -> None:
        """What each SUT collision whose state is in this block or the previous one was: who was
        changing lanes (``lane_change`` non-zero within :data:`COLLISION_LOOKBACK_S` up to the
        state) and, if neither, who struck whom (the vehicle behind, by centre)."""
        n_back = int(np.floor(COLLISION_LOOKBACK_S / dt_s + 1e-9))
        blocks = [(k0, tables, last)]
        if self._prev_lc_block is not None:
            blocks.append(self._prev_lc_block)
        sut_id = int(ids[sut])
        for i, event in enumerate(self.events):
            if i in self.kinds:
                continue
            k = int(event["step"]) if clamp is None else min(int(event["step"]), clamp)
            others = [j for j in event.get("ids", []) if j != sut_id]
            found = np.flatnonzero(ids == others[0]) if others else []
            for b0, b_tables, b_last in blocks:
                if b0 <= k < b0 + b_tables.shape[0] and len(found):
                    r, o = k - b0, int(found[0])
                    sut_lc = b_last[r, sut] >= k - n_back
                    oth_lc = b_last[r, o] >= k - n_back
                    if sut_lc or oth_lc:
                        kind = "both_changing" if sut_lc and oth_lc else ("sut_cut_in" if sut_lc else "other_cut_in")
                    else:
                        behind = b_tables[r, sut, _S] < b_tables[r, o, _S]
                        kind = "sut_rear_end" if behind else "rear_ended_by_other"
                    self.kinds[i] = kind

    def _collision_scenes(self, k0: int, tables: np.ndarray, times: np.ndarray, ids: np.ndarray, sut: int) -> None:
        """The scenes of the first collisions whose states are in this block or the previous one
        (a collision event may arrive after its state)."""
        blocks = [(k0, tables, times)]
        if self._prev_scene_block is not None:
            blocks.append(self._prev_scene_block)
        for event in self.events[:MAX_SNAPSHOTS]:
            k = int(event["step"])
            for b0, b_tables, b_times in blocks:
                if b0 <= k < b0 + b_tables.shape[0] and k not in self.scenes:
                    self.scenes[k] = scene_of(b_tables, b_times, k - b0, k, ids, sut)
