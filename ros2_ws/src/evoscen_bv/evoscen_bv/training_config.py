"""The training configuration (YAML): TD3, controller, grid, rewards, environments, stages.

One file drives the whole level-k pipeline and travels with the policies it produced (the
pipeline copies it into its output directory, and the learned driver reads the copy next
to the weights, so the decision rate and the observation scales at run time are the ones
the policies were trained with). The shipped file is ``share/evoscen_bv/config/training.yaml``
(source: ``evoscen_bv/config/training.yaml``), every key commented there.

Validation: unknown keys and values of the wrong type or out of range fail with one line
naming the file, the key and what is expected.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import yaml

from evoscen_sim.config import share_candidates
from evoscen_sim.errors import InputError
from evoscen_sim.limits import MAX_CONFIG_BYTES, MAX_TRAINING_STEPS, check_yaml_depth, read_text_limited

from .car_following import CarFollowingParams
from .lane_change import GridParams, RewardParams
from .td3 import TD3Params

STAGES = ("control", "level1", "level2", "competitive", "cooperative")
"""Pipeline stages in order (docs/method.md §3.3)."""


@dataclass(frozen=True)
class EnvParams:
    """Training environments [choice: values are ours]."""

    decision_interval_steps: int = 10
    """A lane-change decision every this many simulation steps (1 s at dt 0.1 s) for vehicles
    not already changing lanes; the same rate is used at run time. [choice] Deciding every
    step would make each decision's effect invisible to TD3 and cost 10x the grid work."""
    bv_count: int = 20
    """Vehicles around the trained ego in the decision environments (+ the ego = 21)."""
    desired_speed_mps: tuple[float, float] = (27.0, 33.0)
    """Per-vehicle desired speed of learned BVs, drawn uniformly (capped by the speed limit)."""
    control_episode_steps: int = 300
    """Length of a car-following episode (steps)."""
    decision_episode_decisions: int = 60
    """Decisions per lane-change episode (about one minute of traffic)."""
    eval_every_steps: int = 5000
    """Evaluate the deterministic policy every this many training steps; the best evaluation
    is the stage's policy (see :mod:`evoscen_bv.pipeline`)."""
    profile: str = "driver"
    """The BV run-time rule profile of the decision environments' drivers (``driver`` or
    ``safety_net``, :mod:`evoscen_bv.profile`, docs/bv-profiles.md); the copy of this file
    in a policy directory records what its policies were trained with."""


@dataclass(frozen=True)
class StageSteps:
    """Training steps of each stage: simulation steps for ``control``, decisions otherwise."""

    control: int = 40000
    level1: int = 20000
    level2: int = 20000
    competitive: int = 20000
    cooperative: int = 20000


@dataclass(frozen=True)
class TrainingConfig:
    """Everything the pipeline needs (see the shipped YAML for the meaning of each key)."""

    td3: TD3Params = field(default_factory=TD3Params)
    car_following: CarFollowingParams = field(default_factory=CarFollowingParams)
    grid: GridParams = field(default_factory=GridParams)
    reward: RewardParams = field(default_factory=RewardParams)
    env: EnvParams = field(default_factory=EnvParams)
    steps: StageSteps = field(default_factory=StageSteps)

    def to_dict(self) -> dict[str, Any]:
        out = dataclasses.asdict(self)
        out["env"]["desired_speed_mps"] = list(self.env.desired_speed_mps)
        return out


def default_config_path() -> Path:
    """The shipped training config (installed share dir, else the source tree: evoscen_bv/config/)."""
    candidates = share_candidates("config/training.yaml", "evoscen_bv",
                                  source=Path(__file__).resolve().parent / "config" / "training.yaml")
    return next((p for p in candidates[:-1] if p.is_file()), candidates[-1])


def _convert(section_type: type, raw: Any, where: str, path: str) -> Any:
    if raw is None:
        raw = {}
    if not isinstance(raw, dict):
        raise InputError(f"{where}: '{path}' must be a mapping, got {type(raw).__name__}")
    known = {f.name: f for f in fields(section_type)}
    unknown = sorted(set(raw) - set(known))
    if unknown:
        raise InputError(f"{where}: unknown key '{path}.{unknown[0]}' (expected one of {', '.join(known)})")
    kwargs = {}
    for name, value in raw.items():
        default = getattr(section_type(), name)
        key = f"{path}.{name}"
        if isinstance(default, bool):
            ok = isinstance(value, bool)
            expected = "a boolean"
        elif isinstance(default, int):
            ok = isinstance(value, int) and not isinstance(value, bool) and 1 <= value <= MAX_TRAINING_STEPS
            expected = f"an integer in [1, {MAX_TRAINING_STEPS}]"
        elif isinstance(default, float):
            ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
            expected = "a finite number"
            value = float(value) if ok else value
        elif isinstance(default, str):
            from .profile import PROFILE_NAMES

            ok = value in PROFILE_NAMES
            expected = "one of " + ", ".join(PROFILE_NAMES)
        elif isinstance(default, tuple):
            ok = (isinstance(value, list) and len(value) == 2
                  and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
                  and 0 < value[0] <= value[1])
            expected = "a list [lo, hi] of two numbers with 0 < lo <= hi"
            value = tuple(float(v) for v in value) if ok else value
        else:  # pragma: no cover - every field is one of the above
            ok, expected = True, ""
        if not ok:
            raise InputError(f"{where}: '{key}' = {value!r}: expected {expected}")
        kwargs[name] = value
    return section_type(**kwargs)


def load_training_config(path: Path | str | None = None) -> TrainingConfig:
    """Read and validate a training YAML (``None``: the shipped one)."""
    path = Path(path) if path is not None else default_config_path()
    text = read_text_limited(path, str(path), "training config", MAX_CONFIG_BYTES)
    check_yaml_depth(text, str(path), "training config")
    try:
        raw = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f":{mark.line + 1}" if mark is not None else ""
        raise InputError(f"{path}{line}: not valid YAML ({getattr(exc, 'problem', exc)})") from None
    if raw is None:
        raw = {}
    if not isinstance(raw, dict):
        raise InputError(f"{path}: expected a mapping of sections at the top level")
    sections = {f.name: f for f in fields(TrainingConfig)}
    unknown = sorted(set(raw) - set(sections))
    if unknown:
        raise InputError(f"{path}: unknown section '{unknown[0]}' (expected one of {', '.join(sections)})")
    kwargs = {name: _convert(type(f.default_factory()), raw.get(name), str(path), name)
              for name, f in sections.items()}
    cfg = TrainingConfig(**kwargs)
    for name, value in (("reward.lane_change_penalty", cfg.reward.lane_change_penalty),
                        ("reward.comp_lane_change_penalty", cfg.reward.comp_lane_change_penalty),
                        ("reward.coop_lane_change_penalty", cfg.reward.coop_lane_change_penalty),
                        ("reward.request_penalty", cfg.reward.request_penalty)):
        if value > 0:
            raise InputError(f"{path}: '{name}' = {value}: expected a number <= 0 (a penalty)")
    for name, value in (("car_following.view_m", cfg.car_following.view_m),
                        ("reward.front_view_m", cfg.reward.front_view_m),
                        ("reward.gain_norm_m2", cfg.reward.gain_norm_m2)):
        if value <= 0:
            raise InputError(f"{path}: '{name}' = {value}: expected a number > 0")
    return cfg
