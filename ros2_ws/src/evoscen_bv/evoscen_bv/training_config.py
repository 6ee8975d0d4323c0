"""The training configuration (YAML): TD3, controller, grid, rewards, environments, stages.

One file drives the whole level-k pipeline and travels with the policies it produced (the
pipeline copies it into its output directory, and the learned driver reads the copy next
to the weights, so the decision rate and the observation scales at run time are the ones
the policies were trained with). The shipped file is ``share/evoscen_bv/config/training.yaml``
(source: ``evoscen_bv/config/training.yaml``), every key commented there.

Validation: by the scenario configuration's validator (:func:`evoscen_sim.config.config_load.build`,
the same checkers, the same one-line errors: file, key, value, what is expected, line);
unknown keys and values of the wrong type or out of range fail. The parameter dataclasses
are the kernels' own, so each field's check follows from the type of its default
(:func:`_check_by_default`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from evoscen_sim.config.config_checks import _Bool, _check, _Float, _Int, _Range, _section, _Str
from evoscen_sim.config.config_schema import MAKEUPS
from evoscen_sim.config.config_load import Context, build, parse_yaml
from evoscen_sim.errors import InputError
from evoscen_sim.limits import MAX_CONFIG_BYTES, MAX_TRAINING_STEPS, read_text_limited
from evoscen_sim.share import share_candidates

from .car_following import CarFollowingParams
from .lane_change_decision import GridParams, RewardParams
from .profile import PROFILE_NAMES
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
    control_settling_check: bool = False
    """Select the controller only among evaluations that settle behind a steady leader
    (:func:`evoscen_bv.pipeline.settling_check`: no collision, mean gap within g ± 5 m,
    acceleration flips ≤ 1 %); false (the default of a YAML without the key, as every earlier
    training ran): by evaluation return alone [choice, see :mod:`evoscen_bv.pipeline`]."""
    profile: str = "driver"
    """The BV run-time rule profile of the decision environments' drivers (``driver`` or
    ``safety_net``, :mod:`evoscen_bv.profile`, docs/bv-profiles.md); the copy of this file
    in a policy directory records what its policies were trained with."""
    makeup: str = field(default="uniform", metadata=_check(_Str(lambda: MAKEUPS)))
    """The traffic of the decision environments (docs/learned-bvs.md, "Trained among the highD make-up"):
    ``uniform`` (the default of a YAML without the key, as every earlier training ran) = the spawn
    block on the loop, cars only, desired speeds ``desired_speed_mps``; ``highd`` = the traffic window
    with ``bvs.makeup: highd`` (trucks with their driver, highD's desired speeds uncapped, the cars'
    approach braking), the ego a car of the window, its episode cut when it leaves the window."""


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

    td3: TD3Params = _section(TD3Params)
    car_following: CarFollowingParams = _section(CarFollowingParams)
    grid: GridParams = _section(GridParams)
    reward: RewardParams = _section(RewardParams)
    env: EnvParams = _section(EnvParams)
    steps: StageSteps = _section(StageSteps)

    def to_dict(self) -> dict[str, Any]:
        out = dataclasses.asdict(self)
        out["env"]["desired_speed_mps"] = list(self.env.desired_speed_mps)
        return out


def strict_int(option: str, text: str, lo: int, hi: int, expected: str) -> int:
    """The integer ``text`` of ``option`` (plain decimal digits only: ``int()`` would also take ``1_000``
    and spaces) in [``lo``, ``hi``]; else a one-line InputError in argparse's words."""
    body = text[1:] if text[:1] in "+-" else text
    if not body.isascii() or not body.isdigit() or len(body) > 30 or not lo <= int(text) <= hi:
        raise InputError(f"argument {option}: expected {expected}, got {text!r}")
    return int(text)


def training_steps(option: str, text: str) -> int:
    """A step count of ``option``: 1 .. :data:`~evoscen_sim.limits.MAX_TRAINING_STEPS` (:func:`strict_int`)."""
    return strict_int(option, text, 1, MAX_TRAINING_STEPS,
                      f"a positive integer (decimal digits, at most {MAX_TRAINING_STEPS})")


def training_seed(option: str, text: str) -> int:
    """A training seed of ``option``: 0 .. 2^32 - 1 (:func:`strict_int`)."""
    return strict_int(option, text, 0, 2**32 - 1, "an integer in [0, 2^32)")


def default_config_path() -> Path:
    """The shipped training config (installed share dir, else the source tree: evoscen_bv/config/)."""
    candidates = share_candidates("config/training.yaml", "evoscen_bv",
                                  source=Path(__file__).resolve().parent / "config" / "training.yaml")
    return next((p for p in candidates[:-1] if p.is_file()), candidates[-1])


def _check_by_default(f: dataclasses.Field) -> Any:
    """The checker of a training parameter, by the type of its default: the parameter
    dataclasses (TD3, car following, grid, rewards) are the kernels' own and declare no
    checks; every integer is a count of steps or units, every text a BV profile."""
    default = f.default_factory() if f.default is dataclasses.MISSING else f.default
    if isinstance(default, bool):
        return _Bool()
    if isinstance(default, int):
        return _Int(1, MAX_TRAINING_STEPS)
    if isinstance(default, float):
        return _Float()
    if isinstance(default, str):
        return _Str(lambda: PROFILE_NAMES)
    if isinstance(default, tuple):
        return _Range(0.0, None, lo_open=True)
    raise TypeError(f"training parameter {f.name!r}: no check for a default of type {type(default).__name__}")


def load_training_config(path: Path | str | None = None) -> TrainingConfig:
    """Read and validate a training YAML (``None``: the shipped one)."""
    path = Path(path) if path is not None else default_config_path()
    label = str(path)
    text = read_text_limited(path, label, "training config", MAX_CONFIG_BYTES)
    raw, lines = parse_yaml(text, label, "training config")
    ctx = Context(label, lines, top_level="training config sections", default_check=_check_by_default)
    explicit: set[str] = set()
    cfg = build(TrainingConfig, raw, "", ctx, explicit)
    for name, value in (("reward.lane_change_penalty", cfg.reward.lane_change_penalty),
                        ("reward.comp_lane_change_penalty", cfg.reward.comp_lane_change_penalty),
                        ("reward.coop_lane_change_penalty", cfg.reward.coop_lane_change_penalty),
                        ("reward.request_penalty", cfg.reward.request_penalty)):
        if value > 0:
            ctx.fail(name, value, "expected a number <= 0 (a penalty)", is_default=name not in explicit)
    for name, value in (("car_following.view_m", cfg.car_following.view_m),
                        ("reward.front_view_m", cfg.reward.front_view_m),
                        ("reward.gain_norm_m2", cfg.reward.gain_norm_m2)):
        if value <= 0:
            ctx.fail(name, value, "expected a number > 0", is_default=name not in explicit)
    return cfg
