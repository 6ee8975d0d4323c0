"""The challenge layer: the hard braking of the SUT's leader, drawn from a tilted distribution and weighted
back (docs/challenges.md).

Under ``challenge.mode: naturalistic`` or ``nade`` the simulation, not the BV drivers, runs the onset process
of the SUT's leader's hard braking, for whatever drives the leader (learned, level-0 or rule-based BVs,
trucks). Its naturalistic form p is the learned BVs' rule (docs/learned-bvs.md, "Hard braking"): while a BV
is the SUT's leader (:func:`evoscen_sim.danger.safety.sut_leader_ttc_state`) within a bumper gap of
:data:`VIEW_M`, not changing lanes and faster than the minimum speed, onsets come as a Poisson process in the
distance it drives so, at ``per_1000km``; an onset brakes at a deceleration and for a duration drawn
uniformly from their ranges, and ends early at the minimum speed.

``nade`` tilts the onset rate by a factor m(state) ≥ 1 that grows as the SUT's time headway to that leader
shrinks (:class:`Tilt`): the onset is made likelier where it is critical, the decelerations and durations
keep their naturalistic draws. A step is the unit of the process: a leader driving ds metres in a step under
factor m has an onset in it with probability 1 − e^(−m ds/μ) (μ the mean distance between onsets; m = 1
under p), at most one. Each run carries its likelihood ratio p/q, the product over its steps of p/q of what
happened: e^((m − 1) ds/μ) for a step without an onset, (1 − e^(−ds/μ)) / (1 − e^(−m ds/μ)) for a step with
one. The mean over runs of score × weight estimates the naturalistic mean without bias (docs/challenges.md,
"The estimator").

The process keeps one exponential clock per vehicle in tilted distance (what is left before its next onset),
drawn afresh after each onset; one generator (the scenario's ``challenge`` stream) draws, in order of use:
every vehicle's first clock at construction, then at each onset its deceleration, duration and next clock. The world calls :meth:`apply`
with the commands of every step, so both runners draw the same.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from evoscen_contract.contract import ROLE_SUT
from .safety import sut_leader_ttc_state
from evoscen_sim.physics.vehicle import accel_to_throttle

VIEW_M = 100.0
"""An onset happens only to the SUT's leader within this bumper-to-bumper gap (m): the learned BVs' rule
(``evoscen_bv.learned.HARD_BRAKE_VIEW_M``, the same [choice])."""


@dataclass(frozen=True)
class OnsetProcess:
    """The naturalistic onset process p (``models.learned.hard_brake_*``)."""

    per_1000km: float = 11.8
    decel_mps2: tuple[float, float] = (4.0, 7.0)
    duration_s: tuple[float, float] = (1.0, 3.0)
    min_speed_mps: float = 10.0

    @property
    def mean_m(self) -> float:
        """Mean distance between onsets (m)."""
        return 1.0e6 / self.per_1000km


@dataclass(frozen=True)
class Tilt:
    """q/p of an onset as a function of the SUT's time headway h to the leader: ``max_multiplier`` at h ≤
    ``headway_full_s``, 1 at h ≥ ``headway_none_s``, linear in between (``challenge.*``)."""

    max_multiplier: float = 300.0
    headway_full_s: float = 1.0
    headway_none_s: float = 2.0

    def multiplier(self, headway_s: float) -> float:
        if headway_s >= self.headway_none_s:
            return 1.0
        if headway_s <= self.headway_full_s:
            return self.max_multiplier
        frac = (self.headway_none_s - headway_s) / (self.headway_none_s - self.headway_full_s)
        return 1.0 + (self.max_multiplier - 1.0) * frac


@dataclass(frozen=True)
class Onset:
    """One hard-braking onset: the world index of the braking vehicle, its deceleration (m/s², > 0) as
    applied, its duration (s), the factor q/p of its step and the SUT's time headway then."""

    vehicle: int
    decel_mps2: float
    duration_s: float
    multiplier: float
    headway_s: float


class LeaderBraking:
    """The onset process of the SUT's leader over the ``n`` vehicles of a world (module docstring).

    ``tilt`` None: the naturalistic process (every factor 1, weight 1). ``max_decel_mps2`` per world
    index caps the applied deceleration (a truck brakes at most at its driver's limit; inf: no cap).
    """

    def __init__(self, n: int, process: OnsetProcess, tilt: Tilt | None, rng: np.random.Generator,
                 max_decel_mps2: np.ndarray | None = None) -> None:
        self.process = process
        self.tilt = tilt
        self.rng = rng
        self.mean_m = process.mean_m
        self.to_go = rng.exponential(self.mean_m, size=n)
        """Per vehicle: tilted distance left before its next onset."""
        self.until_step = np.full(n, -1, dtype=np.int64)
        self.decel = np.zeros(n)
        self.max_decel = np.full(n, np.inf) if max_decel_mps2 is None else np.asarray(max_decel_mps2, dtype=float)
        self.log_weight = 0.0
        """log p/q of every draw so far."""
        self.distance_m = 0.0
        """Distance the SUT's leaders drove under the process (the exposure), m."""
        self.onsets: list[tuple[int, Onset]] = []
        """(step, onset) of every onset so far."""

    def apply(self, world, throttle: np.ndarray) -> tuple[np.ndarray, list[Onset]]:
        """The commands of ``world``'s current step with the braking of the episodes in progress (a
        braking vehicle's throttle at most its deceleration's); advances the clocks and starts onsets."""
        p = self.process
        step, dt = int(world.step_index), float(world.dt_s)
        v = world.v
        self.until_step[v <= p.min_speed_mps] = -1  # never into a standstill
        braking = self.until_step > step
        new: list[Onset] = []
        sut = int(np.flatnonzero(world.role == ROLE_SUT)[0])
        leader, _ = sut_leader_ttc_state(world.s, world.d, v, world.length, world.width, sut)
        if leader >= 0 and world.role[leader] != ROLE_SUT and not braking[leader] \
                and v[leader] > p.min_speed_mps and world.lane_change[leader] == 0:
            gap = float(world.s[leader] - world.s[sut]) - 0.5 * float(world.length[leader] + world.length[sut])
            if gap <= VIEW_M:
                headway = gap / float(v[sut]) if v[sut] > 0.0 else math.inf
                onset = self._advance(leader, float(v[leader]) * dt, headway, step, dt)
                if onset is not None:
                    new.append(onset)
                    braking[leader] = True
        if not braking.any():
            return throttle, new
        out = np.array(throttle, dtype=float)
        out[braking] = np.minimum(out[braking], accel_to_throttle(-self.decel[braking], world.vehicle))
        return out, new

    def _advance(self, k: int, ds: float, headway: float, step: int, dt: float) -> Onset | None:
        """Vehicle ``k`` drives ``ds`` metres as the SUT's leader at ``headway``: its clock runs m times as
        fast; the step ends in an onset when it runs out (then a fresh clock). The weight takes the step's
        factor: p/q of no onset, exp((m − 1) ds / μ), or of an onset, (1 − e^(−ds/μ)) / (1 − e^(−m ds/μ))."""
        m = 1.0 if self.tilt is None else self.tilt.multiplier(headway)
        self.to_go[k] -= m * ds
        self.distance_m += ds
        if self.to_go[k] > 0.0:
            if m != 1.0:
                self.log_weight += (m - 1.0) * ds / self.mean_m
            return None
        ratio = 1.0 if m == 1.0 else math.expm1(-m * ds / self.mean_m) / math.expm1(-ds / self.mean_m)  # q/p
        if ratio != 1.0:
            self.log_weight -= math.log(ratio)
        p = self.process
        decel = float(self.rng.uniform(*p.decel_mps2))
        duration = float(self.rng.uniform(*p.duration_s))
        self.to_go[k] = self.rng.exponential(self.mean_m)  # a fresh clock: one onset per step at most
        applied = min(decel, float(self.max_decel[k]))
        self.decel[k] = applied
        self.until_step[k] = step + max(1, int(round(duration / dt)))
        onset = Onset(k, applied, duration, float(ratio), float(headway))
        self.onsets.append((step, onset))
        return onset

    def entered(self, vehicles) -> None:
        """``vehicles`` entered the traffic window anew (their slots reused): an episode in progress ends."""
        self.until_step[np.asarray(vehicles, dtype=np.int64)] = -1

    @property
    def weight(self) -> float:
        """The likelihood ratio p/q of the run so far."""
        return math.exp(self.log_weight)


def build_challenge(mode: str, tilt: Tilt, process: OnsetProcess, world, rng: np.random.Generator,
                    truck_max_decel_mps2: float = math.inf) -> LeaderBraking | None:
    """The layer of ``challenge.mode`` ``mode`` for ``world`` (None under ``none``; ``tilt`` used under ``nade``);
    the trucks of a ``highd`` world brake at most at ``truck_max_decel_mps2``."""
    if mode == "none":
        return None
    cap = np.full(world.n, np.inf)
    makeup = getattr(getattr(world, "window", None), "makeup", None)
    if makeup is not None:
        cap[np.asarray(makeup.truck, dtype=bool)] = truck_max_decel_mps2
    return LeaderBraking(world.n, process, tilt if mode == "nade" else None, rng, cap)
