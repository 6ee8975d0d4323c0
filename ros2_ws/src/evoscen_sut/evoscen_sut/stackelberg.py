"""Stackelberg lane-change decision (docs/method.md §4.3; Yoo & Langari, ASME DSCC 2012).

The ego vehicle is the game's *leader*; the two most relevant other vehicles are its
*followers*. The leader chooses among nine actions, {accelerate, keep, decelerate} ×
{keep lane, left, right}; each follower among {accelerate, keep, decelerate}. Every action
profile is scored on the states predicted a short horizon ahead with

* ``U_pos = min(d_front, d_v)`` — the free space ahead of the ego in its lane after its
  action (``d_v`` if nobody is ahead), and
* ``U_neg = d_back − v_r·T − d_min`` — the gap behind it less the time-headway margin for
  the closing speed of the vehicle behind, less a minimum gap,

and the leader picks ``argmax_leader min_followers (U_pos + U_neg)``: the action whose
*worst case* over the followers' responses is best. Only the lane component of that
action is used (the lane-change request); see "Longitudinal control" below.

Readings (the source paper is not available to us; every choice is a parameter or is
stated here — docs/method.md §4.3 marks the overall reading):

* **The three steps** (docs/method.md §4.3: "three-step leader/followers/leader game") are three phases of
  ``horizon_s`` each, predicted with constant-acceleration kinematics:

  1. the leader applies its action (acceleration ``a1`` and lane) while the followers,
     who have not yet seen it, keep their speed;
  2. the followers respond (each its own acceleration) while the leader holds ``a1``;
  3. the leader moves again: a second acceleration ``a2`` from the same three choices,
     the lane kept, chosen as the leader's best reply to the followers' response
     (``max`` over ``a2``); the followers hold their response.

  The payoff of (leader action, follower response) is the best-``a2`` payoff at the end
  of phase 3 — one entry of the 9 × 9 matrix :func:`game_values` returns. ``steps = 2``
  stops after phase 2 (no second leader move), ``steps = 1`` after phase 1 (the
  followers never respond: every column is equal). Speeds never go below 0 (a braking
  vehicle stops and stays); there is no upper speed cap in the prediction (3 s horizons).
* **Lane after the action**: a lane action moves the ego into the target lane for the
  whole prediction (a change takes a few seconds, the order of the game's horizon). The
  payoff then uses the vehicles ahead and behind *in that lane*.
* **Vehicles considered**: the nearest vehicle ahead and behind in the own lane and in
  each adjacent lane (the simulator's neighbourhood, by centre-of-mass lane) — up to six
  *candidates*. Gaps are bumper to bumper (signed: a predicted overlap is a negative gap).
  The end of a lane that ends (the merge lane I at 960 m) is a standing obstacle at
  ``lane_end_s`` in that lane, so ``d_front`` is the smaller of the gap to the vehicle
  ahead and the distance to the lane's end.
* **The two most relevant followers** ("players"): the two candidates with the smallest
  gap predicted at the end of the game if everyone kept their speed
  (``gap + closing_speed_away · steps · horizon_s``, i.e. the gap the game is about), ties
  broken in the order right-ahead, right-behind, own-ahead, own-behind, left-ahead,
  left-behind. The other candidates keep their speed. With fewer than two candidates the
  missing player has no influence (its three responses give equal columns), so the matrix
  is always 9 × 9.
* **``U_neg`` without a vehicle behind** is ``d_v − d_min`` (nobody within view), and
  ``d_back − v_r·T`` is capped at ``d_v`` like ``d_front`` is in ``U_pos`` — beyond the
  view distance nothing differs. ``v_r = v_back − v_ego`` (positive when it closes in).
* **Availability**: a lane action into a lane that does not exist at the ego's position is
  not available (its row is ``-inf``); while a lane change is in progress no change is
  requested (the decision is 0 and the game is not played).
* **d_min to every vehicle in the target lane** (``target_gap_rule``; docs/method.md §4.3, "The safety
  distance of a lane change"): the method judges a lane change by the nearest vehicles ahead and behind
  in the target lane with a safety distance d_min "of conducting a lane-change action". With
  ``d_min_now`` (default) a lane action is not available while the bumper-to-bumper gap to the nearest
  vehicle ahead or behind in its lane *now* is below ``min_gap_m``; a vehicle alongside (bodies
  overlapping longitudinally: a negative gap) always is. Under this rule a vehicle is in the target lane
  when its lane or its target lane is that lane, except one leaving it on the far side — the vehicles
  the evaluation's *beside* rule looks at (docs/evaluation.md §3.7): the game's vehicle ahead and behind
  in the target lane are the nearer of those and of the neighbourhood's by centre, so a truck crawling
  into the lane from two lanes over is the leader the game plays against, not an empty lane. [choice] With ``end_of_game`` (the rule before)
  only the gaps predicted at the end of the game count, so a faster vehicle alongside that would be
  ahead by then does not stop the change (measured: about half of intact Stackelberg's exposures were
  lane changes started beside a vehicle, docs/sensitivity.md).
* **Hysteresis** (our choice): a lane change is requested only if its worst-case value
  beats the best keep-lane worst-case value by more than ``lane_change_threshold_m``;
  ties (an empty road) keep the lane.

Longitudinal control: docs/method.md §4 — "only the lane-change decision differs between SUTs; car
following uses Krauss". The game's acceleration component only serves to value the lane
choice (the leader may plan to accelerate into a gap); the command sent to the vehicle is
SUMO's Krauss acceleration (:mod:`evoscen_sut.krauss`) behind the leader in the own lane —
and, while a lane change is requested or in progress, the smaller of that and the Krauss
acceleration behind the leader in the target lane.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from evoscen_sim.config.scenario_config import integer, number, text
from evoscen_sim.danger.safety import enters_or_holds_lane
from evoscen_sim.jit import kernel
from evoscen_sim.model_registry import ModelSpec
from evoscen_sim.physics.neighbors import LEFT, OWN, RIGHT

LEADER_ACTIONS: tuple[tuple[int, str], ...] = tuple(
    (lane, accel) for lane in (0, +1, -1) for accel in ("keep", "accelerate", "decelerate")
)
"""Rows of the payoff matrix: (lane offset, acceleration choice). Keep-lane rows come first so
that ties keep the lane (``argmax`` takes the first maximum)."""
FOLLOWER_ACTIONS: tuple[str, ...] = ("accelerate", "keep", "decelerate")
"""One follower's responses."""
FOLLOWER_RESPONSES: tuple[tuple[str, str], ...] = tuple((a, b) for a in FOLLOWER_ACTIONS for b in FOLLOWER_ACTIONS)
"""Columns of the payoff matrix: (first player's response, second player's response)."""
CANDIDATE_SLOTS: tuple[tuple[int, str], ...] = tuple((lane, side) for lane in (-1, 0, +1) for side in ("ahead", "behind"))
"""The six candidate followers: (lane offset, ahead/behind), in tie-break order."""

_COLUMNS = np.array([RIGHT, OWN, LEFT], dtype=np.int64)  # neighbourhood columns of lane offsets -1, 0, +1
TARGET_GAP_RULES: tuple[str, ...] = ("d_min_now", "end_of_game")
_NO_ENTERING = (np.full(3, np.inf), np.full(3, np.nan), np.full(3, np.inf), np.full(3, np.nan))
"""Values of :attr:`StackelbergParams.target_gap_rule`."""


@dataclass(frozen=True)
class StackelbergParams:
    """Stackelberg lane-change decision parameters (module docstring: the readings)."""

    horizon_s: float = number(1.0, 0.0, 10.0, lo_open=True)
    """Prediction horizon of one game step (s), in (0, 10]. Our choice: 1 s per step, 3 s
    for the whole game — the order of a lane change's duration."""
    steps: int = integer(3, 1, 3)
    """Game steps, 1..3: 3 = leader → followers → leader (docs/method.md §4); 2 stops after the
    followers' response, 1 after the leader's move."""
    leader_accel_mps2: float = number(2.0, 0.0, 10.0)
    """The leader's "accelerate" (m/s²), [0, 10]. Our choice, below Krauss's accel 2.6."""
    leader_decel_mps2: float = number(3.0, 0.0, 10.0)
    """The leader's "decelerate" magnitude (m/s²), [0, 10]. Our choice, below Krauss's decel 4.5."""
    follower_accel_mps2: float = number(2.0, 0.0, 10.0)
    """A follower's "accelerate" (m/s²), [0, 10]. Our choice (as the leader's)."""
    follower_decel_mps2: float = number(3.0, 0.0, 10.0)
    """A follower's "decelerate" magnitude (m/s²), [0, 10]. Our choice (as the leader's)."""
    view_distance_m: float = number(100.0, 0.0, lo_open=True)
    """d_v: the payoff's view distance (m), > 0; U_pos when nobody is ahead, and the cap of
    both payoff terms. 100 m (our choice; docs/method.md §3.2's grid also sees ~100 m ahead)."""
    time_headway_s: float = number(1.5, 0.0)
    """T: time headway applied to the closing speed of the vehicle behind in U_neg (s), >= 0.
    Our choice: 1.5 s, the IDM highway value of docs/method.md §4.2."""
    min_gap_m: float = number(2.5, 0.0)
    """d_min: minimum gap subtracted in U_neg (m), >= 0. SUMO/Krauss minGap 2.5 m."""
    lane_change_threshold_m: float = number(1.0, 0.0)
    """Hysteresis (m of payoff), >= 0: a change is requested only if its worst-case value
    exceeds the best keep-lane worst-case value by more than this. Our choice."""
    target_gap_rule: str = text("d_min_now", TARGET_GAP_RULES)
    """How d_min applies to the target lane (module docstring): ``d_min_now`` (default) the current gaps
    to its nearest vehicles ahead and behind must be at least ``min_gap_m`` — a vehicle alongside never
    lets the change start; ``end_of_game`` only the gaps predicted at the game's end count (the rule of
    evoscen 0.6)."""


# ------------------------------------------------------------------------------------------
# The game (pure functions)
# ------------------------------------------------------------------------------------------


@kernel
def _target_lane_neighbours(i, s, v, length, lane, target_lane):
    """Per lane offset -1, 0, +1 (offset 0 not used): the vehicle ahead and the vehicle behind ``i`` with the
    smallest bumper-to-bumper gap among those whose lane or target lane is lane ``lane[i]`` + offset, except
    one in it leaving it on the far side (``target_gap_rule: d_min_now``; module docstring). Returns
    ``(gap ahead, its speed, gap behind, its speed)``, arrays of 3 (``inf`` / ``nan`` where none); a vehicle
    level with ``i`` counts as behind, as in the neighbourhood."""
    gap_f = np.full(3, np.inf)
    v_f = np.full(3, np.nan)
    gap_r = np.full(3, np.inf)
    v_r = np.full(3, np.nan)
    for l in (0, 2):
        off = l - 1
        tgt = lane[i] + off
        away = tgt + off
        for j in range(s.shape[0]):
            if j == i or not enters_or_holds_lane(lane[j], target_lane[j], tgt, away):
                continue
            gap = abs(s[j] - s[i]) - 0.5 * (length[j] + length[i])
            if s[j] > s[i]:
                if gap < gap_f[l]:
                    gap_f[l] = gap
                    v_f[l] = v[j]
            elif gap < gap_r[l]:
                gap_r[l] = gap
                v_r[l] = v[j]
    return gap_f, v_f, gap_r, v_r


def _game_inputs(view, i: int, params: StackelbergParams) -> tuple:
    """Arguments of :func:`_game_kernel` for vehicle ``i``."""
    nb = view.neighborhood()
    road = view.road
    d_min_now = params.target_gap_rule == "d_min_now"
    entering = (_target_lane_neighbours(int(i), view.s, view.v, view.length, view.lane, view.target_lane)
                if d_min_now else _NO_ENTERING)
    return (int(i), int(view.lane[i]), float(view.s[i]), float(view.v[i]), float(view.length[i]),
            nb.gap_front_m, nb.leader_speed_mps, nb.gap_rear_m, nb.follower_speed_mps,
            road.lane_start_s, road.lane_end_s, float(road.length_m),
            float(params.horizon_s), int(params.steps),
            float(params.leader_accel_mps2), float(params.leader_decel_mps2),
            float(params.follower_accel_mps2), float(params.follower_decel_mps2),
            float(params.view_distance_m), float(params.time_headway_s), float(params.min_gap_m),
            float(params.lane_change_threshold_m), d_min_now, *entering)


def game_values(view, i: int, params: StackelbergParams = StackelbergParams()) -> np.ndarray:
    """The 9 × 9 payoff matrix of vehicle ``i``'s game: rows :data:`LEADER_ACTIONS`, columns
    :data:`FOLLOWER_RESPONSES` of the players :func:`relevant_followers` names; ``-inf`` rows
    are unavailable lane actions. Entry = ``U_pos + U_neg`` (m) at the end of the game, with
    the leader's best second move (``steps = 3``)."""
    return _game_kernel(*_game_inputs(view, i, params))[0]


def relevant_followers(view, i: int, params: StackelbergParams = StackelbergParams()) -> np.ndarray:
    """World indices of vehicle ``i``'s two players (first, second; -1 where none)."""
    slots = _game_kernel(*_game_inputs(view, i, params))[1]
    nb = view.neighborhood()
    out = np.full(2, -1, dtype=np.int64)
    for k, slot in enumerate(slots):
        if slot >= 0:
            col = _COLUMNS[slot // 2]
            out[k] = (nb.leader if slot % 2 == 0 else nb.follower)[i, col]
    return out


def decide(payoff: np.ndarray, threshold_m: float) -> int:
    """Lane offset chosen from a payoff matrix: the best worst case (first maximum, so ties keep
    the lane), a change only if it beats the best keep-lane worst case by more than ``threshold_m``."""
    worst = payoff.min(axis=1)
    best = int(np.argmax(worst))
    lane = LEADER_ACTIONS[best][0]
    if lane != 0 and worst[best] - worst[:3].max() <= threshold_m:
        return 0
    return lane


def lane_change_decision(view, vehicles: np.ndarray, params: StackelbergParams = StackelbergParams()) -> np.ndarray:
    """Lane-change requests in {-1, 0, +1} of ``vehicles`` (world indices): 0 while a change is
    in progress, else the lane of the best worst-case leader action (module docstring)."""
    vehicles = np.asarray(vehicles, dtype=np.int64)
    out = np.zeros(vehicles.size, dtype=np.int64)
    for k, i in enumerate(vehicles):
        if view.lane_change[i] != 0:
            continue
        out[k] = _game_kernel(*_game_inputs(view, int(i), params))[2]
    return out


@kernel
def _advance(x, v, a, t):
    """Position and speed after ``t`` at constant ``a`` from ``(x, v)``; a braking vehicle stops at 0."""
    if a < 0.0 and v + a * t < 0.0:
        t_stop = v / -a
        return x + v * t_stop + 0.5 * a * t_stop * t_stop, 0.0
    return x + v * t + 0.5 * a * t * t, v + a * t


@kernel
def _travel(v, a_phase, n, tau):
    """Distance travelled and final speed over ``n`` phases of ``tau`` with accelerations ``a_phase``."""
    x = 0.0
    for k in range(n):
        x, v = _advance(x, v, a_phase[k], tau)
    return x, v


@kernel
def _players(exists, gap_f, v_f, gap_r, v_r, v_e, duration):
    """The game's two players: the candidate slots (module docstring) with the two smallest constant-speed
    gaps at the end of the game, in the tie-break order; -1 where there is none."""
    pred = np.full(6, np.inf)
    for l in range(3):
        if not exists[l]:
            continue
        if np.isfinite(gap_f[l]):
            pred[2 * l] = gap_f[l] + (v_f[l] - v_e) * duration
        if np.isfinite(gap_r[l]):
            pred[2 * l + 1] = gap_r[l] + (v_e - v_r[l]) * duration
    players = np.full(2, -1, dtype=np.int64)
    for p in range(2):
        best = np.inf
        for c in range(6):
            if c != players[0] and pred[c] < best:
                best = pred[c]
                players[p] = c
    return players


@kernel
def _game_kernel(i, lane, s, v_e, len_e, gap_front, leader_speed, gap_rear, follower_speed,
                 lane_start, lane_end, road_length, tau, n, leader_up, leader_down, follower_up, follower_down,
                 d_v, headway, d_min, threshold, d_min_now, ent_gap_f, ent_v_f, ent_gap_r, ent_v_r):
    """Payoff matrix (9 × 9), the players' candidate slots and the decided lane offset.

    Lane arrays are over offsets -1, 0, +1; candidate slot ``2·l + 0`` is the vehicle ahead,
    ``2·l + 1`` the one behind in lane offset ``l - 1``. Positions are relative to the ego at
    time 0 (the game only needs gap changes). Lane existence: the road model keeps every lane
    in one contiguous ``[lane_start_s, lane_end_s)`` range (``RoadModel.lane_exists`` with
    ``s`` clamped to the road).
    """
    leader_acc = np.array([0.0, leader_up, -leader_down])
    follower_acc = np.array([follower_up, 0.0, -follower_down])
    exists = np.zeros(3, dtype=np.bool_)
    end_dist = np.full(3, np.inf)
    gap_f = np.empty(3)
    v_f = np.empty(3)
    gap_r = np.empty(3)
    v_r = np.empty(3)
    s_c = min(max(s, 0.0), road_length)
    for l in range(3):
        ln = lane + l - 1
        if 0 <= ln < lane_start.shape[0]:
            reaches_end = lane_end[ln] >= road_length
            exists[l] = lane_start[ln] <= s_c and (s_c < lane_end[ln] or reaches_end)
            if not reaches_end:
                end_dist[l] = lane_end[ln] - s
        col = l + 1  # neighbourhood column of offset l - 1 (RIGHT = 1, OWN = 2, LEFT = 3)
        gap_f[l] = gap_front[i, col]
        v_f[l] = leader_speed[i, col]
        gap_r[l] = gap_rear[i, col]
        v_r[l] = follower_speed[i, col]
        if d_min_now and l != 1:
            # the target lane's vehicles: those in it or entering it (not only by centre), the nearer each side
            if ent_gap_f[l] < gap_f[l]:
                gap_f[l], v_f[l] = ent_gap_f[l], ent_v_f[l]
            if ent_gap_r[l] < gap_r[l]:
                gap_r[l], v_r[l] = ent_gap_r[l], ent_v_r[l]
            if gap_f[l] < d_min or gap_r[l] < d_min:
                exists[l] = False  # d_min to the target lane's vehicles now; one alongside has a negative gap
    exists[1] = True  # keeping the lane is always an action
    duration = n * tau
    players = _players(exists, gap_f, v_f, gap_r, v_r, v_e, duration)
    # --- candidates' travel under every response of their own (index 0..2) or keeping speed
    # travel[c, r]: distance, speed[c, r]: final speed of candidate c when it responds with r
    travel = np.zeros((6, 3))
    speed = np.zeros((6, 3))
    a_phase = np.zeros(3)
    for c in range(6):
        l = c // 2
        gap = gap_f[l] if c % 2 == 0 else gap_r[l]
        if not np.isfinite(gap):
            continue
        v0 = v_f[l] if c % 2 == 0 else v_r[l]
        for r in range(3):
            a_phase[0] = 0.0  # phase 1: not yet responding
            a_phase[1] = follower_acc[r]
            a_phase[2] = follower_acc[r]
            travel[c, r], speed[c, r] = _travel(v0, a_phase, n, tau)
    # --- payoff matrix
    payoff = np.full((9, 9), -np.inf)
    keep = 1  # index of "keep" in follower_acc
    for row in range(9):
        lat = 0 if row < 3 else (1 if row < 6 else -1)
        l = lat + 1
        if not exists[l]:
            continue
        a1 = leader_acc[row % 3]
        cf, cb = 2 * l, 2 * l + 1  # the candidates ahead and behind in the ego's lane after its action
        for col in range(9):
            resp0, resp1 = col // 3, col % 3
            rf = resp0 if players[0] == cf else (resp1 if players[1] == cf else keep)
            rb = resp0 if players[0] == cb else (resp1 if players[1] == cb else keep)
            best_u = -np.inf
            for k2 in range(3 if n == 3 else 1):  # the leader's second move (phase 3)
                a_phase[0] = a1
                a_phase[1] = a1
                a_phase[2] = leader_acc[k2]
                x_e, v_e_end = _travel(v_e, a_phase, n, tau)
                d_front = end_dist[l] - 0.5 * len_e - x_e  # the lane's end (inf if it has none)
                if np.isfinite(gap_f[l]):
                    d_front = min(d_front, gap_f[l] + travel[cf, rf] - x_e)
                u_pos = min(d_front, d_v)
                if np.isfinite(gap_r[l]):
                    d_back = gap_r[l] + x_e - travel[cb, rb]
                    u_neg = min(d_back - (speed[cb, rb] - v_e_end) * headway, d_v) - d_min
                else:
                    u_neg = d_v - d_min
                best_u = max(best_u, u_pos + u_neg)
            payoff[row, col] = best_u
    # --- decision: the best worst case; first maximum (keep-lane rows first); hysteresis
    best_row = 0
    best_worst = -np.inf
    keep_worst = -np.inf
    for row in range(9):
        worst = np.inf
        for col in range(9):
            worst = min(worst, payoff[row, col])
        if row < 3:
            keep_worst = max(keep_worst, worst)
        if worst > best_worst:
            best_worst = worst
            best_row = row
    decision = 0 if best_row < 3 else (1 if best_row < 6 else -1)
    if decision != 0 and not best_worst - keep_worst > threshold:
        decision = 0
    return payoff, players, decision


# ------------------------------------------------------------------------------------------
# Driver
# ------------------------------------------------------------------------------------------


class StackelbergDriver:
    """SUT driver: Stackelberg lane decision, Krauss car following (module docstring).

    Args:
        vehicles: world indices of the vehicles it drives (one SUT in practice).
        params: the game's parameters.
        car_following: a :class:`evoscen_sut.krauss.KraussCarFollowing` (or anything with its
            ``acceleration(view, vehicles, lane_offset)``).
        vehicle_params: the scenario's :class:`evoscen_sim.physics.vehicle.VehicleParams` (throttle map).
    """

    def __init__(self, vehicles: np.ndarray, params: StackelbergParams, car_following, vehicle_params) -> None:
        self.vehicles = np.asarray(vehicles, dtype=np.int64)
        self.params = params
        self.car_following = car_following
        self.vehicle_params = vehicle_params

    def act(self, view) -> tuple[np.ndarray, np.ndarray]:
        """Throttle in [-1, 1] and lane-change request in {-1, 0, +1} per driven vehicle."""
        from evoscen_sim.physics.vehicle import accel_to_throttle

        request = lane_change_decision(view, self.vehicles, self.params)
        accel = self.car_following.acceleration(view, self.vehicles)
        # while changing lanes (requested now or in progress) also follow the target lane's leader
        direction = np.where(request != 0, request, view.lane_change[self.vehicles])
        if np.any(direction != 0):
            accel = np.minimum(accel, self.car_following.acceleration(view, self.vehicles, lane_offset=direction))
        return accel_to_throttle(accel, self.vehicle_params), request


def _factory(vehicles, params, config, rng):
    from .krauss import krauss_for

    # Krauss with the scenario's models.krauss: the same car following for every SUT (docs/method.md §4)
    return StackelbergDriver(vehicles, params if params is not None else StackelbergParams(),
                             krauss_for(config, rng), config.vehicle)


SPEC = ModelSpec(name="stackelberg", roles=("sut",), factory=_factory, params_type=StackelbergParams,
                 description="Stackelberg lane change (leader = ego, 2 followers, worst-case best response; docs/method.md §4) + Krauss")
