"""Scenario configuration: frozen dataclasses, loaded from YAML and validated on load.

A scenario is data. :func:`load_scenario_config` reads a YAML file (the shipped
``config/default_scenario.yaml`` when no path is given), applies dotted-key
overrides (``{"steps": 200, "bvs.mix": "3:4:3"}``, typically from the command
line) and validates everything before building a :class:`ScenarioConfig`.

Every problem raises :class:`evoscen_sim.errors.InputError` with a one-line
message naming the file (or ``command line`` for an override), the dotted key
path, the offending value and what is allowed, e.g.::

    scenario.yaml: key 'steps' = -5: expected an integer >= 1 (line 4)

Keys missing from the file take the defaults documented on the dataclass
fields; unknown keys are errors (with a suggestion of the closest allowed key).

YAML notes: the loader is PyYAML's safe loader with two YAML 1.1 quirks
removed so that what you write is what you get: ``4:3:3`` is the string
``"4:3:3"`` (not the base-60 integer 14583) and ``1e3`` is the float 1000.0.
Booleans are *not* integers: ``steps: true`` is an error.

The choice lists :data:`BV_DRIVERS` and :data:`SUT_MODELS` are module-level
tuples read at validation time; packages that add drivers or models extend
them with :func:`register_bv_driver` / :func:`register_sut_model`.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import os
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NoReturn

import yaml

from evoscen_sim.errors import InputError
from evoscen_sim.limits import (
    MAX_CONFIG_BYTES,
    MAX_DT_NS_RESIDUE,
    MAX_STEPS,
    MIN_DT_S,
    check_yaml_depth,
    read_text_limited,
)

__all__ = [
    "BV_DRIVERS",
    "COMPRESSIONS",
    "POLICIES",
    "SUT_MODELS",
    "BvConfig",
    "ControlConfig",
    "Level0Config",
    "ReentryConfig",
    "RecordingConfig",
    "ScenarioConfig",
    "SpawnConfig",
    "SutConfig",
    "VehicleConfig",
    "config_from_dict",
    "config_to_dict",
    "dump_config",
    "load_scenario_config",
    "mix_counts",
    "register_bv_driver",
    "register_sut_model",
    "resolve_map_path",
    "share_candidates",
    "share_path",
]

#: BV decision policies, in the canonical order used by the ``"C:M:C"`` mix string.
POLICIES: tuple[str, ...] = ("competitive", "mutual", "cooperative")
#: Background-vehicle driver implementations selectable by ``bvs.driver``.
BV_DRIVERS: tuple[str, ...] = ("level0",)
#: System-under-test models selectable by ``sut.model``.
SUT_MODELS: tuple[str, ...] = ("level0",)
#: Bag compression modes selectable by ``recording.compression``.
COMPRESSIONS: tuple[str, ...] = ("zstd", "lz4", "none")

#: Upper bound of ``sut.s_m`` (the on-ramp map is 2393.76 m long).
MAX_S_M = 2393.0
#: Upper bound of the speed ranges ``spawn.speed_mps`` / ``level0.desired_speed_mps`` (m/s).
MAX_RANGE_SPEED_MPS = 40.0
#: Upper bound of ``bvs.count``.
MAX_BV_COUNT = 200

_PACKAGE = "evoscen_sim"
_DEFAULT_CONFIG = "config/default_scenario.yaml"


def register_bv_driver(name: str) -> None:
    """Make ``name`` a valid ``bvs.driver`` (idempotent)."""
    global BV_DRIVERS
    if name not in BV_DRIVERS:
        BV_DRIVERS = (*BV_DRIVERS, name)


def register_sut_model(name: str) -> None:
    """Make ``name`` a valid ``sut.model`` (idempotent)."""
    global SUT_MODELS
    if name not in SUT_MODELS:
        SUT_MODELS = (*SUT_MODELS, name)


# --------------------------------------------------------------------------------------------
# Leaf value checkers. Each converts a raw YAML value to the stored type or raises _Bad.
# --------------------------------------------------------------------------------------------


class _Bad(Exception):
    """A value failed its check: ``expected`` says what is allowed; optionally at a sub-key."""

    def __init__(self, expected: str, subkey: str | None = None, value: Any = None) -> None:
        super().__init__(expected)
        self.expected = expected
        self.subkey = subkey
        self.value = value


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value: Any) -> bool:
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value))


def _fmt(x: float) -> str:
    return f"{x:g}"


class _Int:
    takes_str = False

    def __init__(self, lo: int | None = None, hi: int | None = None) -> None:
        self.lo, self.hi = lo, hi
        if lo is not None and hi is not None:
            self.expected = f"expected an integer in [{lo}, {hi}]"
        elif lo is not None:
            self.expected = f"expected an integer >= {lo}"
        else:
            self.expected = "expected an integer"

    def __call__(self, value: Any) -> int:
        if not _is_int(value):
            raise _Bad(self.expected)
        if (self.lo is not None and value < self.lo) or (self.hi is not None and value > self.hi):
            raise _Bad(self.expected)
        return int(value)


class _Float:
    takes_str = False

    def __init__(self, lo: float | None = None, hi: float | None = None, *,
                 lo_open: bool = False) -> None:
        self.lo, self.hi, self.lo_open = lo, hi, lo_open
        if lo is not None and hi is not None:
            self.expected = f"expected a number in {'(' if lo_open else '['}{_fmt(lo)}, {_fmt(hi)}]"
        elif lo is not None:
            self.expected = f"expected a number {'>' if lo_open else '>='} {_fmt(lo)}"
        else:
            self.expected = "expected a finite number"

    def __call__(self, value: Any) -> float:
        if not _is_number(value):
            raise _Bad(self.expected)
        v = float(value)
        if self.lo is not None and (v < self.lo or (self.lo_open and v == self.lo)):
            raise _Bad(self.expected)
        if self.hi is not None and v > self.hi:
            raise _Bad(self.expected)
        return v


class _StepSize:
    """``dt_s``: in [MIN_DT_S, 1] s and a whole number of nanoseconds (the bag's stamps are
    ``step * round(dt_s * 1e9)`` ns, exact only then; see docs/input-limits.md)."""

    takes_str = False
    expected = (f"expected a number of seconds in [{_fmt(MIN_DT_S)}, 1] that is a whole number of "
                "nanoseconds (the bag's stamps are integer ns)")

    def __call__(self, value: Any) -> float:
        if not _is_number(value):
            raise _Bad(self.expected)
        v = float(value)
        if not MIN_DT_S <= v <= 1.0 or abs(v * 1e9 - round(v * 1e9)) > MAX_DT_NS_RESIDUE:
            raise _Bad(self.expected)
        return v


class _Bool:
    takes_str = False
    expected = "expected a boolean (true or false)"

    def __call__(self, value: Any) -> bool:
        if not isinstance(value, bool):
            raise _Bad(self.expected)
        return value


class _Str:
    takes_str = True

    def __init__(self, choices: Callable[[], tuple[str, ...]] | None = None) -> None:
        self.choices = choices

    @property
    def expected(self) -> str:
        if self.choices is None:
            return "expected a non-empty string"
        return "expected one of " + ", ".join(self.choices())

    def __call__(self, value: Any) -> str:
        if not isinstance(value, str) or not value:
            raise _Bad(self.expected)
        if self.choices is not None:
            allowed = self.choices()
            if value not in allowed:
                raise _Bad(self.expected + _suggest(value, allowed))
        return value


class _Range:
    """A ``[lo, hi]`` pair of numbers with ``lo <= hi`` inside the given bounds."""

    takes_str = False

    def __init__(self, lo: float, hi: float, *, lo_open: bool = False) -> None:
        self.lo, self.hi, self.lo_open = lo, hi, lo_open
        bracket = "(" if lo_open else "["
        self.expected = (f"expected a list [lo, hi] of two numbers with lo <= hi, "
                         f"both in {bracket}{_fmt(lo)}, {_fmt(hi)}]")

    def __call__(self, value: Any) -> tuple[float, float]:
        if not isinstance(value, (list, tuple)) or len(value) != 2:
            raise _Bad(self.expected)
        if not all(_is_number(v) for v in value):
            raise _Bad(self.expected)
        lo, hi = float(value[0]), float(value[1])
        for v in (lo, hi):
            if v < self.lo or v > self.hi or (self.lo_open and v == self.lo):
                raise _Bad(self.expected)
        if lo > hi:
            raise _Bad(self.expected)
        return (lo, hi)


_MIX_STRING = re.compile(r"^\s*(\d+)\s*:\s*(\d+)\s*:\s*(\d+)\s*$")


class _Mix:
    """BV policy mix: a mapping policy -> non-negative int, or the string ``"C:M:C"``."""

    takes_str = True
    expected = ("expected a mapping of " + "/".join(POLICIES)
                + " to non-negative integers, or a string 'competitive:mutual:cooperative'"
                + " such as '4:3:3'")

    def __call__(self, value: Any) -> dict[str, int]:
        if isinstance(value, str):
            m = _MIX_STRING.match(value)
            if m is None:
                raise _Bad(self.expected)
            return {p: int(g) for p, g in zip(POLICIES, m.groups())}
        if not isinstance(value, Mapping):
            raise _Bad(self.expected)
        for key, v in value.items():
            if key not in POLICIES:
                raise _Bad(_unknown_text(key, POLICIES), subkey=str(key), value=None)
            if not _is_int(v) or v < 0:
                raise _Bad("expected a non-negative integer", subkey=key, value=v)
        return {p: int(value.get(p, 0)) for p in POLICIES}


class _MapPath:
    """``map``: a non-empty string; existence is checked after the rest (see resolve_map_path)."""

    takes_str = True
    expected = "expected a non-empty path to an OpenDRIVE (.xodr) file"

    def __call__(self, value: Any) -> str:
        if not isinstance(value, str) or not value.strip():
            raise _Bad(self.expected)
        return value


def _suggest(word: str, allowed: tuple[str, ...] | list[str]) -> str:
    close = difflib.get_close_matches(word, list(allowed), n=1, cutoff=0.6)
    return f"; did you mean '{close[0]}'?" if close else ""


def _unknown_text(key: Any, allowed: tuple[str, ...] | list[str]) -> str:
    text = "unknown key; allowed keys: " + ", ".join(allowed)
    return text + (_suggest(key, allowed) if isinstance(key, str) else "")


def _check(checker: Any) -> dict[str, Any]:
    return {"check": checker}


def _section(cls: type) -> Any:
    return field(default_factory=cls, metadata={"section": cls})


# Public helpers to declare the fields of a model's parameter dataclass (see
# evoscen_sim.models): the scenario YAML's ``models.<name>`` section is validated with them.
def number(default: float, lo: float | None = None, hi: float | None = None, *, lo_open: bool = False) -> Any:
    """A float parameter with bounds (``lo_open``: strictly above ``lo``)."""
    return field(default=default, metadata=_check(_Float(lo, hi, lo_open=lo_open)))


def integer(default: int, lo: int | None = None, hi: int | None = None) -> Any:
    """An integer parameter with bounds."""
    return field(default=default, metadata=_check(_Int(lo, hi)))


def flag(default: bool) -> Any:
    """A boolean parameter."""
    return field(default=default, metadata=_check(_Bool()))


def text(default: str, choices: tuple[str, ...] | Callable[[], tuple[str, ...]] | None = None) -> Any:
    """A non-empty string parameter, optionally one of ``choices`` (a tuple, or a callable
    returning one at validation time, e.g. the registered SUT models)."""
    if choices is None or callable(choices):
        return field(default=default, metadata=_check(_Str(choices)))
    fixed = tuple(choices)
    return field(default=default, metadata=_check(_Str(lambda: fixed)))


def number_range(default: tuple[float, float], lo: float, hi: float, *, lo_open: bool = False) -> Any:
    """A ``[lo, hi]`` pair parameter within bounds."""
    return field(default=default, metadata=_check(_Range(lo, hi, lo_open=lo_open)))


# --------------------------------------------------------------------------------------------
# Schema
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BvConfig:
    """Background vehicles (BVs)."""

    count: int = field(default=20, metadata=_check(_Int(0, MAX_BV_COUNT)))
    """Number of background vehicles, 0..200."""
    mix: dict[str, int] = field(
        default_factory=lambda: {"competitive": 4, "mutual": 3, "cooperative": 3},
        metadata=_check(_Mix()))
    """Policy mix ratio competitive:mutual:cooperative (always all three keys, in that order);
    split into counts by :func:`mix_counts`. YAML accepts a mapping (missing policies = 0) or
    the string ``"4:3:3"``. Must not be all zero when ``count > 0``."""
    driver: str = field(default="learned", metadata=_check(_Str(lambda: BV_DRIVERS)))
    """BV driver implementation, one of :data:`BV_DRIVERS`: ``learned`` (default; the shipped
    TD3 policies of ``evoscen_bv``, the mix applies), ``level0``, ..."""


@dataclass(frozen=True)
class SutConfig:
    """The system under test (SUT)."""

    model: str = field(default="level0", metadata=_check(_Str(lambda: SUT_MODELS)))
    """SUT decision model, one of :data:`SUT_MODELS`."""
    lane: int = field(default=2, metadata=_check(_Int(1, 4)))
    """Initial lane index on the mainline, 1..4 (0 is the merge lane; see CONVENTIONS)."""
    s_m: float = field(default=300.0, metadata=_check(_Float(0.0, MAX_S_M)))
    """Initial arc-length position along the reference line (m), 0..2393."""
    speed_mps: float = field(default=27.0, metadata=_check(_Float(0.0, MAX_RANGE_SPEED_MPS)))
    """Initial speed (m/s), 0..40."""


@dataclass(frozen=True)
class SpawnConfig:
    """Initial placement of the BVs."""

    ramp_vehicles: int = field(default=3, metadata=_check(_Int(0)))
    """BVs that start on the merge lane (lane 0); 0..bvs.count."""
    mainline_gap_m: float = field(default=40.0, metadata=_check(_Float(0.0, lo_open=True)))
    """Nominal bumper-to-bumper spacing used to lay BVs out on the mainline (m), > 0."""
    speed_mps: tuple[float, float] = field(
        default=(24.0, 30.0), metadata=_check(_Range(0.0, MAX_RANGE_SPEED_MPS)))
    """Uniform initial speed range [lo, hi] (m/s), lo <= hi, within [0, 40]."""
    jitter_m: float = field(default=5.0, metadata=_check(_Float(0.0)))
    """Uniform random longitudinal jitter of each spawn position (m), >= 0."""


@dataclass(frozen=True)
class ReentryConfig:
    """Re-entry of vehicles that leave the map (keeps the density constant)."""

    ramp_share: float = field(default=0.2, metadata=_check(_Float(0.0, 1.0)))
    """Probability that a re-entering vehicle re-enters on the ramp (merge lane) instead of
    the mainline, [0, 1]."""
    min_gap_m: float = field(default=15.0, metadata=_check(_Float(0.0)))
    """Bumper-to-bumper gap required at the entry point (m), >= 0."""


_POSITIVE = _check(_Float(0.0, lo_open=True))
_NON_NEGATIVE = _check(_Float(0.0))


@dataclass(frozen=True)
class VehicleConfig:
    """Vehicle body and single-track model limits (all > 0)."""

    length_m: float = field(default=4.8, metadata=_POSITIVE)
    """Body length (m)."""
    width_m: float = field(default=1.9, metadata=_POSITIVE)
    """Body width (m)."""
    wheelbase_m: float = field(default=2.9, metadata=_POSITIVE)
    """Distance between the axles of the bicycle model (m)."""
    max_accel_mps2: float = field(default=3.0, metadata=_POSITIVE)
    """Acceleration at full throttle (+1) (m/s^2)."""
    max_brake_mps2: float = field(default=8.0, metadata=_POSITIVE)
    """Deceleration magnitude at full brake (-1) (m/s^2)."""
    max_speed_mps: float = field(default=40.0, metadata=_POSITIVE)
    """Speed cap (m/s)."""
    max_steer_rad: float = field(default=0.5, metadata=_POSITIVE)
    """Front-wheel steering-angle limit (rad)."""
    max_steer_rate_radps: float = field(default=0.5, metadata=_POSITIVE)
    """Steering-angle rate limit (rad/s)."""


@dataclass(frozen=True)
class ControlConfig:
    """Low-level dual PID lateral controller (lateral offset + heading error).

    Cascaded loops, gain-scheduled by speed (see :mod:`evoscen_sim.control`): the
    lateral-offset PID gives a lateral-speed demand, the heading PID a heading-rate
    demand. Defaults: near critically damped, a lane change crosses into the new lane
    in ~3.3 s at 30 m/s without overshoot.
    """

    lat_kp: float = field(default=0.8, metadata=_NON_NEGATIVE)
    """Lateral-offset PID proportional gain (lateral m/s per m of offset, i.e. 1/s)."""
    lat_ki: float = field(default=0.0, metadata=_NON_NEGATIVE)
    """Lateral-offset PID integral gain (1/s²)."""
    lat_kd: float = field(default=0.0, metadata=_NON_NEGATIVE)
    """Lateral-offset PID derivative gain (dimensionless: m/s per m/s)."""
    head_kp: float = field(default=3.0, metadata=_NON_NEGATIVE)
    """Heading-error PID proportional gain (heading rate rad/s per rad, i.e. 1/s)."""
    head_ki: float = field(default=0.0, metadata=_NON_NEGATIVE)
    """Heading-error PID integral gain (1/s²)."""
    head_kd: float = field(default=0.0, metadata=_NON_NEGATIVE)
    """Heading-error PID derivative gain (dimensionless)."""
    max_lateral_speed_mps: float = field(default=0.6, metadata=_POSITIVE)
    """Cap on the commanded lateral speed while changing lanes (m/s), > 0."""
    max_heading_ref_rad: float = field(default=0.2, metadata=_check(_Float(0.0, 1.5, lo_open=True)))
    """Cap on the heading reference of the lateral loop (rad), (0, 1.5]; binds only below
    max_lateral_speed_mps / sin(cap) (~3 m/s), see evoscen_sim.control."""


@dataclass(frozen=True)
class Level0Config:
    """Level-0 driver: IDM car following, lane keeping except forced merges."""

    desired_speed_mps: tuple[float, float] = field(
        default=(27.0, 33.0),
        metadata=_check(_Range(0.0, MAX_RANGE_SPEED_MPS, lo_open=True)))
    """Per-vehicle IDM desired speed drawn uniformly from [lo, hi] (m/s), within (0, 40]."""
    time_headway_s: float = field(default=1.5, metadata=_POSITIVE)
    """IDM safe time headway T (s)."""
    min_gap_m: float = field(default=2.0, metadata=_NON_NEGATIVE)
    """IDM standstill gap s0 (m)."""
    accel_mps2: float = field(default=1.5, metadata=_POSITIVE)
    """IDM maximum acceleration a (m/s^2)."""
    comfort_decel_mps2: float = field(default=2.0, metadata=_POSITIVE)
    """IDM comfortable deceleration b (m/s^2)."""
    delta: float = field(default=4.0, metadata=_POSITIVE)
    """IDM acceleration exponent delta."""
    merge_min_front_gap_m: float = field(default=8.0, metadata=_NON_NEGATIVE)
    """Minimum bumper-to-bumper gap to the new leader for a forced merge (m)."""
    merge_min_rear_gap_m: float = field(default=8.0, metadata=_NON_NEGATIVE)
    """Minimum bumper-to-bumper gap to the new follower for a forced merge (m)."""
    merge_closing_headway_s: float = field(default=1.5, metadata=_NON_NEGATIVE)
    """Extra merge gap per m/s of closing speed to the new leader / from the new follower (s)."""
    merge_stop_margin_m: float = field(default=15.0, metadata=_NON_NEGATIVE)
    """The merge lane's end acts as a standing obstacle this far before the lane ends (m)."""


@dataclass(frozen=True)
class RecordingConfig:
    """rosbag2 (MCAP) recording."""

    enabled: bool = field(default=True, metadata=_check(_Bool()))
    """Record a bag of the run."""
    compression: str = field(default="zstd", metadata=_check(_Str(lambda: COMPRESSIONS)))
    """Chunk compression, one of :data:`COMPRESSIONS`."""
    chunk_size_bytes: int = field(default=1048576, metadata=_check(_Int(1)))
    """Target MCAP chunk size (bytes), >= 1."""
    markers_every: int = field(default=5, metadata=_check(_Int(0, 100000)))
    """Publish the vehicle markers (``/evoscen/markers``) every this many steps; 0 = never.
    The map markers go out once whatever the value."""


EFFICIENCY_DENSITY_FORMS = ("literal", "normalised")
ACCEL_ACTIVITY_FORMS = ("smoothed", "literal")
#: ``evaluation.rear_conflicts`` values (see :mod:`evoscen_sim.safety`).
REAR_CONFLICT_MODES = ("after_lane_change", "all", "none")
#: ``evaluation.rear_braking`` values (see :mod:`evoscen_sim.safety`).
REAR_BRAKING_RULES = ("within_headway", "any")
#: ``evaluation.undefined_terms`` values.
UNDEFINED_TERM_RULES = ("exclude", "literal")


@dataclass(frozen=True)
class EvaluationConfig:
    """Scoring of the SUT and of the scenario (docs/method.md §5.1-5.2; see :mod:`evoscen_eval.metrics`).

    Every **[choice]** the method leaves open is a key here, defaults as documented in
    docs/evaluation.md (§7: the choices at a glance).
    """

    ttc_threshold_s: float = field(default=2.0, metadata=_POSITIVE)
    """A state is dangerous when the SUT's time to collision with the vehicle ahead in its
    path is below this (s)."""
    hard_brake_mps2: float = field(default=6.0, metadata=_POSITIVE)
    """... or when the SUT's acceleration is below minus this (m/s^2)."""
    view_behind_m: float = field(default=20.0, metadata=_NON_NEGATIVE)
    """The SUT's view: this far behind its reference point (m), all lanes."""
    view_ahead_m: float = field(default=100.0, metadata=_POSITIVE)
    """... to this far ahead (m)."""
    view_lanes: int = field(default=5, metadata=_check(_Int(1, 20)))
    """Lanes counted in H (the most vehicles that fit in the view)."""
    min_spacing_m: float = field(default=6.8, metadata=_POSITIVE)
    """Minimum spacing (length + standstill gap, m) used for H = view_lanes *
    floor((view_behind_m + view_ahead_m) / min_spacing_m)."""
    v_max_mps: float = field(default=33.33, metadata=_POSITIVE)
    """v_max of the efficiency score (m/s)."""
    efficiency_density: str = field(default="literal", metadata=_check(_Str(lambda: EFFICIENCY_DENSITY_FORMS)))
    """Density-speed term of I_e: literal = sqrt(h)*v/(H*v_max) as the method writes it;
    normalised = sqrt(h/H)*v/v_max (in [0, 1])."""
    lane_change_time_scale_s: float = field(default=3.0, metadata=_POSITIVE)
    """The 3 of e^(-T_l/3) (s)."""
    no_lane_change_time_s: float = field(default=0.0, metadata=_NON_NEGATIVE)
    """T_l when the SUT completed no lane change (s), used only with undefined_terms: literal."""
    collision_cap: int = field(default=10, metadata=_check(_Int(1)))
    """C_max of the safety score."""
    dv_max_mps: float = field(default=5.0, metadata=_POSITIVE)
    """Normaliser of the BVs' speed fluctuation |v~| (m/s)."""
    da_max_mps2: float = field(default=3.0, metadata=_POSITIVE)
    """Normaliser of the BVs' acceleration fluctuation |a~| (m/s^2)."""
    weight_safety: float = field(default=0.6, metadata=_NON_NEGATIVE)
    """i_s of I = i_s*I_s + i_e*I_e + i_i*I_i."""
    weight_efficiency: float = field(default=0.2, metadata=_NON_NEGATIVE)
    """i_e."""
    weight_interaction: float = field(default=0.2, metadata=_NON_NEGATIVE)
    """i_i."""
    window_steps: int = field(default=100, metadata=_check(_Int(1)))
    """Complexity window (steps); only whole windows count."""
    accel_activity_mps2: float = field(default=0.1, metadata=_NON_NEGATIVE)
    """AD counts vehicle-steps with |acceleration| above this (m/s^2)."""
    accel_activity_form: str = field(default="smoothed", metadata=_check(_Str(lambda: ACCEL_ACTIVITY_FORMS)))
    """Acceleration AD compares with the threshold: smoothed = the mean over the trailing
    ``accel_activity_window_s`` (manoeuvres, not per-step car-following noise such as Krauss
    dawdling; docs/evaluation.md); literal = the per-step acceleration."""
    accel_activity_window_s: float = field(default=1.0, metadata=_POSITIVE)
    """Trailing window of the smoothed AD acceleration (s)."""
    k_exposure: float = field(default=25.0, metadata=_POSITIVE)
    """k1 of the complexity score."""
    k_lane_change: float = field(default=8.0, metadata=_POSITIVE)
    """k2."""
    k_accel: float = field(default=1400.0, metadata=_POSITIVE)
    """k3."""
    rear_conflicts: str = field(default="after_lane_change", metadata=_check(_Str(lambda: REAR_CONFLICT_MODES)))
    """Rear conflicts (the follower in the SUT's path closing with TTC < ttc_threshold_s or
    braking harder than hard_brake_mps2) make a state dangerous: after_lane_change = from the
    start of a SUT lane change until rear_attribution_s after it ends; all = always; none =
    never (the SUT's own front and braking only). See docs/evaluation.md."""
    rear_attribution_s: float = field(default=5.0, metadata=_NON_NEGATIVE)
    """Attribution window after a SUT lane change ends (s); also the window after the change
    over which its lane-change PET is taken."""
    rear_braking: str = field(default="within_headway", metadata=_check(_Str(lambda: REAR_BRAKING_RULES)))
    """Which braking of the follower is a rear conflict: within_headway = braking harder than
    hard_brake_mps2 while its time headway to the SUT (gap / its speed) is below
    rear_braking_headway_s (the SUT can have caused it); any = every such braking (round 2's
    first rule: counted followers braking 30-160 m behind for reasons of their own). See
    docs/evaluation.md."""
    rear_braking_headway_s: float = field(default=2.0, metadata=_POSITIVE)
    """Time headway below which a follower's hard braking is the SUT's to answer for (s; the
    two-second rule)."""
    drac_threshold_mps2: float = field(default=3.0, metadata=_POSITIVE)
    """Reported counts of states whose DRAC exceeds this (m/s^2; SUMO SSM's default 3)."""
    undefined_terms: str = field(default="exclude", metadata=_check(_Str(lambda: UNDEFINED_TERM_RULES)))
    """A score term undefined in the run (T_l without a completed SUT lane change; I_i without
    any SUT lane change): exclude = left out and the remaining weights renormalised;
    literal = T_l = no_lane_change_time_s and I_i = 1 (the method's arithmetic taken literally)."""


@dataclass(frozen=True)
class ScenarioConfig:
    """One scenario: map, timing, population, models, control and recording."""

    name: str = field(default="onramp_default", metadata=_check(_Str()))
    """Scenario name (used in output names)."""
    map: str = field(default="onramp.xodr", metadata=_check(_MapPath()))
    """OpenDRIVE map. In the file: an absolute path, a path relative to the config file's
    directory, or a name under evoscen_sim's share ``maps/``. After loading it holds the
    resolved absolute path (see :func:`resolve_map_path`)."""
    dt_s: float = field(default=0.1, metadata=_check(_StepSize()))
    """Fixed integration step (s), in [1e-6, 1] and a whole number of nanoseconds (the bag's
    stamps are integer ns; docs/input-limits.md)."""
    steps: int = field(default=3000, metadata=_check(_Int(1, MAX_STEPS)))
    """Number of simulation steps, 1..1,000,000 (:data:`evoscen_sim.limits.MAX_STEPS`)."""
    seed: int = field(default=0, metadata=_check(_Int(0)))
    """Seed of the scenario's numpy Generator, >= 0."""
    bvs: BvConfig = _section(BvConfig)
    """Background vehicles."""
    sut: SutConfig = _section(SutConfig)
    """System under test."""
    spawn: SpawnConfig = _section(SpawnConfig)
    """Initial placement."""
    reentry: ReentryConfig = _section(ReentryConfig)
    """Re-entry of vehicles leaving the map."""
    vehicle: VehicleConfig = _section(VehicleConfig)
    """Vehicle body and dynamics limits."""
    control: ControlConfig = _section(ControlConfig)
    """Low-level dual PID."""
    level0: Level0Config = _section(Level0Config)
    """Level-0 (IDM) driver parameters."""
    recording: RecordingConfig = _section(RecordingConfig)
    """Bag recording."""
    evaluation: EvaluationConfig = _section(EvaluationConfig)
    """Scoring (intelligence, complexity)."""
    models: dict[str, Any] = field(default_factory=dict, metadata={"models": True})
    """Parameters of driver models by model name (``models.mobil.politeness: 0.5``), each
    validated against the model's parameter dataclass (:mod:`evoscen_sim.models`); a model
    not listed uses its defaults."""


# --------------------------------------------------------------------------------------------
# YAML loading with line numbers
# --------------------------------------------------------------------------------------------


class _Loader(yaml.SafeLoader):
    """Safe loader without YAML 1.1 base-60 numbers; floats may omit the dot (``1e3``)."""


_INT_TAG = "tag:yaml.org,2002:int"
_FLOAT_TAG = "tag:yaml.org,2002:float"
_Loader.yaml_implicit_resolvers = {
    first: [(tag, rx) for tag, rx in resolvers if tag not in (_INT_TAG, _FLOAT_TAG)]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_Loader.add_implicit_resolver(
    _INT_TAG,
    re.compile(r"^(?:[-+]?0b[0-1_]+|[-+]?0x[0-9a-fA-F_]+|[-+]?(?:0|[1-9][0-9_]*))$"),
    list("-+0123456789"))
_Loader.add_implicit_resolver(
    _FLOAT_TAG,
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?(?:[eE][-+]?[0-9]+)?
                   |[-+]?\.[0-9][0-9_]*(?:[eE][-+]?[0-9]+)?
                   |[-+]?\.(?:inf|Inf|INF)
                   |\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."))


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def _record_lines(node: yaml.Node, path: str, lines: dict[str, int], label: str,
                  seen_nodes: set[int] | None = None) -> None:
    """Map dotted key paths to 1-based line numbers of their values; reject duplicate keys.

    A node reached again through an alias is not walked again (a chain of aliases would
    otherwise cost exponential time, YAML's "billion laughs")."""
    if not isinstance(node, yaml.MappingNode):
        return
    if seen_nodes is None:
        seen_nodes = set()
    if id(node) in seen_nodes:
        return
    seen_nodes.add(id(node))
    seen: set[str] = set()
    for key_node, value_node in node.value:
        if not isinstance(key_node, yaml.ScalarNode):
            continue
        key_path = _join(path, key_node.value)
        line = key_node.start_mark.line + 1
        if key_node.value in seen:
            raise InputError(f"{label}: key '{key_path}' appears twice (line {line}): "
                             "expected each key once")
        seen.add(key_node.value)
        lines[key_path] = line
        _record_lines(value_node, key_path, lines, label, seen_nodes)


def _parse_yaml(text: str, label: str) -> tuple[Any, dict[str, int]]:
    check_yaml_depth(text, label, "scenario config", _Loader)
    lines: dict[str, int] = {}
    loader = None
    try:
        loader = _Loader(text)  # the reader checks the characters here (YAMLError)
        node = loader.get_single_node()
        if node is None:
            return None, lines
        _record_lines(node, "", lines, label)
        return loader.construct_document(node), lines
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = " ".join(str(exc.problem or exc.context or "invalid YAML").split())
        raise InputError(f"{label}: YAML syntax error{where}: {problem}") from None
    except yaml.YAMLError as exc:
        raise InputError(f"{label}: YAML error: {' '.join(str(exc).split())}") from None
    finally:
        if loader is not None:
            loader.dispose()


_CLI_DECIMAL = re.compile(r"^[-+]?[0-9]+$")
_CLI_FLOAT = re.compile(r"^[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?$")


def _parse_cli_scalar(text: str) -> Any:
    """Interpret an override given as text (``"200"``, ``"true"``, ``"[24, 30]"``) as YAML.

    Numbers on the command line are strict: a plain decimal integer (``16``, not ``0x10``,
    ``0b10000`` or ``1_6``, which YAML would read as 16) or a plain decimal float; anything
    else stays text, so the key's check rejects it naming the value as typed."""
    if len(text) > 10_000:
        return text
    try:
        value = yaml.load(text, Loader=_Loader)  # noqa: S506 - _Loader is a SafeLoader
    except (yaml.YAMLError, RecursionError):
        return text
    stripped = text.strip()
    if isinstance(value, int) and not isinstance(value, bool) and not _CLI_DECIMAL.match(stripped):
        return text
    if isinstance(value, float) and not _CLI_FLOAT.match(stripped):
        return text
    return value


# --------------------------------------------------------------------------------------------
# Validation
# --------------------------------------------------------------------------------------------


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


class _Context:
    """Where values came from, for error messages."""

    def __init__(self, label: str, lines: dict[str, int], cli_paths: set[str],
                 override_keys: set[str]) -> None:
        self.label = label
        self.lines = lines
        self.cli_paths = cli_paths
        self.override_keys = override_keys

    def from_cli(self, path: str) -> bool:
        if path in self.cli_paths:
            return True
        parts = path.split(".")
        return any(".".join(parts[:i]) in self.override_keys for i in range(1, len(parts)))

    def _prefix(self, path: str) -> tuple[str, str]:
        if self.from_cli(path):
            return "command line", f" (overriding {self.label})"
        line = self.lines.get(path)
        return self.label, (f" (line {line})" if line else "")

    def fail(self, path: str, value: Any, expected: str, *, is_default: bool = False) -> NoReturn:
        source, suffix = self._prefix(path)
        default = " (default)" if is_default else ""
        raise InputError(f"{source}: key '{path}' = {_show(value)}{default}: {expected}{suffix}")

    def unknown(self, path: str, key: Any, allowed: tuple[str, ...] | list[str]) -> NoReturn:
        key_path = _join(path, str(key))
        source, suffix = self._prefix(key_path)
        raise InputError(f"{source}: key '{key_path}': {_unknown_text(key, allowed)}{suffix}")


def _build(cls: type, raw: Any, path: str, ctx: _Context,
           explicit: set[str]) -> Any:
    """Validate ``raw`` (a mapping or None) against dataclass ``cls``; record explicit keys."""
    fields = dataclasses.fields(cls)
    names = [f.name for f in fields]
    if raw is None:  # an empty section (all lines commented out) means all defaults
        raw = {}
    if not isinstance(raw, Mapping):
        if not path:
            raise InputError(f"{ctx.label}: expected a mapping of scenario keys at top level "
                             f"({', '.join(names)}), got {type(raw).__name__} {_show(raw)}")
        ctx.fail(path, raw, "expected a mapping with keys " + ", ".join(names))
    for key in raw:
        if key not in names:
            ctx.unknown(path, key, names)
    kwargs: dict[str, Any] = {}
    for f in fields:
        if f.name not in raw:
            continue
        key_path = _join(path, f.name)
        value = raw[f.name]
        explicit.add(key_path)
        if "section" in f.metadata:
            kwargs[f.name] = _build(f.metadata["section"], value, key_path, ctx, explicit)
            continue
        if "models" in f.metadata:
            kwargs[f.name] = _build_models(value, key_path, ctx, explicit)
            continue
        checker = f.metadata["check"]
        if isinstance(value, str) and not checker.takes_str and ctx.from_cli(key_path):
            value = _parse_cli_scalar(value)
        try:
            kwargs[f.name] = checker(value)
        except _Bad as bad:
            if bad.subkey is None:
                ctx.fail(key_path, value, bad.expected)
            sub_path = _join(key_path, bad.subkey)
            if bad.expected.startswith("unknown key"):
                ctx.unknown(key_path, bad.subkey, POLICIES)
            ctx.fail(sub_path, bad.value, bad.expected)
    return cls(**kwargs)


def _build_models(raw: Any, path: str, ctx: _Context, explicit: set[str]) -> dict[str, Any]:
    """The ``models`` section: model name -> validated parameter dataclass."""
    from .models import model_names, params_type_of

    if raw is None:
        return {}
    with_params = sorted({n for role in ("sut", "bv") for n in model_names(role) if params_type_of(n) is not None})
    if not isinstance(raw, Mapping):
        ctx.fail(path, raw, "expected a mapping of model name -> parameters (models with parameters: "
                 + ", ".join(with_params) + ")")
    out: dict[str, Any] = {}
    for name, section in raw.items():
        cls = params_type_of(str(name))
        if cls is None:
            ctx.unknown(path, name, with_params)
        out[str(name)] = _build(cls, section, _join(path, str(name)), ctx, explicit)
    return out


def _cross_check(cfg: ScenarioConfig, ctx: _Context, explicit: set[str]) -> None:
    count_text = f"bvs.count = {cfg.bvs.count}"
    if ctx.from_cli("bvs.count") and not ctx.from_cli("spawn.ramp_vehicles"):
        count_text += " (set on the command line)"
    if cfg.spawn.ramp_vehicles > cfg.bvs.count:
        ctx.fail("spawn.ramp_vehicles", cfg.spawn.ramp_vehicles,
                 f"expected an integer in [0, bvs.count] with {count_text}",
                 is_default="spawn.ramp_vehicles" not in explicit)
    ev = cfg.evaluation
    if ev.weight_safety + ev.weight_efficiency + ev.weight_interaction == 0:
        ctx.fail("evaluation.weight_safety", ev.weight_safety,
                 "expected weights not all 0 (evaluation.weight_safety, weight_efficiency, weight_interaction)")
    if cfg.bvs.count > 0 and sum(cfg.bvs.mix.values()) == 0:
        ctx.fail("bvs.mix", cfg.bvs.mix,
                 f"expected at least one non-zero share when {count_text}",
                 is_default="bvs.mix" not in explicit)


def evaluation_from_dict(raw: Any, source: str) -> EvaluationConfig:
    """Validate an ``evaluation`` section alone (e.g. from a bag's recorded scenario), as the
    whole file would be; ``source`` names it in errors."""
    cfg = _build(EvaluationConfig, raw, "evaluation", _Context(source, {}, set(), set()), set())
    if cfg.weight_safety + cfg.weight_efficiency + cfg.weight_interaction == 0:
        raise InputError(f"{source}: key 'evaluation.weight_safety' = 0: expected weights not all 0 "
                         "(evaluation.weight_safety, weight_efficiency, weight_interaction)")
    return cfg


def resolve_map_path(value: str, base_dir: str | Path | None = None) -> Path:
    """Resolve a ``map`` value to an existing file's absolute path.

    Order: ``value`` itself if absolute (``~`` expanded); else ``base_dir / value`` (the config
    file's directory; the current directory when ``base_dir`` is None); else
    ``share_path("maps/" + value)``. Raises InputError listing the places tried.
    """
    candidate = Path(os.path.expanduser(value))
    if candidate.is_absolute():
        tried = [candidate]
    else:
        base = Path(base_dir) if base_dir is not None else Path.cwd()
        tried = [base / candidate, *share_candidates(f"maps/{value}", _PACKAGE)]
    for path in tried:
        if path.is_file():
            return path.resolve()
    raise InputError(f"map '{value}': file not found (tried {', '.join(map(str, tried))})")


def config_from_dict(data: Any, *, source: str = "<dict>",
                     base_dir: str | Path | None = None,
                     overrides: Mapping[str, object] | None = None,
                     _lines: dict[str, int] | None = None) -> ScenarioConfig:
    """Validate an already-parsed mapping (e.g. from a ROS parameter file) into a config.

    ``source`` names it in error messages; ``base_dir`` anchors a relative ``map``.
    """
    from .models import discover

    discover()  # the registered models define the valid sut.model, bvs.driver and models.*
    override_keys: set[str] = set()
    cli_paths: set[str] = set()
    if overrides:
        data = _apply_overrides(data, overrides, source, override_keys, cli_paths)
    ctx = _Context(source, _lines or {}, cli_paths, override_keys)
    explicit: set[str] = set()
    cfg = _build(ScenarioConfig, data, "", ctx, explicit)
    _cross_check(cfg, ctx, explicit)
    map_base = None if ctx.from_cli("map") else base_dir
    try:
        # a relative map given on the command line is looked up from the current directory
        map_path = resolve_map_path(cfg.map, map_base)
    except InputError as exc:
        detail = str(exc).split(": ", 1)[1]
        ctx.fail("map", cfg.map, detail + "; expected an existing OpenDRIVE file: an absolute "
                 "path, a path relative to the config file, or a name under evoscen_sim maps/",
                 is_default="map" not in explicit)
    return dataclasses.replace(cfg, map=str(map_path))


def _apply_overrides(data: Any, overrides: Mapping[str, object], label: str,
                     override_keys: set[str], cli_paths: set[str]) -> dict[str, Any]:
    """Return a deep-enough copy of ``data`` with dotted-key overrides set."""
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        return data  # the top-level error is reported by _build
    result: dict[str, Any] = _copy_mappings(data)
    for key, value in overrides.items():
        parts = key.split(".") if isinstance(key, str) else []
        if not parts or not all(parts):
            raise InputError(f"command line: override key {_show(key)} = {_show(value)}: "
                             "expected a dotted key such as 'bvs.count'")
        node = result
        for i, part in enumerate(parts[:-1]):
            sub_path = ".".join(parts[: i + 1])
            child = node.get(part)
            if child is None:
                if part not in node:
                    cli_paths.add(sub_path)
                child = node[part] = {}
            elif not isinstance(child, dict):
                raise InputError(f"command line: key '{key}' = {_show(value)}: cannot set "
                                 f"inside '{sub_path}', which is {_show(child)} in {label}, "
                                 "not a mapping")
            node = child
        node[parts[-1]] = value
        override_keys.add(key)
        cli_paths.add(key)
    return result


def _copy_mappings(data: Mapping[Any, Any]) -> dict[Any, Any]:
    return {k: _copy_mappings(v) if isinstance(v, Mapping) else v for k, v in data.items()}


# --------------------------------------------------------------------------------------------
# Public API
# --------------------------------------------------------------------------------------------


def _source_dir(package: str) -> Path:
    here = Path(__file__).resolve().parents[1]  # ros2_ws/src/evoscen_sim
    return here if package == _PACKAGE else here.parent / package


def share_candidates(relative: str, package: str = _PACKAGE, source: Path | None = None) -> list[Path]:
    """Where a share file of ``package`` may live: the ament share directory (if any), then the source tree.

    The one package-path lookup of evoscen (:func:`share_path`, the map look-up, the BV
    package's policies and training config use it): ``share/<package>/<relative>`` of an
    installed workspace (the ament index; skipped when ament_index_python, the package or
    ``AMENT_PREFIX_PATH`` is missing), then ``source``, by default
    ``ros2_ws/src/<package>/<relative>`` (for files whose installed path mirrors their source
    path). The paths are returned whether or not they exist.
    """
    candidates: list[Path] = []
    try:
        from ament_index_python.packages import (  # type: ignore[import-not-found]
            PackageNotFoundError,
            get_package_share_directory,
        )
    except ImportError:
        pass
    else:
        try:
            candidates.append(Path(get_package_share_directory(package)) / relative)
        except (PackageNotFoundError, OSError, ValueError):
            # not installed, or no AMENT_PREFIX_PATH (OSError): use the source tree
            pass
    candidates.append(_source_dir(package) / relative if source is None else source)
    return candidates


def share_path(relative: str, package: str = _PACKAGE) -> Path:
    """Absolute path of ``relative`` in ``package``'s share directory.

    Tries the ament index (an installed workspace) first, then the source tree
    (``ros2_ws/src/<package>/<relative>``). Raises InputError if the file is in neither.
    """
    tried = share_candidates(relative, package)
    for candidate in tried:
        if candidate.exists():
            return candidate.resolve()
    raise InputError(f"{package} share file '{relative}': not found "
                     f"(tried {', '.join(map(str, tried))})")


def load_scenario_config(path: str | Path | None = None,
                         overrides: Mapping[str, object] | None = None) -> ScenarioConfig:
    """Load, override and validate a scenario YAML file (None: the shipped default).

    ``overrides`` maps dotted keys to values (``{"bvs.count": 5, "bvs.mix": "3:4:3"}``); they
    are applied before validation and get the same checks. Text values for non-text keys are
    read as YAML scalars (``"200"`` -> 200), as a command line would give them.
    """
    file_path = share_path(_DEFAULT_CONFIG) if path is None else Path(path)
    label = str(path) if path is not None else str(file_path)
    text = read_text_limited(file_path, label, "scenario config file", MAX_CONFIG_BYTES)
    data, lines = _parse_yaml(text, label)
    if not isinstance(data, Mapping):
        what = "an empty document" if data is None else f"{type(data).__name__} {_show(data)}"
        raise InputError(f"{label}: expected a mapping of scenario keys at top level, "
                         f"got {what}")
    return config_from_dict(data, source=label, base_dir=file_path.resolve().parent,
                            overrides=overrides, _lines=lines)


def config_to_dict(cfg: Any) -> dict[str, Any]:
    """Plain nested dict (str keys; int/float/str/bool/list values) of a config or section."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(cfg):
        out[f.name] = _plain(getattr(cfg, f.name))
    return out


def _plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return config_to_dict(value)
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def dump_config(cfg: ScenarioConfig, path: str | Path) -> None:
    """Write ``cfg`` as YAML that :func:`load_scenario_config` reads back to an equal config."""
    text = yaml.safe_dump(config_to_dict(cfg), sort_keys=False, default_flow_style=None)
    Path(path).write_text(f"# evoscen scenario '{cfg.name}'\n{text}", encoding="utf-8")


def mix_counts(cfg: ScenarioConfig | BvConfig) -> dict[str, int]:
    """Split ``bvs.count`` by ``bvs.mix`` with the largest-remainder (Hamilton) method.

    Each policy first gets floor(count * share / total); the vehicles left over go one each to
    the largest remainders, ties broken in the order competitive, mutual, cooperative.
    E.g. 20 at 4:3:3 -> 8/6/6; 7 at 1:1:1 -> 3/2/2.
    """
    bvs = cfg.bvs if isinstance(cfg, ScenarioConfig) else cfg
    weights = [int(bvs.mix.get(p, 0)) for p in POLICIES]
    total = sum(weights)
    if bvs.count == 0:
        return dict.fromkeys(POLICIES, 0)
    if total <= 0:
        raise InputError(f"bvs.mix = {_show(bvs.mix)}: expected at least one non-zero share "
                         f"when bvs.count = {bvs.count}")
    # exact integer arithmetic: quota_i = count * w_i / total
    counts = [bvs.count * w // total for w in weights]
    remainders = [bvs.count * w % total for w in weights]
    left = bvs.count - sum(counts)
    order = sorted(range(len(POLICIES)), key=lambda i: (-remainders[i], i))
    for i in order[:left]:
        counts[i] += 1
    return dict(zip(POLICIES, counts))
