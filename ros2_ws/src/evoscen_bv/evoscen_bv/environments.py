"""Training environments over the simulation core (docs/method.md §3.3): same world, same step.

Both environments step :class:`evoscen_sim.physics.world.World` — the dynamics, PID control,
lane-change execution, collision test and re-entry of evaluation runs — and differ only
in who drives which vehicle.

* :class:`CarFollowingEnv` (stage ``control``): the ego follows one leader in a mainline
  lane of the real road. The leader drives a random acceleration profile (a new target
  acceleration in [-2.5, 1.5] m/s² every 2-5 s, kept between 8 and 32 m/s), the ego starts
  5-90 m behind at -5..+10 m/s of the leader's speed; in 1 of 5 episodes the leader stands
  still 40-100 m ahead (a queue, or the end of the merge lane, which learned BVs treat as a
  standing leader) and the ego comes at 10-30 m/s. One step = one simulation step.
* :class:`DecisionEnv` (stages ``level1`` … ``cooperative``): a full 21-vehicle scenario
  world (the shipped default scenario, seeded per episode; the ego is a random vehicle,
  so it starts on the merge lane in about 1 of 7 episodes). The other vehicles run the
  frozen lower-level traffic: level-0 drivers, or learned drivers with a frozen decision
  policy (mutual); every vehicle, the ego included, drives longitudinally with the trained
  controller (level-0 drivers with their IDM). One step = one decision: the world runs
  until the next decision point (``step_index % N == 0`` with the ego not changing lanes).
  [choice] An ego collision ends the episode (terminal); the rewards have no collision
  term of their own (the rule constraints prevent cut-ins within 10 m).
  The run-time rules of every learned driver here (ego and traffic: reaction time, bounded
  braking, emergency brake, cut-in gap) are those of the config's ``env.profile``
  (docs/bv-profiles.md), so the policies learn with the driver they will run with.
* ``env.makeup: highd`` (docs/learned-bvs.md, "Trained among the highD make-up"): the decision
  environments carry the traffic the policies meet under ``bvs.makeup: highd`` — the traffic window
  (with its warm-up) around a SUT slot driven as traffic, trucks driven by the truck driver, every
  BV car with its drawn highD desired speed, uncapped, and the cars' approach braking (the ego's
  too). The ego is a car drawn among those at least :data:`EGO_EDGE_M` inside the window's edges;
  its episode ends (truncated, not terminal) when the window takes it out, and that last
  decision's next drivable area is the one it chose (it is elsewhere after a re-entry).

Every episode is built from its own seed (the pipeline derives it from the stage seed and
the episode index), so an episode can be replayed alone and a resumed run continues
exactly.
"""

from __future__ import annotations

import numpy as np
from evoscen_sim.loop.hand_built import hand_built_world

from .car_following import (
    CarFollowingParams,
    car_following_reward,
    compose_throttle,
    controller_observations,
    speed_cap_throttle,
)
from .lane_change_decision import (
    OBS_DIM,
    action_to_lane_change,
    apply_rule_constraints,
    drivable_area,
    individual_reward,
    observation_grid,
    social_reward,
    social_terms,
)
from .learned import LearnedDriver
from .profile import get_profile
from .td3 import NumpyActor
from .training_config import TrainingConfig

MUTUAL_CODE = 1
EGO_EDGE_M = 50.0
"""``env.makeup: highd``: the ego is drawn among the cars at least this far inside the window's edges."""


class CarFollowingEnv:
    """Car following behind a leader with a random acceleration profile (see module docstring)."""

    state_dim = 4
    STANDING_SHARE = 0.2
    """Share of episodes with a standing leader (approach and stop behind it)."""

    def __init__(self, road, config: TrainingConfig) -> None:
        self.road = road
        self.config = config
        self.params: CarFollowingParams = config.car_following
        self.world = None

    def reset(self, seed: int) -> np.ndarray:
        rng = np.random.default_rng(seed)
        lane = int(rng.integers(1, 5))
        self.standing = bool(rng.random() < self.STANDING_SHARE)
        s0 = float(rng.uniform(100.0, 300.0))
        if self.standing:  # a standing obstacle (a queue, the end of the merge lane) ahead
            v_lead = 0.0
            gap = float(rng.uniform(40.0, 100.0))
            v_ego = float(rng.uniform(10.0, 30.0))
        else:
            v_lead = float(rng.uniform(10.0, 28.0))
            gap = float(rng.uniform(5.0, 90.0))
            v_ego = max(0.0, v_lead + float(rng.uniform(-5.0, 10.0)))
        self.world = hand_built_world(self.road, s=[s0, s0 + gap + 5.0], lane=[lane, lane], speed=[v_ego, v_lead],
                                      seed=seed)
        self.rng = rng
        lo, hi = self.config.env.desired_speed_mps
        self.desired = float(rng.uniform(lo, hi))
        self.lead_accel = 0.0
        self.lead_until = 0
        self.t = 0
        self.obs = self._observe()
        return self.obs

    def _observe(self) -> np.ndarray:
        own, _ = controller_observations(self.world, np.array([0]), self.params)
        return own[0]

    def leader_throttle(self) -> float:
        w = self.world
        if self.standing:
            return -1.0
        if self.t >= self.lead_until:
            self.lead_accel = float(self.rng.uniform(-2.5, 1.5))
            self.lead_until = self.t + int(self.rng.integers(20, 51))
        a = self.lead_accel
        if w.v[1] < 8.0:
            a = max(a, 0.5)
        elif w.v[1] > 32.0:
            a = min(a, -0.5)
        vp = w.vehicle
        return a / vp.max_accel_mps2 if a >= 0 else a / vp.max_brake_mps2

    def ego_throttle(self, action: float) -> float:
        w = self.world
        vp = w.vehicle
        desired = float(np.fmin(self.desired, w.speed_limit_mps[0]))
        cap = speed_cap_throttle(w.v[:1], np.array([desired]), self.params, vp.max_accel_mps2, vp.max_brake_mps2)
        o = self.obs[None, :]
        return float(compose_throttle(np.array([action]), np.array([action]), o, o, cap)[0])

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        """(next obs, reward, terminal, truncated, info); info has the gap (m) and collision flag."""
        w = self.world
        throttle = np.array([self.ego_throttle(float(action[0])), self.leader_throttle()])
        result = w.step(throttle, np.zeros(2, dtype=np.int64))
        self.t += 1
        collided = any(0 in pair for pair in result.collisions)
        next_obs = self._observe()
        reward = float(car_following_reward(self.obs[None], next_obs[None], np.array([collided]), self.params)[0])
        self.obs = next_obs
        truncated = self.t >= self.config.env.control_episode_steps
        gap = float(w.neighborhood().gap_front_m[0, 2])
        return next_obs, reward, collided, truncated, {"gap_m": gap, "collision": collided, "speed": float(w.v[0])}


class DecisionEnv:
    """One learning ego among frozen lower-level traffic (see module docstring).

    Args:
        road: the road model.
        config: the training config.
        kind: the ego's reward: ``mutual``, ``competitive`` or ``cooperative``.
        controller: the trained car-following actor.
        frozen_policy: the surrounding vehicles' decision actor; ``None`` = level-0 traffic.
    """

    state_dim = OBS_DIM

    def __init__(self, road, config: TrainingConfig, kind: str, controller: NumpyActor,
                 frozen_policy: NumpyActor | None) -> None:
        from evoscen_sim.config.scenario_config import config_from_dict

        self.road = road
        self.config = config
        self.kind = kind
        self.controller = controller
        self.frozen_policy = frozen_policy
        self._config_from_dict = config_from_dict
        social_reward(kind, 0.0, 0.0, 0.0, config.reward)  # validates kind
        self.profile = get_profile(config.env.profile)
        """The run-time rule profile every learned driver here drives with (docs/bv-profiles.md)."""

    def reset(self, seed: int) -> np.ndarray:
        if self.config.env.makeup == "highd":
            return self._reset_makeup(seed)
        from evoscen_sim.scenario_builders import build_world

        from evoscen_bv.level0 import Level0Driver, level0_params_from_config

        rng = np.random.default_rng(seed)
        n_bv = self.config.env.bv_count
        cfg = self._config_from_dict({
            "seed": int(rng.integers(0, 2**31 - 1)),
            "bvs": {"count": n_bv, "driver": "level0", "makeup": "uniform"},
            "sut": {"lane": int(rng.integers(1, 5)), "s_m": float(rng.uniform(200.0, 700.0))},
            # jitter below 5 m: a larger one can put the first ramp vehicle before the merge lane starts
            "spawn": {"ramp_vehicles": min(3, n_bv), "jitter_m": 4.0},
            # the design the shipped policies were trained in: the spawn block, re-entry at the road's start
            "traffic": {"mode": "loop"},
        }, source="<training environment>")
        world = build_world(cfg, self.road)
        self.world = world
        n = world.n
        self.ego = int(rng.integers(0, n))
        others = np.array([i for i in range(n) if i != self.ego], dtype=np.int64)
        vp = cfg.vehicle
        world.policy[:] = MUTUAL_CODE if self.frozen_policy is not None else 0
        if self.frozen_policy is None:
            self.traffic = Level0Driver(others, level0_params_from_config(cfg), rng, vp)
        else:
            self.traffic = LearnedDriver(others, self.controller, {MUTUAL_CODE: self.frozen_policy}, self.config,
                                         rng, vp)
        self.ego_driver = LearnedDriver(np.array([self.ego]), self.controller, {}, self.config, rng, vp)
        self.others = others
        self.ego_bound = None
        return self._start()

    def _start(self) -> np.ndarray:
        self.decisions = 0
        self.lane_changes = 0
        self.collisions = 0
        self.left = False
        self._advance_to_decision(np.int64(0))
        self.obs = self._observe()
        return self.obs

    def _reset_makeup(self, seed: int) -> np.ndarray:
        """``env.makeup: highd`` (module docstring): the traffic window with the highD make-up around a SUT
        slot driven as traffic; the ego a car of the window."""
        import evoscen_bv.bv_models  # noqa: F401  (registers the make-up's driver, used by the warm-up)
        from evoscen_sim.scenario_builders import build_world, bv_makeup

        from evoscen_bv.level0 import Level0Driver, level0_params_from_config

        from .truck import MakeupDriver, TruckDriver, TruckParams

        rng = np.random.default_rng(seed)
        n_bv = self.config.env.bv_count
        cfg = self._config_from_dict({
            "seed": int(rng.integers(0, 2**31 - 1)),
            "bvs": {"count": n_bv, "driver": "level0", "makeup": "highd"},
            "sut": {"lane": int(rng.integers(1, 5))},
            "traffic": {"mode": "window"},
        }, source="<training environment>")
        world = build_world(cfg, self.road)  # (the window's warm-up included: traffic that has settled)
        self.world = world
        makeup = bv_makeup(cfg)
        truck_of = np.zeros(world.n, dtype=bool)  # by world index: the SUT (0) is a car
        truck_of[1:] = makeup.truck
        desired = np.full(world.n, np.nan)
        desired[1:] = makeup.desired_speed_mps
        cars = np.flatnonzero(~truck_of[1:]) + 1
        # [choice] the ego is a car at least EGO_EDGE_M inside the window's edges (where the SUT's traffic
        # is; one at an edge, or outside waiting for a place, would leave at once); any car if none is
        p = world.window.p
        rel = world.s[cars] - world.s[0]
        inner = cars[(rel >= -p.behind_m + EGO_EDGE_M) & (rel <= p.ahead_m - EGO_EDGE_M)]
        pool = inner if inner.size else cars
        self.ego = int(pool[rng.integers(0, pool.size)])
        others = np.array([i for i in range(world.n) if i != self.ego], dtype=np.int64)
        vp = cfg.vehicle
        world.policy[:] = MUTUAL_CODE if self.frozen_policy is not None else 0
        car_others = others[~truck_of[others]]
        if self.frozen_policy is None:
            car_driver = Level0Driver(car_others, level0_params_from_config(cfg), rng, vp)
        else:
            car_driver = LearnedDriver(car_others, self.controller, {MUTUAL_CODE: self.frozen_policy}, self.config,
                                       rng, vp)
        # BV cars take their drawn wishes, uncapped; the SUT slot keeps its driver's draw (a car near the limit)
        bv_car = car_others > 0
        car_driver.desired_speed_mps[bv_car] = desired[car_others[bv_car]]
        car_driver.speed_cap = False
        truck_params = cfg.models.get("truck") or TruckParams()
        trucks = TruckDriver(others[truck_of[others]], truck_params, desired[others[truck_of[others]]], vp)
        self.traffic = MakeupDriver(others, truck_of[others], car_driver, trucks)
        self.ego_driver = LearnedDriver(np.array([self.ego]), self.controller, {}, self.config, rng, vp)
        self.ego_driver.desired_speed_mps[:] = desired[self.ego]
        self.ego_driver.speed_cap = False
        # the ego's throttle takes the cars' approach braking, as every car of the make-up at run time
        self.ego_bound = MakeupDriver(np.array([self.ego]), np.zeros(1, dtype=bool), self.ego_driver,
                                      TruckDriver(np.zeros(0, dtype=np.int64), truck_params, np.zeros(0), vp))
        self.others = others
        return self._start()

    def _observe(self) -> np.ndarray:
        return observation_grid(self.world, np.array([self.ego]), self.config.grid).reshape(OBS_DIM)

    def _advance_to_decision(self, first_request: np.int64) -> bool:
        """Step the world (the ego's request on the first step) to the next decision point; True on an ego collision."""
        w = self.world
        n = w.n
        N = self.config.env.decision_interval_steps
        request_ego = int(first_request)
        collided = False
        for k in range(20 * N):
            if k > 0 and w.step_index % N == 0 and w.lane_change[self.ego] == 0:
                break
            throttle = np.empty(n)
            request = np.zeros(n, dtype=np.int64)
            t_o, r_o = self.traffic.act(w)
            throttle[self.others] = t_o
            request[self.others] = r_o
            ego_throttle = self.ego_driver.throttle(w)
            if self.ego_bound is not None:
                ego_throttle = self.ego_bound.approach_bound(w, np.asarray(ego_throttle, dtype=float))
            throttle[self.ego] = ego_throttle[0]
            request[self.ego] = request_ego
            request_ego = 0
            result = w.step(throttle, request)
            if any(self.ego in pair for pair in result.collisions):
                collided = True
                break
            if w.window is not None and self._ego_left(result):
                self.left = True  # the window took the ego out (or re-entered it elsewhere): the episode ends
                break
        return collided

    def _ego_left(self, result) -> bool:
        """Whether the ego left the traffic window in the step of ``result`` (``env.makeup: highd``)."""
        if any(r[0] == self.ego for r in result.reentries):
            return True
        p = self.world.window.p
        rel = float(self.world.s[self.ego] - self.world.s[0])
        return rel > p.ahead_m + p.exit_margin_m or rel < -(p.behind_m + p.exit_margin_m)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        """One decision: (next obs, reward, terminal, truncated, info)."""
        w = self.world
        p = self.config.reward
        ego = np.array([self.ego])
        requested = action_to_lane_change(np.asarray(action, dtype=float)[:1])
        executed = apply_rule_constraints(w, ego, requested, self.profile.cut_in_closing_headway_s,
                                          self.profile.cut_in_closing_decel_mps2)
        o_c = drivable_area(w, ego, np.zeros(1, dtype=np.int64), p.front_view_m)
        o_t = drivable_area(w, ego, executed, p.front_view_m)
        theta = np.where(executed > 0, p.theta_left, 1.0)
        collided = self._advance_to_decision(executed[0])
        self.decisions += 1
        self.lane_changes += int(executed[0] != 0)
        self.collisions += int(collided)
        # an ego the window took out is somewhere else now: its lane's area then is the one it chose
        o_c_next = o_t if self.left else drivable_area(w, ego, np.zeros(1, dtype=np.int64), p.front_view_m)
        r_i = float(individual_reward(o_c, o_t, theta, requested, executed, o_c_next, p, self.kind)[0])
        space, brake, speed = social_terms(w, self.ego, p)
        reward = r_i + social_reward(self.kind, space, brake, speed, p)
        self.obs = self._observe()
        truncated = self.decisions >= self.config.env.decision_episode_decisions or (self.left and not collided)
        return self.obs, reward, collided, truncated, {
            "requested": int(requested[0]), "executed": int(executed[0]), "collision": collided,
            "speed": float(w.v[self.ego]),
        }
