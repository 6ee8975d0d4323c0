"""Learned background vehicles: the trained controller and decision policies, batched.

A :class:`LearnedDriver` drives a set of vehicles. Every step it

1. builds the car-following observation of every hosted vehicle (own lane, and the target
   lane during a lane change) and runs the controller once for all of them
   (:mod:`evoscen_bv.car_following`: throttle = min over leaders in view, and the
   free-road speed term);
2. every ``decision_interval_steps`` steps (``step_index % N == 0``; the rate of training),
   builds the grid Ω_d of the hosted vehicles not changing lanes and runs **one** forward
   pass for all of them through the decision policies stacked side by side
   (:class:`StackedActors`: the first layers concatenated, the others block-diagonal), each
   vehicle reading the output of its own policy (the world's policy code: competitive,
   mutual, cooperative); then maps the output to keep/left/right and applies the rule
   constraints (:mod:`evoscen_bv.lane_change`), so only executable requests reach the world.

Inference is plain numpy (:class:`evoscen_bv.td3.NumpyActor` weights): no torch at run time,
and the in-process runner and the BV node compute the same floats.

The policy directory holds ``controller.npz``, ``mutual.npz`` (level-2 mutual),
``competitive.npz``, ``cooperative.npz`` (and ``level1_mutual.npz``), the ``training.yaml``
they were trained with, and a model card per policy. The shipped directory is
``share/evoscen_bv/policies``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from evoscen_sim.errors import InputError

from .car_following import compose_throttle, controller_observations, speed_cap_throttle
from .lane_change import OBS_DIM, action_to_lane_change, apply_rule_constraints, observation_grid
from .td3 import NumpyActor
from .training_config import TrainingConfig, load_training_config

POLICY_FILES = {"mutual": "mutual.npz", "competitive": "competitive.npz", "cooperative": "cooperative.npz"}
"""Decision policy of each policy name at run time (``mutual`` is the level-2 mutual policy)."""
CONTROLLER_FILE = "controller.npz"
POLICY_CODE = {"mutual": 1, "competitive": 2, "cooperative": 3}
"""The world's policy codes (``evoscen_sim.scenario.POLICY_CODES``)."""


def shipped_policy_dir() -> Path:
    """The shipped policies (installed share dir, else the source tree)."""
    try:
        from ament_index_python.packages import get_package_share_directory

        p = Path(get_package_share_directory("evoscen_bv")) / "policies"
        if p.is_dir():
            return p
    except Exception:  # noqa: BLE001 - no ament index: use the source tree
        pass
    return Path(__file__).resolve().parent / "policies"


class StackedActors:
    """Several actors of equal shape evaluated in one forward pass over a batch.

    ``forward(x)`` returns ``(m, P)``: column ``p`` is actor ``p``'s (1-D) action for every
    row. Layer 1 concatenates the actors' W1 side by side; layers 2 and 3 are block-diagonal,
    so each actor only sees its own hidden units.
    """

    def __init__(self, actors: list[NumpyActor]) -> None:
        if not actors:
            raise ValueError("StackedActors: no actors")
        h = actors[0].W1.shape[1]
        p = len(actors)
        self.W1 = np.concatenate([a.W1 for a in actors], axis=1)
        self.b1 = np.concatenate([a.b1 for a in actors])
        self.W2 = np.zeros((p * h, p * h))
        self.W3 = np.zeros((p * h, p))
        for k, a in enumerate(actors):
            self.W2[k * h:(k + 1) * h, k * h:(k + 1) * h] = a.W2
            self.W3[k * h:(k + 1) * h, k] = a.W3[:, 0]
        self.b2 = np.concatenate([a.b2 for a in actors])
        self.b3 = np.array([a.b3[0] for a in actors])
        self.max_action = np.array([a.max_action for a in actors])

    def forward(self, x: np.ndarray) -> np.ndarray:
        h = np.maximum(x @ self.W1 + self.b1, 0.0)
        h = np.maximum(h @ self.W2 + self.b2, 0.0)
        return self.max_action * np.tanh(h @ self.W3 + self.b3)


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
        vehicle_params: the scenario's :class:`evoscen_sim.vehicle.VehicleParams`.
        default_code: policy code used for vehicles with an unknown code.
    """

    def __init__(self, vehicles, controller: NumpyActor, decision_actors: dict[int, NumpyActor],  # noqa: ANN001
                 config: TrainingConfig, rng: np.random.Generator, vehicle_params, default_code: int = 1) -> None:
        self.vehicles = np.asarray(vehicles, dtype=np.int64)
        self.controller = controller
        self.config = config
        self.vehicle_params = vehicle_params
        self.codes = np.array(sorted(decision_actors), dtype=np.int64)
        self.stack = StackedActors([decision_actors[int(c)] for c in self.codes]) if decision_actors else None
        self.column_of_code = np.full(max(16, int(self.codes.max(initial=0)) + 1), -1, dtype=np.int64)
        self.column_of_code[self.codes] = np.arange(self.codes.size)
        self.default_column = int(self.column_of_code[default_code]) if decision_actors else -1
        lo, hi = config.env.desired_speed_mps
        self.desired_speed_mps = rng.uniform(lo, hi, size=self.vehicles.size)
        self.last_request = np.zeros(self.vehicles.size, dtype=np.int64)
        """Requested (pre-constraint) actions of the last decision, for training and tests."""

    def throttle(self, view) -> np.ndarray:  # noqa: ANN001
        """The controller's throttle for every hosted vehicle (one batched forward pass)."""
        idx = self.vehicles
        cf = self.config.car_following
        own, target = controller_observations(view, idx, cf)
        u = self.controller.forward(np.vstack([own, target]))[:, 0]
        m = idx.size
        desired = np.minimum(self.desired_speed_mps, view.speed_limit_mps[idx])
        vp = self.vehicle_params
        cap = speed_cap_throttle(view.v[idx], desired, cf, vp.max_accel_mps2, vp.max_brake_mps2)
        return compose_throttle(u[:m], u[m:], own, target, cap)

    def decide(self, view, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # noqa: ANN001
        """Decisions of the hosted vehicles at ``positions``: (grid obs, requested, executed)."""
        idx = self.vehicles[positions]
        obs = observation_grid(view, idx, self.config.grid).reshape(idx.size, OBS_DIM)
        out = self.stack.forward(obs)
        col = self.column_of_code[np.clip(view.policy[idx], 0, self.column_of_code.size - 1)]
        col = np.where(col < 0, self.default_column, col)
        requested = action_to_lane_change(out[np.arange(idx.size), col])
        executed = apply_rule_constraints(view, idx, requested)
        return obs, requested, executed

    def act(self, view) -> tuple[np.ndarray, np.ndarray]:  # noqa: ANN001
        """Throttle in [-1, 1] and lane-change request in {-1, 0, +1} for each hosted vehicle."""
        throttle = self.throttle(view)
        request = np.zeros(self.vehicles.size, dtype=np.int64)
        if self.stack is not None and view.step_index % self.config.env.decision_interval_steps == 0:
            positions = np.flatnonzero(view.lane_change[self.vehicles] == 0)
            if positions.size:
                _, requested, executed = self.decide(view, positions)
                request[positions] = executed
                self.last_request[:] = 0
                self.last_request[positions] = requested
        return throttle, request


def load_policies(directory: Path | str) -> tuple[NumpyActor, dict[int, NumpyActor], TrainingConfig]:
    """Controller, decision actors by policy code, and training config from a policy directory."""
    directory = Path(directory)
    if not directory.is_dir():
        raise InputError(f"models.learned.policy_dir: {directory} is not a directory")
    cfg_path = directory / "training.yaml"
    if not cfg_path.is_file():
        raise InputError(f"{directory}: no training.yaml (the training config the policies were trained with)")
    config = load_training_config(cfg_path)

    def _load(name: str, dim: int) -> NumpyActor:
        try:
            return load_actor(directory, name, dim)
        except ValueError as exc:
            raise InputError(str(exc)) from None

    controller = _load(CONTROLLER_FILE, 4)
    decisions = {POLICY_CODE[p]: _load(f, OBS_DIM) for p, f in POLICY_FILES.items()}
    return controller, decisions, config
