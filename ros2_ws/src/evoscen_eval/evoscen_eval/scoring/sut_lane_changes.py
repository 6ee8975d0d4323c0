"""The SUT's lane changes as :class:`~evoscen_eval.scoring.streaming.ScoreStream` follows them block by
block: each change's interaction sums over its states and its PET window, which runs
``rear_attribution_s`` past the change's end, so it can outlive the change by blocks
(:func:`evoscen_eval.scoring.metrics.change_intervals`, :func:`evoscen_eval.scoring.metrics.lane_change_pet`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass
class SutLaneChange:
    """A SUT lane change ``[k0, k1)`` (k1 None while it lasts) with its PET and interaction sums."""

    k0: int
    value: float
    target: int
    v0: np.ndarray
    a0: np.ndarray
    k1: int | None = None
    # PET (docs/evaluation.md §3): running minimum, first of equal values
    pet_any: bool = False
    pet: float = math.inf
    pet_state: int | None = None
    pet_follower: int | None = None
    # interaction: in-view samples of the change
    dv_sum: float = 0.0
    da_sum: float = 0.0
    samples: int = 0
    seen: np.ndarray | None = None
    starts: np.ndarray | None = None


class SutLaneChanges:
    """The SUT's lane changes: those still open (the change or its PET window) and the finished ones."""

    def __init__(self) -> None:
        self.open: list[SutLaneChange] = []
        self.finished: list[SutLaneChange] = []

    def add_block(self, sut: int, ids: np.ndarray, lc_sut, ks, c, in_view, starts, v, a, after: int) -> None:
        """Open and close the SUT's lane changes (:func:`evoscen_eval.scoring.metrics.change_intervals`) and
        add this block's rows to each change's interaction sums and PET window (``sut``: the SUT's
        index, ``ids``: the vehicles' ids; ``after``: the states of the window past the change's end)."""
        k0 = int(ks[0])
        n = ks.shape[0]
        prev = self.open[-1].value if self.open and self.open[-1].k1 is None else 0.0
        for r in range(n):
            value = float(lc_sut[r])
            if value == prev:
                continue
            if self.open and self.open[-1].k1 is None:
                self.open[-1].k1 = k0 + r
            if value != 0.0:
                self.open.append(SutLaneChange(k0=k0 + r, value=value, target=int(c["target_lane"][r, sut]),
                                           v0=v[r].copy(), a0=a[r].copy(),
                                           seen=np.zeros(v.shape[1], dtype=bool),
                                           starts=np.zeros(v.shape[1], dtype=np.int64)))
            prev = value
        k_end_block = k0 + n
        still = []
        for ch in self.open:
            # interaction over the change's states [k0, k1)
            lo = max(ch.k0, k0) - k0
            hi = (min(ch.k1, k_end_block) if ch.k1 is not None else k_end_block) - k0
            if hi > lo:
                view = in_view[lo:hi]
                if view.any():
                    ch.dv_sum += float(np.abs(v[lo:hi] - ch.v0)[view].sum())
                    ch.da_sum += float(np.abs(a[lo:hi] - ch.a0)[view].sum())
                    ch.samples += int(view.sum())
                    ch.seen |= view.any(axis=0)
                ch.starts += starts[lo:hi].sum(axis=0)
            # PET over [k0, k1 + after)
            p_hi = (min(ch.k1 + after, k_end_block) if ch.k1 is not None else k_end_block) - k0
            if p_hi > lo:
                _pet_rows(ch, sut, ids, c, lo, p_hi, k0)
            if ch.k1 is not None and ch.k1 + after <= k_end_block:
                self.finished.append(ch)
            else:
                still.append(ch)
        self.open = still

    def close(self, end: int) -> None:
        """The run ended at state ``end``: every open change ends there; the finished ones in order."""
        for ch in self.open:
            if ch.k1 is None:
                ch.k1 = end
            self.finished.append(ch)
        self.open = []
        self.finished.sort(key=lambda ch: ch.k0)


def _pet_rows(ch: SutLaneChange, sut: int, ids: np.ndarray, c: dict, lo: int, hi: int, k0: int) -> None:
    """:func:`evoscen_eval.scoring.metrics.lane_change_pet` over rows ``[lo, hi)`` of the block."""
    s, d, v = c["s"][lo:hi], c["d"][lo:hi], c["speed"][lo:hi]
    length, width, lane = c["length"][lo:hi], c["width"][lo:hi], c["lane"][lo:hi]
    back = s[:, sut:sut + 1] - s
    cand = (back > 0.0) & (np.abs(d - d[:, sut:sut + 1]) < 0.5 * (width + width[:, sut:sut + 1])) \
        & (lane == ch.target)
    cand[:, sut] = False
    j = np.argmin(np.where(cand, back, np.inf), axis=1)
    rows = np.arange(hi - lo)
    has = cand[rows, j]
    gap = back[rows, j] - 0.5 * (length[rows, j] + length[:, sut])
    vj = v[rows, j]
    with np.errstate(divide="ignore", invalid="ignore"):
        pet = np.where(has & (vj > 0.0), np.maximum(gap, 0.0) / vj, np.inf)
    if k0 + lo == ch.k0:  # the window's first row: argmin's answer when every PET is infinite
        ch.pet_state, ch.pet_follower = ch.k0, int(ids[j[0]])
    if has.any():
        ch.pet_any = True
    m = int(np.argmin(pet))
    if pet[m] < ch.pet:
        ch.pet, ch.pet_state, ch.pet_follower = float(pet[m]), k0 + lo + m, int(ids[j[m]])
