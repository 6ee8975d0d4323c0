"""Learned background vehicles: the trained controller and decision policies, batched.

A :class:`LearnedDriver` drives a set of vehicles. Every step it

1. builds the car-following observation of every hosted vehicle (own lane, and the target
   lane during a lane change) and runs the controller once for all of them
   (:mod:`evoscen_bv.car_following`: throttle = min over leaders in view, and the
   free-road speed term);
2. every ``decision_interval_steps`` steps (``step_index % N == 0``; the rate of training),
   builds the grid Ω_d of the hosted vehicles not changing lanes and runs **one** batched
   forward pass for all of them (:class:`PolicyBank`), each row through the decision
   policy of its vehicle's code in the world (competitive, mutual, cooperative); then maps the output to keep/left/right and applies the rule
   constraints (:mod:`evoscen_bv.lane_change_decision`), so only executable requests reach the world.

Inference needs no torch: the exported weights (:class:`evoscen_bv.td3.NumpyActor`) run in a
compiled kernel (:class:`PolicyBank`), so the in-process runner and the BV node compute the
same floats.

The policy directory holds ``controller.npz``, ``mutual.npz`` (level-2 mutual),
``competitive.npz``, ``cooperative.npz`` (and ``level1_mutual.npz``), the ``training.yaml``
they were trained with, and a model card per policy. The shipped directory is
``share/evoscen_bv/policies``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
from evoscen_contract.contract import POLICY_CODES, ROLE_SUT, SOCIAL_POLICIES
from evoscen_sim.config.scenario_config import share_candidates
from evoscen_sim.errors import InputError
from evoscen_sim.jit import kernel
from evoscen_sim.physics.window import NEW_TRIP_MAX_SPEED_MPS
from evoscen_sim.physics.vehicle import accel_to_throttle

from .car_following import ReactionState, learned_throttle, throttle_constants
from .lane_change_decision import (
    FORCED_MERGE_M,
    LANE_END_MARGIN_M,
    OBS_DIM,
    action_to_lane_change,
    apply_rule_constraints,
    forced_merge_targets,
    merge_seek_accel,
    observation_grid,
)
from .learned_step import HARD_BRAKE_VIEW_M, _hard_brake_scan, _lane_hold_step, driver_step
from .profile import get_profile
from .td3 import NumpyActor
from .training_config import TrainingConfig, load_training_config

POLICY_FILES = {"mutual": "mutual.npz", "competitive": "competitive.npz", "cooperative": "cooperative.npz"}
"""Decision policy of each policy name at run time (``mutual`` is the level-2 mutual policy)."""
CONTROLLER_FILE = "controller.npz"
POLICY_CODE = {name: POLICY_CODES[name] for name in SOCIAL_POLICIES}
"""The world's policy codes of the social types (``evoscen_contract.contract.POLICY_CODES``)."""


@dataclasses.dataclass(frozen=True)
class HardBrakeParams:
    """The run-time hard-braking rule of the learned BVs (docs/learned-bvs.md, "Hard braking").

    While a BV is the SUT's leader (:data:`HARD_BRAKE_VIEW_M`), on the main line (not changing
    lanes) and at ``min_speed_mps`` or faster, hard-braking episodes start as a Poisson process
    of ``per_1000km`` events per 1,000 km it drives so; an episode brakes at a deceleration
    drawn uniformly from ``decel_mps2`` for a duration drawn uniformly from ``duration_s`` and
    ends early when the BV's speed falls to ``min_speed_mps`` (never into a standstill).
    """

    per_1000km: float = 11.8
    decel_mps2: tuple[float, float] = (4.0, 7.0)
    duration_s: tuple[float, float] = (1.0, 3.0)
    min_speed_mps: float = 10.0

    def __post_init__(self) -> None:
        lo, hi = self.decel_mps2
        dlo, dhi = self.duration_s
        if not (self.per_1000km > 0.0 and 0.0 < lo <= hi and 0.0 < dlo <= dhi and self.min_speed_mps >= 0.0):
            raise ValueError(f"HardBrakeParams: bad values {self}")


class HardBrakeState:
    """Per hosted vehicle: the distance left, as the SUT's leader, to its next hard-braking
    episode (exponential draws, mean 1,000 km / ``per_1000km``), and the episode in progress.

    Each vehicle draws from its own generator, seeded from ``rng`` at construction (one seed per
    vehicle, in vehicle order), in a fixed order (at construction its first distance; at each of
    its starts: deceleration, duration, next distance), so a seed gives the same episodes in
    every runner and whatever the split of the BVs into BV nodes (:meth:`restrict`).
    """

    def __init__(self, n: int, params: HardBrakeParams, rng: np.random.Generator) -> None:
        self.params = params
        self.rngs = [np.random.default_rng(int(x)) for x in rng.integers(0, 2**63 - 1, size=n)]
        self.mean_m = 1.0e6 / params.per_1000km
        self.to_go_m = np.array([g.exponential(self.mean_m) for g in self.rngs])
        self.until_step = np.full(n, -1, dtype=np.int64)
        """Steps before this one brake (the episode in progress); -1: none."""
        self.decel = np.zeros(n)
        self.driven_m = 0.0
        """Distance driven by the hosted vehicles while their odometers ran (the exposure)."""
        self.episodes: list[tuple[int, int, float, float]] = []
        """Every episode started: (hosted position, step, deceleration m/s², duration s)."""

    def restrict(self, positions: np.ndarray) -> None:
        """Keep the vehicles at ``positions`` only, each with its own generator and state."""
        self.rngs = [self.rngs[int(k)] for k in positions]
        self.to_go_m, self.until_step, self.decel = (self.to_go_m[positions], self.until_step[positions],
                                                     self.decel[positions])

    def start(self, k: int, step: int, dt_s: float) -> None:
        p = self.params
        rng = self.rngs[k]
        decel = float(rng.uniform(*p.decel_mps2))
        duration = float(rng.uniform(*p.duration_s))
        self.to_go_m[k] += rng.exponential(self.mean_m)  # the overshoot carries: exact in distance
        self.decel[k] = decel
        self.until_step[k] = step + max(1, int(round(duration / dt_s)))
        self.episodes.append((k, step, decel, duration))

    def bound(self, view, vehicles: np.ndarray, throttle: np.ndarray, vehicle_params, scan: tuple | None = None
              ) -> np.ndarray:
        """``throttle`` with the episodes' braking; advances the odometers and starts episodes. ``scan``: this
        step's :func:`_hard_brake_scan` result, if the caller made it."""
        p = self.params
        step, dt = int(view.step_index), float(view.dt_s)
        v = np.asarray(view.v, dtype=np.float64)
        if scan is None:
            scan = _hard_brake_scan(np.asarray(vehicles, dtype=np.int64), self.until_step, v,
                                    np.asarray(view.role, dtype=np.int64), np.asarray(view.s, dtype=np.float64),
                                    np.asarray(view.d, dtype=np.float64), np.asarray(view.length, dtype=np.float64),
                                    np.asarray(view.width, dtype=np.float64),
                                    np.asarray(view.lane_change, dtype=np.int64), float(p.min_speed_mps), step,
                                    HARD_BRAKE_VIEW_M, ROLE_SUT)
        braking, k = scan
        if k >= 0:  # the SUT's leader is hosted here and its odometer runs
            vk = v[vehicles[k]]
            self.to_go_m[k] -= vk * dt
            self.driven_m += vk * dt
            if self.to_go_m[k] <= 0.0:
                self.start(k, step, dt)
                braking[k] = True
        if not np.count_nonzero(braking):
            return throttle
        out = np.array(throttle, dtype=float)
        out[braking] = np.minimum(out[braking], accel_to_throttle(-self.decel[braking], vehicle_params))
        return out


def shipped_policy_dir() -> Path:
    """The shipped policies (installed share dir, else the source tree)."""
    candidates = share_candidates("policies", "evoscen_bv")  # the source tree keeps them in ros2_ws/src/evoscen_bv/policies
    return next((p for p in candidates[:-1] if p.is_dir()), candidates[-1])


class PolicyBank:
    """Several actors of equal shape evaluated in one batched, compiled forward pass.

    ``forward(x, column)`` returns one action per row of ``x``: row ``r`` goes through actor
    ``column[r]``. The pass is one numba kernel over the batch (not numpy matmuls: for a few
    dozen rows, BLAS thread start-up cost more than the arithmetic — measured 3.9 ms per call
    on the shared 2-core machine for the 3-policy batch, against tens of µs here), and it
    skips zero inputs in the first layer (the decision grid is mostly empty cells). Sums run
    in a fixed order without fastmath, so every runner computes the same floats; they equal
    the torch actor's within float32 rounding.
    """

    def __init__(self, actors: list[NumpyActor]) -> None:
        if not actors:
            raise ValueError("PolicyBank: no actors")
        shapes = {(a.W1.shape, a.W2.shape, a.W3.shape) for a in actors}
        if len(shapes) != 1 or actors[0].action_dim != 1:
            raise ValueError(f"PolicyBank: actors differ in shape or are not 1-D: {sorted(shapes)}")
        self.W1 = np.ascontiguousarray(np.stack([a.W1 for a in actors]))
        self.b1 = np.ascontiguousarray(np.stack([a.b1 for a in actors]))
        self.W2 = np.ascontiguousarray(np.stack([a.W2 for a in actors]))
        self.b2 = np.ascontiguousarray(np.stack([a.b2 for a in actors]))
        self.W3 = np.ascontiguousarray(np.stack([a.W3[:, 0] for a in actors]))
        self.b3 = np.array([a.b3[0] for a in actors])
        self.max_action = np.array([a.max_action for a in actors])
        for w in (self.W1, self.b1, self.W2, self.b2, self.W3, self.b3, self.max_action):
            w.flags.writeable = False  # read by the forward pass only: a copy of a driver shares them

    def __deepcopy__(self, memo: dict) -> PolicyBank:
        """The bank itself: its weights are read-only, so a copied driver (a run from a shared start,
        :mod:`evoscen_bringup.starts`) shares them instead of copying ~1.8 MB per run."""
        return self

    def forward(self, x: np.ndarray, column: np.ndarray | None = None) -> np.ndarray:
        x = np.ascontiguousarray(x, dtype=np.float64)
        col = np.zeros(x.shape[0], dtype=np.int64) if column is None else np.asarray(column, dtype=np.int64)
        return _bank_forward(x, col, self.W1, self.b1, self.W2, self.b2, self.W3, self.b3, self.max_action)


@kernel
def _bank_forward(x, col, W1, b1, W2, b2, W3, b3, max_action):
    m, n_in = x.shape
    h = W1.shape[2]
    out = np.empty(m)
    h1 = np.empty(h)
    h2 = np.empty(h)
    for r in range(m):
        p = col[r]
        for u in range(h):
            h1[u] = b1[p, u]
        for k in range(n_in):
            xk = x[r, k]
            if xk != 0.0:
                for u in range(h):
                    h1[u] += xk * W1[p, k, u]
        for u in range(h):
            h1[u] = max(h1[u], 0.0)
            h2[u] = b2[p, u]
        for k in range(h):
            hk = h1[k]
            if hk != 0.0:
                for u in range(h):
                    h2[u] += hk * W2[p, k, u]
        z = b3[p]
        for u in range(h):
            z += max(h2[u], 0.0) * W3[p, u]
        out[r] = max_action[p] * np.tanh(z)
    return out


def load_actor(directory: Path, name: str, state_dim: int) -> NumpyActor:
    actor = NumpyActor.load(Path(directory) / name)
    if actor.state_dim != state_dim or actor.action_dim != 1:
        raise InputError(f"{Path(directory) / name}: expected an actor with {state_dim} inputs and 1 output, "
                         f"got {actor.state_dim} inputs and {actor.action_dim} outputs")
    return actor


class LearnedDriver:
    """Learned drivers for the vehicles ``vehicles`` (world indices).

    Args:
        vehicles: world indices of the hosted vehicles.
        controller: the car-following actor (4 inputs).
        decision_actors: policy code -> decision actor (500 inputs); a vehicle whose policy
            code is not a key uses ``default_code``'s actor.
        config: the training config the policies were trained with.
        rng: draws each vehicle's desired speed.
        vehicle_params: the scenario's :class:`evoscen_sim.physics.vehicle.VehicleParams`.
        default_code: policy code used for vehicles with an unknown code.
        forced_merge: apply the run-time forced merge
            (:func:`evoscen_bv.lane_change_decision.forced_merge_requests`): scenario BVs yes, the
            training environments' traffic no (the policies were trained without it).
        profile: the run-time rule profile (:mod:`evoscen_bv.profile`, docs/bv-profiles.md):
            ``driver`` or ``safety_net``; ``None``: the training config's ``env.profile``.
        lane_hold_s: the run-time lane hold (docs/learned-bvs.md, "Lane hold"): for this long
            after a vehicle's lane change ends (the world's ``lane_change`` column back to 0),
            its policy's requests are rewritten to keep, except the forced merge's; 0 = no
            hold (the training environments, and the scenario's BVs before the hold existed).
        cut_in_decel_mps2: b of the cut-in gap term c²/(2b) under the ``driver`` profile (0: no
            such term); ``None``: the profile's (none). Ignored under ``safety_net``.
        standing_leader_at_once: under the ``driver`` profile, the emergency brake acts at once
            for a perceived leader at rest (R2); ``None``: the profile's. Ignored under ``safety_net``.
        into_ending_lane: whether a change into a lane that ends 200 m or more ahead is allowed
            (the training rule, the default here); False: never into a lane that ends.
        forced_merge_m: with ``forced_merge``, how far before its lane's end a vehicle requests the
            change to the lane that goes on (:func:`evoscen_bv.lane_change_decision.forced_merge_targets`).
        merge_seek: with ``forced_merge``, a vehicle that must merge adapts its speed to drop
            back behind the target lane's vehicles that block it
            (:func:`evoscen_bv.lane_change_decision.merge_seek_accel`); False: it keeps the controller's throttle.
        hold_on_entry: with ``lane_hold_s``, a vehicle that enters anew (the traffic window's entries,
            re-entries) starts with a lane hold, as a vehicle that has settled in its lane; False:
            without one (it may change lanes at its first decision).
        compete_with_sut: competitive BVs do not yield to the SUT's lane-change intent: the SUT
            occupies their lane once its body reaches into it
            (:func:`evoscen_bv.car_following._late_occupancy`; ``models.learned.competitive_cut_in``);
            False: every BV yields on the intent.
        hard_brake: the run-time hard braking of the SUT's leader (:class:`HardBrakeParams`,
            docs/learned-bvs.md, "Hard braking"); its draws come from a generator seeded by one
            draw from ``rng`` after the desired speeds. ``None``: no hard braking (no draw).
    """

    def __init__(self, vehicles, controller: NumpyActor, decision_actors: dict[int, NumpyActor],
                 config: TrainingConfig, rng: np.random.Generator, vehicle_params, default_code: int = 1,
                 forced_merge: bool = False, profile: str | None = None, lane_hold_s: float = 0.0,
                 cut_in_decel_mps2: float | None = None, standing_leader_at_once: bool | None = None,
                 into_ending_lane: bool = True, forced_merge_m: float = FORCED_MERGE_M,
                 merge_seek: bool = False, hold_on_entry: bool = False, compete_with_sut: bool = False,
                 hard_brake: HardBrakeParams | None = None) -> None:
        self.vehicles = np.asarray(vehicles, dtype=np.int64)
        if not lane_hold_s >= 0.0:
            raise ValueError(f"lane_hold_s must be >= 0, got {lane_hold_s}")
        self.lane_hold_s = float(lane_hold_s)
        self._changing = np.zeros(self.vehicles.size, dtype=bool)
        """Whether each hosted vehicle was changing lanes at the last :meth:`act`."""
        self.hold_until_step = np.full(self.vehicles.size, -1, dtype=np.int64)
        """Per hosted vehicle: decisions at steps before this one keep the lane (the lane hold)."""
        self._last_s: np.ndarray | None = None
        """Arc lengths at the last :meth:`act` (a fall marks a re-entry)."""
        self.profile = get_profile(config.env.profile if profile is None else profile)
        if cut_in_decel_mps2 is not None and self.profile.name != "safety_net":  # safety_net: the rules as they were
            self.profile = dataclasses.replace(self.profile,
                                               cut_in_closing_decel_mps2=float(cut_in_decel_mps2) or None)
        if standing_leader_at_once is not None and self.profile.name != "safety_net":
            self.profile = dataclasses.replace(self.profile, standing_leader_at_once=bool(standing_leader_at_once))
        self.reaction: ReactionState | None = None
        """The driver profile's state, made at the first step (N needs the step length); None: safety_net."""
        self.end_margin_m = LANE_END_MARGIN_M if into_ending_lane else float("inf")
        """A change into a lane that ends less than this far ahead becomes keep."""
        self.forced_merge = forced_merge
        self.forced_merge_m = float(forced_merge_m)
        self.merge_seek = bool(merge_seek)
        self.hold_on_entry = bool(hold_on_entry)
        self.compete_with_sut = bool(compete_with_sut)
        self.controller = controller
        self.controller_bank = PolicyBank([controller])
        self.config = config
        self.vehicle_params = vehicle_params
        self.codes = np.array(sorted(decision_actors), dtype=np.int64)
        self.decision_actors = [decision_actors[int(c)] for c in self.codes]
        self.stack = PolicyBank([decision_actors[int(c)] for c in self.codes]) if decision_actors else None
        self.column_of_code = np.full(max(16, int(self.codes.max(initial=0)) + 1), -1, dtype=np.int64)
        self.column_of_code[self.codes] = np.arange(self.codes.size)
        self.default_column = int(self.column_of_code[default_code]) if decision_actors else -1
        lo, hi = config.env.desired_speed_mps
        self.desired_speed_mps = rng.uniform(lo, hi, size=self.vehicles.size)
        self.speed_cap = True
        """Whether the desired speed is capped by the lane's speed limit (False: ``bvs.makeup: highd``,
        whose drawn desired speeds are the drivers' own; docs/bv-profiles.md, "Traffic make-up")."""
        self._nan_limits: np.ndarray | None = None
        self._merge_seek_ready = False  # the merge kernel run once (_merge_seek_bound)
        self.hard_brake: HardBrakeState | None = None
        if hard_brake is not None:
            child = np.random.default_rng(int(rng.integers(0, 2**63 - 1)))
            self.hard_brake = HardBrakeState(self.vehicles.size, hard_brake, child)
        self._throttle_constants: tuple | None = None
        self._throttle_road = None
        self.last_request = np.zeros(self.vehicles.size, dtype=np.int64)
        """Requested (pre-constraint) actions of the last decision, for training and tests."""

    def restrict(self, positions: np.ndarray) -> None:
        """Host only the vehicles at ``positions`` of :attr:`vehicles`, each with the state it was
        built with (its desired speed: the draws do not depend on the split), so that a BV node's
        share drives exactly as in the one driver of all BVs (:mod:`evoscen_sim.nodes.bv_nodes`). Before
        the first :meth:`act` (the per-vehicle state of the profile is made there, for the hosted ones)."""
        if self.reaction is not None or self._last_s is not None:
            raise RuntimeError("LearnedDriver.restrict: after the first act")
        self.vehicles = self.vehicles[positions]
        self._changing = self._changing[positions]
        self.hold_until_step = self.hold_until_step[positions]
        self.desired_speed_mps = self.desired_speed_mps[positions]
        self.last_request = self.last_request[positions]
        if self.hard_brake is not None:
            self.hard_brake.restrict(positions)

    def prepare_throttle(self, view) -> None:
        """The profile's state (at the first step: N needs the step length) and the throttle's constants (again
        when the road is another), as :meth:`throttle` and :func:`evoscen_bv.learned_step.driver_step` need them."""
        if self.reaction is None and self.profile.name != "safety_net":
            p = self.profile
            brake = float(self.vehicle_params.max_brake_mps2)
            cap = 1.0 if p.max_decel_mps2 is None else min(p.max_decel_mps2 / brake, 1.0)
            self.reaction = ReactionState(self.vehicles.size, p.reaction_steps(float(view.dt_s)), cap,
                                          p.standing_leader_at_once)
        if self._throttle_constants is None or self._throttle_road is not view.road:
            vp = self.vehicle_params
            self._throttle_road = view.road
            self._throttle_constants = throttle_constants(self.controller_bank, self.config.car_following, view.road,
                                                          vp.max_accel_mps2, vp.max_brake_mps2)

    def throttle(self, view) -> np.ndarray:
        """The controller's throttle for every hosted vehicle (one compiled pass, see
        :func:`evoscen_bv.car_following.learned_throttle`)."""
        self.prepare_throttle(view)
        late, sut = None, -1
        if self.compete_with_sut:
            sut_rows = np.flatnonzero(np.asarray(view.role) == ROLE_SUT)
            if sut_rows.size:
                sut = int(sut_rows[0])
                late = np.asarray(view.policy)[self.vehicles] == POLICY_CODE["competitive"]
        return learned_throttle(view, self.vehicles, self.desired_speed_mps, self.controller_bank,
                                self.config.car_following, 0.0, 0.0, self._throttle_constants, self.reaction,
                                late, sut, max_speed=None if self.speed_cap else self._no_limits(view))

    def _no_limits(self, view) -> np.ndarray:
        """Lane limits that cap nothing (all NaN), shaped as the view's look-up (kept between steps)."""
        shape = view.lane_lookup().max_speed_mps.shape
        if self._nan_limits is None or self._nan_limits.shape != shape:
            self._nan_limits = np.full(shape, np.nan)
        return self._nan_limits

    def _merge_seek_bound(self, view, throttle: np.ndarray, targets: np.ndarray | None = None) -> np.ndarray:
        """``throttle`` bounded by the merge's speed adaptation (:func:`merge_seek_accel`) for the
        hosted vehicles that must merge (few: those on a lane that ends); ``targets``: their
        :func:`forced_merge_targets`, if the caller has them."""
        if targets is None:
            targets = forced_merge_targets(view, self.vehicles, self.forced_merge_m)
        if not np.count_nonzero(targets):  # count_nonzero: a fifth of .any()'s cost on a small int array
            if not self._merge_seek_ready:
                # The first act runs the merge's kernel on no vehicle (nothing changes): compiled, or
                # loaded from numba's cache, here rather than at the first merge. A controller node
                # warms up with one act on the start state (controller_node._warm_up), so the kernel
                # is never first compiled mid-run, where a cold compile took ~1.8 s and missed the
                # lockstep's deadline (docs/recording.md, "Compiled kernels before the first step").
                merge_seek_accel(view, self.vehicles[:0], targets[:0], self.desired_speed_mps[:0],
                                 self.profile.cut_in_closing_headway_s, self.profile.cut_in_closing_decel_mps2)
                self._merge_seek_ready = True
            return throttle
        self._merge_seek_ready = True
        bound = merge_seek_accel(view, self.vehicles, targets, self.desired_speed_mps,
                                 self.profile.cut_in_closing_headway_s, self.profile.cut_in_closing_decel_mps2)
        limited = np.isfinite(bound)
        if not limited.any():
            return throttle
        out = np.array(throttle, dtype=float)
        out[limited] = np.minimum(out[limited], accel_to_throttle(bound[limited], self.vehicle_params))
        return out

    def policy_columns(self, view, idx: np.ndarray) -> np.ndarray:
        """Column of :attr:`stack` (decision policy) of every vehicle in ``idx``, from its policy code."""
        col = self.column_of_code[np.clip(view.policy[idx], 0, self.column_of_code.size - 1)]
        return np.where(col < 0, self.default_column, col)

    def decide(self, view, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Decisions of the hosted vehicles at ``positions``: (grid obs, requested, executed)."""
        idx = self.vehicles[positions]
        obs = observation_grid(view, idx, self.config.grid).reshape(idx.size, OBS_DIM)
        requested = action_to_lane_change(self.stack.forward(obs, self.policy_columns(view, idx)))
        forced = np.zeros(idx.size, dtype=np.int64)
        if self.forced_merge:
            forced = forced_merge_targets(view, idx, self.forced_merge_m)
            requested = np.where(forced != 0, forced, requested)
        allowed = requested
        if self.lane_hold_s > 0.0:  # the hold rewrites the policy's requests, not the road's forced merge
            held = (self.hold_until_step[positions] > int(view.step_index)) & (forced == 0)
            allowed = np.where(held, 0, requested)
        executed = apply_rule_constraints(view, idx, allowed, self.profile.cut_in_closing_headway_s,
                                          self.profile.cut_in_closing_decel_mps2, self.end_margin_m)
        return obs, requested, executed

    def act(self, view) -> tuple[np.ndarray, np.ndarray]:
        """Throttle in [-1, 1] and lane-change request in {-1, 0, +1} for each hosted vehicle."""
        fused = self.profile.name != "safety_net"
        targets = scan = None
        if fused:  # the throttle, the merge targets, the hard-braking scan and the lane hold: one call
            throttle, targets, scan = driver_step(self, view)
        else:
            throttle = self.throttle(view)
        if self.forced_merge and self.merge_seek:
            throttle = self._merge_seek_bound(view, throttle, targets)
        if self.hard_brake is not None:
            throttle = self.hard_brake.bound(view, self.vehicles, throttle, self.vehicle_params, scan)
        if self.lane_hold_s > 0.0 and not fused:
            dt = float(view.dt_s)
            self._changing, self._last_s = _lane_hold_step(
                self.vehicles, np.asarray(view.lane_change, dtype=np.int64), np.asarray(view.s, dtype=np.float64),
                self._changing, self.hold_until_step, self._last_s, int(view.step_index),
                int(round(self.lane_hold_s / dt)), self.hold_on_entry, NEW_TRIP_MAX_SPEED_MPS * dt + 10.0)
        request = np.zeros(self.vehicles.size, dtype=np.int64)
        if self.stack is not None and view.step_index % self.config.env.decision_interval_steps == 0:
            positions = np.flatnonzero(view.lane_change[self.vehicles] == 0)
            if positions.size:
                _, requested, executed = self.decide(view, positions)
                request[positions] = executed
                self.last_request[:] = 0
                self.last_request[positions] = requested
        return throttle, request


_POLICY_CACHE: dict[Path, tuple[tuple, tuple[NumpyActor, dict[int, NumpyActor], TrainingConfig]]] = {}
"""Per process: resolved policy directory -> (stat signature of the files read, what they gave)."""


def _policy_signature(directory: Path) -> tuple | None:
    """(inode, size, mtime_ns) of ``training.yaml`` and every weight file :func:`load_policies` reads;
    None when one cannot be read (the load then fails as without a cache, and nothing is kept)."""
    out = []
    for name in ("training.yaml", CONTROLLER_FILE, *POLICY_FILES.values()):
        try:
            st = (directory / name).stat()
        except OSError:
            return None
        out.append((name, st.st_ino, st.st_size, st.st_mtime_ns))
    return tuple(out)


def load_policies(directory: Path | str) -> tuple[NumpyActor, dict[int, NumpyActor], TrainingConfig]:
    """Controller, decision actors by policy code, and training config from a policy directory.

    Loaded once per process and directory: a later call with ``training.yaml`` and the weight files
    unchanged (same inode, size and modification time) returns the same actors and config, shared (the
    config is frozen, the actors' arrays read-only; the dict is new); a changed file is read anew. Failures are not kept.
    """
    directory = Path(directory)
    if not directory.is_dir():
        raise InputError(f"{directory} is not a directory")
    cfg_path = directory / "training.yaml"
    if not cfg_path.is_file():
        raise InputError(f"{directory}: no training.yaml (the training config the policies were trained with)")
    key = directory.resolve()
    before = _policy_signature(directory)
    cached = _POLICY_CACHE.get(key)
    if before is not None and cached is not None and cached[0] == before:
        controller, decisions, config = cached[1]
        return controller, dict(decisions), config
    config = load_training_config(cfg_path)

    def _load(name: str, dim: int) -> NumpyActor:
        try:
            actor = load_actor(directory, name, dim)
        except ValueError as exc:
            raise InputError(str(exc)) from None
        for a in (actor.W1, actor.b1, actor.W2, actor.b2, actor.W3, actor.b3):
            a.flags.writeable = False  # shared by every driver built from this directory
        return actor

    controller = _load(CONTROLLER_FILE, 4)
    decisions = {POLICY_CODE[p]: _load(f, OBS_DIM) for p, f in POLICY_FILES.items()}
    loaded = controller, decisions, config
    if before is not None and _policy_signature(directory) == before:  # unchanged while read
        _POLICY_CACHE[key] = (before, loaded)
    return controller, dict(decisions), config
