"""The world: every vehicle's state and the fixed-step update, vectorized over vehicles.

One call of :meth:`World.step` takes one command per vehicle — a throttle/brake value in
[-1, 1] and a lane-change request in {-1, 0, +1} (+1 = left) — and advances all vehicles
by ``dt_s``:

1. **Lane-change requests.** A request is executed only when the vehicle is not already
   changing lanes and the target lane exists at the vehicle's position; otherwise the
   executed action is 0 (keep). The executed action is returned, so drivers can compare
   requested and executed actions. An executed request moves the *target lane*; the
   dual PID (:mod:`evoscen_sim.physics.control`) then steers to the target lane's centre line.
2. **Dynamics.** Throttle → acceleration, dual PID → steering, kinematic bicycle
   (:mod:`evoscen_sim.physics.vehicle`).
3. **Lanes.** A vehicle's lane is the lane that contains its centre of mass. A lane
   change is complete when the centre of mass is in the target lane; its duration (the
   decision to that moment) is T_l of the efficiency score. A vehicle whose centre leaves
   the road keeps its last lane and raises one ``off_road`` event.
4. **Re-entry** (docs/method.md §1 [choice]): a vehicle whose centre passes the end of the road
   re-enters at once, so the number of vehicles on the road never changes. With
   probability ``ramp_share`` (drawn from the scenario's seeded generator) it re-enters
   at the start of the merge lane (coming from the on-ramp), else at ``s = 0`` of the
   mainline lane with the most free space before its rearmost vehicle. It is put
   ``min_gap_m`` behind that rearmost vehicle if the entry point is not free (also when
   that vehicle is itself still waiting on the approach) (``s`` may then be negative: the
   vehicle is on the approach and road look-ups use ``s = 0``), centred in the lane,
   heading along the road, and keeps its speed, capped by the speed of the vehicle it
   enters behind when that one is within 100 m.
5. **Collisions**: oriented bounding boxes overlap (:mod:`evoscen_sim.physics.collision`). A
   collision is reported once, at the first step a pair overlaps; vehicles are not
   removed and there is no contact physics (the drivers see the negative gap and brake).
   A pair that separates and touches again is a new collision.

Time: ``time_s = step_index * dt_s`` exactly (no accumulated floating-point drift).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from evoscen_contract.contract import ROLE_BV, ROLE_SUT  # noqa: F401  (re-exported: the world's role codes)

from evoscen_sim.config.config_schema import ReentryConfig
from evoscen_sim.jit import kernel
from evoscen_sim.physics.window import TrafficParams, TrafficWindow
from evoscen_sim.road.road_kernels import frenet_to_cartesian_kernel, lane_center_d, lane_lookup_kernel
from evoscen_sim.road.road_model import LaneLookup

from .collision import overlapping_pairs
from .control import ControlParams, DualPidController, dual_pid_one
from .neighbors import Neighborhood, compute_neighborhood
from .vehicle import VehicleParams, bicycle_one


@dataclass(frozen=True)
class ReentryParams:
    """Re-entry policy of vehicles that leave the road (see the module docstring)."""

    ramp_share: float = ReentryConfig.ramp_share  # the defaults of the ``reentry`` section
    min_gap_m: float = ReentryConfig.min_gap_m
    speed_match_range_m: float = 100.0


@dataclass(frozen=True)
class InitialState:
    """Where the vehicles start. Arrays of length N; lanes are lane indices."""

    ids: np.ndarray
    roles: np.ndarray
    policies: np.ndarray
    s_m: np.ndarray
    lane: np.ndarray
    speed_mps: np.ndarray
    length_m: np.ndarray | None = None
    """Per-vehicle body length (m); None: every vehicle the ``vehicle`` section's (``bvs.makeup``)."""
    width_m: np.ndarray | None = None
    """Per-vehicle body width (m); None: the ``vehicle`` section's."""


@dataclass
class StepResult:
    """What happened during one step (indices are vehicle indices, not ids)."""

    step: int
    time_s: float
    executed_lane_change: np.ndarray
    collisions: list[tuple[int, int]] = field(default_factory=list)
    lane_changes_completed: list[tuple[int, int, int, float]] = field(default_factory=list)
    """(vehicle, from lane, to lane, duration_s) of lane changes completed in this step."""
    lane_changes_aborted: list[tuple[int, int, int]] = field(default_factory=list)
    """(vehicle, from lane, target lane) of lane changes aborted because the target lane ended."""
    reentries: list[tuple[int, int, float]] = field(default_factory=list)
    """(vehicle, lane, s_m) of vehicles that left the road and re-entered."""
    off_road: list[int] = field(default_factory=list)
    shift_m: float = 0.0
    """Distance every vehicle was moved back along the road in this step (the traffic window's
    shift, :mod:`evoscen_sim.physics.window`); 0 when none."""
    challenges: list = field(default_factory=list)
    """The challenge layer's onsets of this step (:class:`evoscen_sim.danger.challenge.Onset`)."""



STATE_FLOATS = ("s", "d", "heading_rel", "speed", "accel", "steer", "length", "width")
"""The float64 state arrays of :meth:`World.state_arrays`, in order (their column names)."""
STATE_INTS = ("id", "role", "policy", "lane", "target_lane", "lane_change")
"""The int64 state arrays of :meth:`World.state_arrays`, in order (their column names)."""


def state_columns(road, state: tuple) -> dict[str, np.ndarray]:  # a Road
    """The world table's named columns from :meth:`World.state_arrays` (what :meth:`World.columns`
    returns; the one definition, so a copy of the state gives the same columns bit for bit)."""
    (s, d, psi, v, accel, steer, length, width), (ids, role, policy, lane, target_lane, lane_change) = state
    x, y, heading = road.frenet_to_cartesian(np.maximum(s, 0.0), d)
    return {
        "id": ids,
        "role": role,
        "policy": policy,
        "x": x,
        "y": y,
        "yaw": heading + psi,
        "s": s,
        "d": d,
        "heading_rel": psi,
        "speed": v,
        "accel": accel,
        "steer": steer,
        "lane": lane,
        "target_lane": target_lane,
        "lane_change": lane_change,
        "length": length,
        "width": width,
    }


class World:
    """State of all vehicles on one road and the fixed-step update (see module docstring)."""

    def __init__(
        self,
        road,  # evoscen_sim.road.road_model.RoadModel
        initial: InitialState,
        *,
        vehicle: VehicleParams,
        control: ControlParams,
        reentry: ReentryParams,
        dt_s: float,
        rng: np.random.Generator,
        traffic: TrafficParams | None = None,
        makeup=None,  # evoscen_sim.traffic.makeup.WindowMakeup: the highd make-up's entries
    ) -> None:
        self.road = road
        self.vehicle = vehicle
        self.reentry = reentry
        self.dt_s = float(dt_s)
        self.rng = rng
        self.challenge = None
        """The challenge layer (:class:`evoscen_sim.danger.challenge.LeaderBraking`), set after the warm-up
        when ``challenge.mode`` is not ``none``: it brakes the SUT's leader in the step's commands."""
        n = int(initial.s_m.shape[0])
        self.n = n
        self.ids = np.asarray(initial.ids, dtype=np.int64).copy()
        self.role = np.asarray(initial.roles, dtype=np.int64).copy()
        self.policy = np.asarray(initial.policies, dtype=np.int64).copy()
        self.length = (np.full(n, vehicle.length_m) if initial.length_m is None
                       else np.asarray(initial.length_m, dtype=float).copy())
        self.width = (np.full(n, vehicle.width_m) if initial.width_m is None
                      else np.asarray(initial.width_m, dtype=float).copy())
        self.lane = np.asarray(initial.lane, dtype=np.int64).copy()
        self.s = np.asarray(initial.s_m, dtype=float).copy()
        self.d = road.lane_center_d(self.lane, self.s).astype(float)
        self.psi = np.zeros(n)
        self.v = np.asarray(initial.speed_mps, dtype=float).copy()
        self.accel = np.zeros(n)
        self.steer = np.zeros(n)
        self.target_lane = self.lane.copy()
        self.lane_change = np.zeros(n, dtype=np.int64)
        """Direction of the lane change in progress (0 = none)."""
        self.lane_change_start_s = np.full(n, np.nan)
        self.lane_change_count = np.zeros(n, dtype=np.int64)
        self.last_lane_change_duration_s = np.full(n, np.nan)
        self.off_road = np.zeros(n, dtype=bool)
        self.step_index = 0
        self.controller = DualPidController(n, control, vehicle.wheelbase_m, self.dt_s)
        self.controller.reset(np.arange(n))
        self._contacts: set[tuple[int, int]] = set()
        self._neighborhood: Neighborhood | None = None
        self._rows = np.arange(n)
        self._refresh_road_lookups()
        bad = ~road.lane_exists(self.lane, self.s)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(
                f"initial state: vehicle {int(self.ids[i])} placed in lane {int(self.lane[i])} "
                f"at s = {self.s[i]:.1f} m, where that lane does not exist"
            )
        sut = np.flatnonzero(self.role == ROLE_SUT)
        self.window: TrafficWindow | None = None
        if traffic is not None and sut.size:
            self.window = TrafficWindow(self, traffic, int(sut[0]), makeup)

    @property
    def time_s(self) -> float:
        """Simulation time of the current state (s)."""
        return self.step_index * self.dt_s

    @property
    def time_ns(self) -> int:
        """Simulation time of the current state in integer nanoseconds (message stamps)."""
        return self.step_index * round(self.dt_s * 1e9)

    def _refresh_road_lookups(self) -> None:
        """Road quantities at the current positions, evaluated once per step."""
        self._lanes = self.road.lane_lookup(np.maximum(self.s, 0.0), self.d)
        self._speed_limit: np.ndarray | None = None

    def refresh(self) -> None:
        """Recompute the per-step road look-ups and neighbourhood after positions were changed from
        outside :meth:`step` (the warm-up's hold)."""
        self._neighborhood = None
        self._refresh_road_lookups()

    def restart_clock(self) -> None:
        """Make the current state step 0 (after a warm-up): lane changes in progress keep the time
        they have been under way."""
        elapsed = self.time_s
        self.step_index = 0
        self.lane_change_start_s -= elapsed

    def lane_lookup(self):  # evoscen_sim.road.road_model.LaneLookup
        """Lane data (borders, existence, limits) at every vehicle's position (cached per step)."""
        return self._lanes

    @property
    def speed_limit_mps(self) -> np.ndarray:
        """Maximum speed of every vehicle's lane at its position (m/s)."""
        if self._speed_limit is None:
            self._speed_limit = self._lanes.max_speed_mps[self._rows, self.lane]
        return self._speed_limit

    def neighborhood(self) -> Neighborhood:
        """Leaders/followers of every vehicle in the current state (cached per step)."""
        if self._neighborhood is None:
            self._neighborhood = compute_neighborhood(self.s, self.lane, self.v, self.accel, self.length)
        return self._neighborhood

    def columns(self) -> dict[str, np.ndarray]:
        """The current state as named columns (the world table of the topic contract).

        State columns are live views that the next :meth:`step` updates in place: copy
        them (``np.column_stack`` does) to keep a snapshot.
        """
        return state_columns(self.road, self.state_arrays())

    def table(self) -> np.ndarray:
        """The world table of the current state, ``[N, len(WORLD_FIELDS)]`` float64 in the contract's column order:
        :meth:`columns` stacked as the evaluator stacks them, made in one compiled pass (a fresh array)."""
        return _world_table_kernel(self.s, self.d, self.psi, self.v, self.accel, self.steer, self.length, self.width,
                                   self.ids, self.role, self.policy, self.lane, self.target_lane, self.lane_change,
                                   *self.road.geometry_tables())

    def state_arrays(self) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
        """The state :func:`state_columns` needs, as ``(floats, integers)`` (live views, in
        :data:`STATE_FLOATS` and :data:`STATE_INTS` order): what a recorder copies to rebuild
        :meth:`columns` elsewhere (evoscen_record.bag_writer)."""
        return ((self.s, self.d, self.psi, self.v, self.accel, self.steer, self.length, self.width),
                (self.ids, self.role, self.policy, self.lane, self.target_lane, self.lane_change))

    # ------------------------------------------------------------------ the step
    def step(self, throttle: np.ndarray, lane_change_request: np.ndarray) -> StepResult:
        """Advance every vehicle by ``dt_s`` (see the module docstring for the order)."""
        road = self.road
        n = self.n
        if throttle.shape != (n,) or lane_change_request.shape != (n,):
            raise ValueError(f"step: expected commands of shape ({n},), got {throttle.shape} and {lane_change_request.shape}")
        onsets = None
        if self.challenge is not None:
            throttle, onsets = self.challenge.apply(self, throttle)
        lanes = self._lanes
        c = self.controller
        cp = c.params
        vp = self.vehicle

        # 1. lane-change requests, 2. control and dynamics, 3. the lanes at the new positions and the lane
        # changes completed or aborted: one compiled pass (docs/performance.md "Per-step work of the world
        # and of the BV drivers")
        lane_floats, present, ints, per_vehicle, changes, done_duration = _step_kernel(
            np.asarray(lane_change_request, dtype=np.int64), np.asarray(throttle, dtype=float), self.time_s,
            (self.step_index + 1) * self.dt_s,
            self.lane, self.lane_change, self.target_lane, self.lane_change_start_s,
            lanes.d_right, lanes.d_left, lanes.present, lanes.curvature,
            self.s, self.d, self.psi, self.v, self.accel, self.steer,
            c.int_d, c.int_psi, c.prev_e_d, c.prev_e_psi, c.fresh,
            cp.lat_kp, cp.lat_ki, cp.lat_kd, cp.head_kp, cp.head_ki, cp.head_kd, cp.max_lateral_speed_mps,
            cp.max_heading_ref_rad, vp.wheelbase_m, vp.max_speed_mps, vp.max_accel_mps2, vp.max_brake_mps2,
            vp.max_steer_rad, vp.max_steer_rate_radps * self.dt_s, self.dt_s,
            self.off_road, self.lane_change_count, self.last_lane_change_duration_s, *road.lookup_tables(),
        )
        executed, lane_now = ints
        d_right, d_left, vmax = lane_floats
        kappa, speed_limit = per_vehicle
        self.step_index += 1
        self._neighborhood = None
        result = StepResult(step=self.step_index, time_s=self.time_s, executed_lane_change=executed)
        if onsets:
            result.challenges = onsets
        self._lanes = LaneLookup(d_right, d_left, present, vmax, lane_now, kappa)  # = _refresh_road_lookups()
        self._speed_limit = speed_limit  # = speed_limit_mps (made again if the window moves vehicles below)
        if changes.size > 3:  # lane changes completed or aborted, vehicles newly off the road (_step_kernel)
            n_done, n_aborted, _ = changes[:3].tolist()
            done, done_from = changes[3:3 + n_done], changes[3 + n_done:3 + 2 * n_done]
            k = 3 + 2 * n_done
            aborted, aborted_from = changes[k:k + n_aborted], changes[k + n_aborted:k + 2 * n_aborted]
            newly_off = changes[k + 2 * n_aborted:]
            if n_done:
                result.lane_changes_completed = [
                    (int(i), int(f), int(self.lane[i]), float(t)) for i, f, t in zip(done, done_from, done_duration)
                ]
            if n_aborted:
                result.lane_changes_aborted = [
                    (int(i), int(f), int(self.target_lane[i])) for i, f in zip(aborted, aborted_from)
                ]
                # the target reverts to the lane the vehicle is in
                self.target_lane[aborted] = self.lane[aborted]
                self.controller.reset(aborted)
            if newly_off.size:
                result.off_road = [int(i) for i in newly_off]

        # 4. the traffic window (shift, exits, entries), or re-entry of vehicles past the road's end
        if self.window is not None:
            self.window.after_step(self, result)
            if result.reentries or result.shift_m:
                self._refresh_road_lookups()
        else:
            gone = self.s > road.length_m
            if gone.any():
                for i in np.flatnonzero(gone):
                    result.reentries.append(self._reenter(int(i)))
                self._refresh_road_lookups()

        if self.challenge is not None and result.reentries:  # an entering vehicle brings no braking with it
            self.challenge.entered([i for i, _, _ in result.reentries])

        # 5. collisions (rising edge of each overlapping pair)
        pairs = overlapping_pairs(self.s, self.d, self.psi, self.length, self.width)
        contacts = {(int(i), int(j)) for i, j in pairs.tolist()} if pairs.shape[0] else set()
        if contacts or self._contacts:
            result.collisions = sorted(contacts - self._contacts)
            self._contacts = contacts
        return result

    # ------------------------------------------------------------------ re-entry
    def _reenter(self, i: int) -> tuple[int, int, float]:
        road = self.road
        p = self.reentry
        others = np.arange(self.n) != i
        ramp_lane = road.merge_lane
        choice: tuple[int, float] | None = None
        if road.lane_start_s[ramp_lane] > 0.0 and self.rng.random() < p.ramp_share:
            entry_s = float(road.lane_start_s[ramp_lane])
            space, _ = self._free_space(ramp_lane, entry_s, others)
            if space >= p.min_gap_m:
                choice = (ramp_lane, entry_s)
        if choice is None:
            mainline = road.mainline_lanes
            spaces = [self._free_space(k, 0.0, others)[0] for k in mainline]
            best = int(np.argmax(spaces))  # first lane (rightmost) among equals
            lane = mainline[best]
            s_entry = min(0.0, spaces[best] - p.min_gap_m)  # behind the last vehicle if crowded
            choice = (lane, s_entry)
        lane, s_entry = choice
        _, ahead = self._free_space(lane, s_entry, others)
        speed = self.v[i]
        if ahead >= 0 and self.s[ahead] - s_entry < p.speed_match_range_m:
            speed = min(speed, self.v[ahead])
        self._place(i, lane, s_entry, speed)
        return (i, int(lane), float(s_entry))

    def _place(self, i: int, lane: int, s_entry: float, speed: float) -> None:
        """Put vehicle ``i`` centred in ``lane`` at ``s_entry``, heading along the road, at ``speed``:
        a new trip (no lane change, controller reset, contacts forgotten)."""
        road = self.road
        self.s[i] = s_entry
        self.lane[i] = lane
        self.target_lane[i] = lane
        self.d[i] = lane_center_d(road.kernel_tables(), int(lane), max(float(s_entry), 0.0))  # = road.lane_center_d, compiled
        self.psi[i] = 0.0
        self.steer[i] = 0.0
        self.v[i] = speed
        self.accel[i] = 0.0
        self.lane_change[i] = 0
        self.lane_change_start_s[i] = np.nan
        self.off_road[i] = False
        self.controller.reset(np.array([i]))
        for pair in [c for c in self._contacts if i in c]:
            self._contacts.discard(pair)

    def _free_space(self, lane: int, s_entry: float, others: np.ndarray) -> tuple[float, int]:
        """Bumper gap from a vehicle centred at ``s_entry`` to the rearmost vehicle of ``lane``.

        The rearmost vehicle may itself be behind ``s_entry`` (waiting on the approach);
        the gap is then negative. Vehicles changing into ``lane`` count as in it. Returns
        ``(gap_m, index)``, ``(inf, -1)`` for an empty lane.
        """
        cand = others & ((self.lane == lane) | (self.target_lane == lane))
        if not cand.any():
            return float("inf"), -1
        k = np.flatnonzero(cand)
        j = int(k[np.argmin(self.s[k])])
        gap = self.s[j] - s_entry - 0.5 * (self.length[j] + self.vehicle.length_m)
        return float(gap), j


@kernel
def _advance_kernel(request, throttle, time_s, lane, lane_change, target_lane, lane_change_start_s,
                    d_right, d_left, present, kappa, s, d, psi, v, accel, steer,
                    int_d, int_psi, prev_e_d, prev_e_psi, fresh,
                    lat_kp, lat_ki, lat_kd, head_kp, head_ki, head_kd, max_lat_speed, max_heading,
                    wheelbase, max_speed, max_accel, max_brake, max_steer, max_steer_step, dt):
    """Steps 1 and 2 of :meth:`World.step` for every vehicle, state updated in place."""
    n = s.shape[0]
    num_lanes = present.shape[1]
    executed = np.zeros(n, dtype=np.int64)
    reset = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        # 1. a lane-change request is executed if no change is in progress and the target exists
        r = min(max(request[i], -1), 1)
        if r != 0 and lane_change[i] == 0:
            tgt = lane[i] + r
            if 0 <= tgt < num_lanes and present[i, tgt]:
                executed[i] = r
                target_lane[i] = tgt
                lane_change[i] = r
                lane_change_start_s[i] = time_s
                int_d[i] = 0.0
                int_psi[i] = 0.0
                fresh[i] = True
                reset[i] = True
        # 2. dual PID to the target lane's centre (a lane that has ended: its border)
        tl = target_lane[i]
        d_target = 0.5 * (d_right[i, tl] + d_left[i, tl])
        cmd = dual_pid_one(i, d[i], psi[i], v[i], d_target, kappa[i], int_d, int_psi, prev_e_d, prev_e_psi,
                           fresh, lat_kp, lat_ki, lat_kd, head_kp, head_ki, head_kd, max_lat_speed, max_heading,
                           wheelbase, dt)
        delta = steer[i] + min(max(cmd - steer[i], -max_steer_step), max_steer_step)
        steer[i] = min(max(delta, -max_steer), max_steer)
        # throttle/brake command -> acceleration (as evoscen_sim.physics.vehicle.throttle_to_accel)
        u = min(max(throttle[i], -1.0), 1.0)
        a_cmd = u * max_accel if u >= 0.0 else u * max_brake
        bicycle_one(i, s, d, psi, v, accel, a_cmd, steer[i], kappa[i], wheelbase, max_speed, dt)
    return executed, reset


@kernel
def _lane_bookkeeping_kernel(lane_now, present, time_s, lane, off_road, lane_change, target_lane,
                             lane_change_start_s, lane_change_count, last_duration):
    """Step 3 of :meth:`World.step`: lanes, completed and aborted lane changes, off-road flags."""
    n = lane.shape[0]
    done = []
    done_from = []
    done_duration = []
    aborted = []
    aborted_from = []
    newly_off = []
    for i in range(n):
        if lane_now[i] >= 0:
            lane[i] = lane_now[i]
            off_road[i] = False
        else:  # off the road: keep the last lane, flag the first step
            if not off_road[i]:
                newly_off.append(i)
            off_road[i] = True
        if lane_change[i] != 0:
            if lane[i] == target_lane[i]:
                duration = time_s - lane_change_start_s[i]
                done.append(i)
                done_from.append(target_lane[i] - lane_change[i])
                done_duration.append(duration)
                last_duration[i] = duration
                lane_change_count[i] += 1
                lane_change[i] = 0
                lane_change_start_s[i] = np.nan
            elif not present[i, target_lane[i]]:
                aborted.append(i)
                aborted_from.append(target_lane[i] - lane_change[i])
                lane_change[i] = 0
                lane_change_start_s[i] = np.nan
    return (np.array(done, dtype=np.int64), np.array(done_from, dtype=np.int64), np.array(done_duration, dtype=np.float64),
            np.array(aborted, dtype=np.int64), np.array(aborted_from, dtype=np.int64), np.array(newly_off, dtype=np.int64))


@kernel
def _step_kernel(request, throttle, time_s, time_next, lane, lane_change, target_lane, lane_change_start_s,
                 d_right, d_left, present, kappa, s, d, psi, v, accel, steer,
                 int_d, int_psi, prev_e_d, prev_e_psi, fresh,
                 lat_kp, lat_ki, lat_kd, head_kp, head_ki, head_kd, max_lat_speed, max_heading,
                 wheelbase, max_speed, max_accel, max_brake, max_steer, max_steer_step, dt,
                 off_road, lane_change_count, last_duration,
                 length_m, breaks, seg_const, dr_table, dl_table, present_table, vmax_table, w_coef, w_origin,
                 off_coef, off_origin, g_s0, g_k):
    """Steps 1 to 3 of :meth:`World.step` in one call: :func:`_advance_kernel` (``time_s``), the road look-up
    at the new positions (:meth:`World._refresh_road_lookups`: ``s`` below 0 looked up at 0, as
    ``np.maximum(s, 0.0)`` gives it) and :func:`_lane_bookkeeping_kernel` (``time_next``); the state is
    updated in place. The same operations in the same order as the three calls, so the same bits.

    Returns six arrays, packed because a compiled call pays about half a microsecond for every array it
    hands back (docs/performance.md "Per-step work of the world and of the BV drivers"): the
    :class:`~evoscen_sim.road.road_model.LaneLookup` borders and speed limits as one ``(3, N, lanes)`` array
    (``d_right``, ``d_left``, ``max_speed_mps``), its ``present``, the executed lane changes and the lanes
    as one ``(2, N)`` integer array, the curvature and each vehicle's speed limit in its lane after the
    bookkeeping (:attr:`World.speed_limit_mps`) as one ``(2, N)`` array; then the bookkeeping's changes as one integer array
    ``[n_done, n_aborted, n_off, done…, done_from…, aborted…, aborted_from…, newly_off…]`` and the
    completed changes' durations."""
    executed, _reset = _advance_kernel(request, throttle, time_s, lane, lane_change, target_lane, lane_change_start_s,
                                       d_right, d_left, present, kappa, s, d, psi, v, accel, steer,
                                       int_d, int_psi, prev_e_d, prev_e_psi, fresh,
                                       lat_kp, lat_ki, lat_kd, head_kp, head_ki, head_kd, max_lat_speed, max_heading,
                                       wheelbase, max_speed, max_accel, max_brake, max_steer, max_steer_step, dt)
    n = s.shape[0]
    s_road = np.empty(n)
    for i in range(n):  # np.maximum(s, 0.0): NaN kept, -0.0 kept
        x = s[i]
        s_road[i] = x if (x >= 0.0 or x != x) else 0.0
    dr, dl, here, vmax, lane_now, kap = lane_lookup_kernel(s_road, d, length_m, breaks, seg_const, dr_table, dl_table,
                                                           present_table, vmax_table, w_coef, w_origin, off_coef,
                                                           off_origin, g_s0, g_k)
    done, done_from, done_duration, aborted, aborted_from, newly_off = _lane_bookkeeping_kernel(
        lane_now, here, time_next, lane, off_road, lane_change, target_lane, lane_change_start_s, lane_change_count,
        last_duration)
    lane_floats = np.empty((3, n, here.shape[1]))
    lane_floats[0] = dr
    lane_floats[1] = dl
    lane_floats[2] = vmax
    ints = np.empty((2, n), dtype=np.int64)
    ints[0] = executed
    ints[1] = lane_now
    per_vehicle = np.empty((2, n))
    per_vehicle[0] = kap
    for i in range(n):  # max_speed_mps[rows, lane]
        per_vehicle[1, i] = vmax[i, lane[i]]
    nd, na, no = done.shape[0], aborted.shape[0], newly_off.shape[0]
    changes = np.empty(3 + 2 * nd + 2 * na + no, dtype=np.int64)
    changes[0], changes[1], changes[2] = nd, na, no
    changes[3:3 + nd] = done
    changes[3 + nd:3 + 2 * nd] = done_from
    k = 3 + 2 * nd
    changes[k:k + na] = aborted
    changes[k + na:k + 2 * na] = aborted_from
    changes[k + 2 * na:] = newly_off
    return lane_floats, here, ints, per_vehicle, changes, done_duration


TABLE_FIELDS = ("id", "role", "policy", "x", "y", "yaw", "s", "d", "heading_rel", "speed", "accel", "steer", "lane",
                "target_lane", "lane_change", "length", "width")
""":meth:`World.table`'s columns: the contract's ``WORLD_FIELDS`` (a test holds them equal)."""


@kernel
def _world_table_kernel(s, d, psi, v, accel, steer, length, width, ids, role, policy, lane, target_lane, lane_change,
                        g_s0, g_x0, g_y0, g_h0, g_k):
    """:meth:`World.table`: :func:`state_columns` (``x``, ``y`` and the heading at ``s`` below 0 taken at 0, as
    ``np.maximum(s, 0.0)``; ``yaw`` = heading + ``heading_rel``) as float64 rows in :data:`TABLE_FIELDS` order."""
    n = s.shape[0]
    s_road = np.empty(n)
    for i in range(n):  # np.maximum(s, 0.0): NaN kept, -0.0 kept
        x = s[i]
        s_road[i] = x if (x >= 0.0 or x != x) else 0.0
    x, y, h = frenet_to_cartesian_kernel(s_road, d, g_s0, g_x0, g_y0, g_h0, g_k)
    t = np.empty((n, 17))
    for i in range(n):
        t[i, 0] = ids[i]
        t[i, 1] = role[i]
        t[i, 2] = policy[i]
        t[i, 3] = x[i]
        t[i, 4] = y[i]
        t[i, 5] = h[i] + psi[i]
        t[i, 6] = s[i]
        t[i, 7] = d[i]
        t[i, 8] = psi[i]
        t[i, 9] = v[i]
        t[i, 10] = accel[i]
        t[i, 11] = steer[i]
        t[i, 12] = lane[i]
        t[i, 13] = target_lane[i]
        t[i, 14] = lane_change[i]
        t[i, 15] = length[i]
        t[i, 16] = width[i]
    return t
