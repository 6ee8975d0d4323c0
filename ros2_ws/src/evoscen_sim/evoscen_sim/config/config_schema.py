"""The scenario schema: one frozen dataclass per section, each field's default, check and meaning.

The defaults written here are the only ones: the simulation core takes :class:`VehicleParams`
and :class:`ControlParams` (the ``vehicle`` and ``control`` sections) as they are, and the
level-0 driver's and the re-entry's parameter objects take their defaults from
:class:`Level0Config` and :class:`ReentryConfig`. Validation, YAML and overrides live in
:mod:`evoscen_sim.config.config_load`; the checkers in :mod:`evoscen_sim.config.config_checks`.

The choice lists of ``sut.model`` and ``bvs.driver`` are the model registry's
(:data:`evoscen_sim.model_registry.SUT_MODELS`, :data:`~evoscen_sim.model_registry.BV_DRIVERS`), read at
validation time.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from evoscen_sim import model_registry as _registry
from evoscen_sim.config.config_checks import (
    POLICIES,
    _Bool,
    _BvNodes,
    _check,
    _Float,
    _Int,
    _MapPath,
    _MeanSd,
    _Mix,
    _Numbers,
    _Range,
    _section,
    _show,
    _StepSize,
    _Str,
)
from evoscen_sim.limits import MAX_STEPS
from evoscen_sim.errors import InputError

#: Bag compression modes selectable by ``recording.compression``.
COMPRESSIONS: tuple[str, ...] = ("zstd", "lz4", "none")

#: Upper bound of ``sut.s_m`` (the on-ramp map is 2393.76 m long).
MAX_S_M = 2393.0
#: Upper bound of the speed ranges ``spawn.speed_mps`` / ``level0.desired_speed_mps`` (m/s).
MAX_RANGE_SPEED_MPS = 40.0
#: Values of ``bvs.makeup`` (:mod:`evoscen_sim.traffic.makeup`).
MAKEUPS: tuple[str, ...] = ("uniform", "highd")
#: The ``bvs.driver`` values that can drive the cars of ``bvs.makeup: highd`` (drivers that take a desired
#: speed per vehicle: docs/bv-profiles.md, "Traffic make-up").
MAKEUP_CAR_DRIVERS: tuple[str, ...] = ("learned", "level0", "nilsson", "mobil")
#: Upper bound of ``bvs.count``.
MAX_BV_COUNT = 200



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
    driver: str = field(default="learned", metadata=_check(_Str(lambda: _registry.BV_DRIVERS)))
    """BV driver implementation, one of :data:`evoscen_sim.model_registry.BV_DRIVERS`: ``learned`` (default; the shipped
    TD3 policies of ``evoscen_bv``, the mix applies), ``level0``, ..."""
    nodes: str | int = field(default="by_policy", metadata=_check(_BvNodes()))
    """How the BVs are split over BV nodes (processes of the graph; the in-process runner models the
    same split): ``by_policy`` (default) one node per driver type present — competitive, mutual,
    cooperative for the learned drivers, one node named after the driver (``level0``, ``nilsson``,
    ``mobil``, a plug-in's) otherwise; ``single`` one node for all BVs; a number N in [1, 32]: the BVs
    split by id into N nodes of consecutive ids. A vehicle keeps its id and its driver type for the
    whole run (an entry at a window edge reuses its slot), so it stays with its node. The world, the
    events and the scores do not depend on the split (docs/architecture.md §5, "BV nodes")."""
    makeup: str = field(default="highd", metadata=_check(_Str(lambda: MAKEUPS)))
    """The traffic's make-up (docs/bv-profiles.md, "Traffic make-up"; :mod:`evoscen_sim.traffic.makeup`):
    ``highd`` (default) cars and trucks with lengths, widths and desired speeds (not capped) drawn
    from the highD dataset's figures (``models.highd``; Krajewski et al., ITSC 2018), trucks driven by
    the truck driver (``models.truck``), cars by ``bvs.driver`` (one of :data:`MAKEUP_CAR_DRIVERS`);
    needs ``traffic.mode: window``. ``uniform`` every BV a car of the ``vehicle`` section, its desired
    speed capped at the lane's limit (the default before evoscen 0.7.0). A bag records the key only when
    it is not ``uniform``: a bag's scenario without it was uniform traffic."""


@dataclass(frozen=True)
class SutConfig:
    """The system under test (SUT)."""

    model: str = field(default="level0", metadata=_check(_Str(lambda: _registry.SUT_MODELS)))
    """SUT decision model, one of :data:`evoscen_sim.model_registry.SUT_MODELS`."""
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
    """Re-entry of vehicles that leave the map (keeps the density constant); the defaults of
    :class:`evoscen_sim.physics.world.ReentryParams`."""

    ramp_share: float = field(default=0.2, metadata=_check(_Float(0.0, 1.0)))
    """Probability that a re-entering vehicle re-enters on the ramp (merge lane) instead of
    the mainline, [0, 1]."""
    min_gap_m: float = field(default=15.0, metadata=_check(_Float(0.0)))
    """Bumper-to-bumper gap required at the entry point (m), >= 0."""


#: Values of ``traffic.mode``.
TRAFFIC_MODES: tuple[str, ...] = ("window", "loop")


@dataclass(frozen=True)
class TrafficParams:
    """Where the traffic is during the run (docs/method.md §1 [choice]): the ``traffic`` section, and
    the parameters the traffic window takes as they are (:class:`evoscen_sim.physics.window.TrafficWindow`,
    built by :func:`evoscen_sim.traffic.scenario_params.traffic_params_from_config`): one declaration,
    one set of defaults and checks."""

    mode: str = field(default="window", metadata=_check(_Str(lambda: TRAFFIC_MODES)))
    """``window``: a window of traffic moves with the SUT (vehicles leave it and enter at its edges
    into safe gaps; the window is shifted back along the road where the road is uniform, so the
    SUT is never moved); ``loop``: vehicles that pass the road's end re-enter at its start (the
    ``reentry`` section), the SUT too."""
    behind_m: float = field(default=150.0, metadata=_check(_Float(0.0, 2000.0, lo_open=True)))
    """Window extent behind the SUT (m), (0, 2000]."""
    ahead_m: float = field(default=250.0, metadata=_check(_Float(0.0, 2000.0, lo_open=True)))
    """Window extent ahead of the SUT (m), (0, 2000]."""
    exit_margin_m: float = field(default=10.0, metadata=_check(_Float(0.0, 500.0)))
    """A BV leaves once its centre is this far beyond an edge of the window (m), [0, 500]."""
    lane_density_per_km: tuple[float, ...] = field(
        default=(12.5, 12.5, 12.5, 12.5), metadata=_check(_Numbers(0.0, 150.0)))
    """Target density of each mainline lane, rightmost (II) first (vehicles/km), [0, 150]."""
    lane_speed_mean_mps: tuple[float, ...] = field(
        default=(26.0, 28.0, 30.0, 32.0), metadata=_check(_Numbers(0.0, MAX_RANGE_SPEED_MPS)))
    """Mean entry speed of each mainline lane, rightmost first (m/s), [0, 40]."""
    lane_speed_sd_mps: tuple[float, ...] = field(default=(1.5, 1.5, 1.5, 1.5), metadata=_check(_Numbers(0.0, 10.0)))
    """Standard deviation of each lane's entry speed (m/s), [0, 10]; draws truncated at ±2 sd."""
    ramp_density_per_km: float = field(default=10.0, metadata=_check(_Float(0.0, 150.0)))
    """Target density of the merge lane while its start is in the window (vehicles/km), [0, 150]."""
    ramp_speed_mps: tuple[float, float] = field(
        default=(22.0, 2.0), metadata=_check(_MeanSd(0.0, MAX_RANGE_SPEED_MPS, 10.0)))
    """Entry speed on the merge lane: [mean, sd] (m/s)."""
    insertion_headway_s: float = field(default=1.0, metadata=_check(_Float(0.0, 10.0)))
    """τ of the safe-insertion rule: reaction time before braking (s), [0, 10]."""
    insertion_decel_mps2: float = field(default=4.5, metadata=_check(_Float(0.0, 10.0, lo_open=True)))
    """b of the safe-insertion rule (m/s^2), (0, 10] (SUMO's default decel)."""
    insertion_min_gap_m: float = field(default=2.5, metadata=_check(_Float(0.0, 50.0)))
    """g0 of the safe-insertion rule: standstill gap (m), [0, 50] (SUMO's default minGap)."""
    insertion_band_m: float = field(default=50.0, metadata=_check(_Float(0.0, 1000.0)))
    """When the edge itself is taken, a vehicle may enter the middle of the largest gap of its lane
    within this distance inside the window from the edge (m), [0, 1000]; 0 = the edge only."""
    entry_retry_s: float = field(default=1.0, metadata=_check(_Float(0.0, 60.0)))
    """A vehicle that found no safe place to enter tries again this long later (s), [0, 60], rounded to
    whole steps; 0 = at the next step (``uniform``'s rule before evoscen 0.8). [choice] 1 s under both
    make-ups (docs/method.md §1): the search every step cost ``uniform`` about a quarter of its step time."""
    warmup_s: float = field(default=20.0, metadata=_check(_Float(0.0, 600.0)))
    """Before step 0 the traffic evolves this long around the SUT's start (s), [0, 600]: BVs with
    their own drivers, the SUT driven by the level-0 lane keeper and held at sut.s_m (every vehicle
    is moved back by the SUT's advance each step), so every SUT model meets the same evolved start;
    nothing of it is recorded. 0 = start from the window's spawn."""
    shift_from_m: float = field(default=2000.0, metadata=_check(_Float(0.0, MAX_S_M)))
    """When the SUT reaches this arc length, every vehicle is moved back by shift_from_m - shift_to_m (m)."""
    shift_to_m: float = field(default=300.0, metadata=_check(_Float(0.0, MAX_S_M)))
    """Where the shift puts the SUT (m); the road must be uniform (same lanes, straight) over the
    window with its exit margins around both points (checked against the map)."""

    @property
    def lane_speed_mps(self) -> tuple[tuple[float, float], ...]:
        """(mean, standard deviation) of the entry speed of each mainline lane, rightmost first (m/s):
        ``lane_speed_mean_mps`` and ``lane_speed_sd_mps`` paired."""
        return tuple(zip(self.lane_speed_mean_mps, self.lane_speed_sd_mps))


TrafficConfig = TrafficParams
"""The ``traffic`` section's type: the traffic window's :class:`TrafficParams` itself."""


_POSITIVE = _check(_Float(0.0, lo_open=True))
_NON_NEGATIVE = _check(_Float(0.0))


@dataclass(frozen=True)
class VehicleParams:
    """Vehicle body and single-track model limits (all > 0): the ``vehicle`` section, and the
    physical limits the simulation core takes (:mod:`evoscen_sim.physics.vehicle`; the same for every
    vehicle of a scenario)."""

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


VehicleConfig = VehicleParams
"""The ``vehicle`` section's type: the core's :class:`VehicleParams` itself (one type, one set of defaults)."""


@dataclass(frozen=True)
class ControlParams:
    """Low-level dual PID lateral controller (lateral offset + heading error): the ``control``
    section, and the gains the controller takes (:mod:`evoscen_sim.physics.control`).

    Cascaded loops, gain-scheduled by speed (see :mod:`evoscen_sim.physics.control`): the
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
    max_lateral_speed_mps / sin(cap) (~3 m/s), see evoscen_sim.physics.control."""


ControlConfig = ControlParams
"""The ``control`` section's type: the controller's :class:`ControlParams` itself."""


@dataclass(frozen=True)
class Level0Config:
    """Level-0 driver: IDM car following, lane keeping except forced merges.

    The single source of the level-0 defaults: :class:`evoscen_bv.level0.Level0Params` (the
    driver's structured form) takes its defaults from ``Level0Config()``."""

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
#: ``evaluation.rear_conflicts`` values (see :mod:`evoscen_sim.danger.safety`).
REAR_CONFLICT_MODES = ("after_lane_change", "all", "none")
#: ``evaluation.rear_braking`` values (see :mod:`evoscen_sim.danger.safety`).
REAR_BRAKING_RULES = ("within_headway", "any")
#: ``evaluation.hard_braking`` values (see :mod:`evoscen_sim.danger.safety`).
HARD_BRAKING_RULES = ("conflict", "own")
#: ``evaluation.undefined_terms`` values.
UNDEFINED_TERM_RULES = ("exclude", "literal")
#: ``evaluation.count_normalisation`` values.
COUNT_NORMALISATIONS = ("method_length", "literal")
#: ``evaluation.score_form`` values: the score experiments compare SUTs with (docs/evaluation.md §10).
SCORE_FORMS = ("comparative", "method")
#: The ``evaluation`` keys a bag's scenario record carries only when they differ from their defaults
#: (:func:`evoscen_record.scenario_record.scenario_metadata`): they select and shape the comparative
#: score (docs/evaluation.md §10), which reads nothing the recording depends on, so a run at the
#: defaults records the same bytes as before the keys existed; a recorded section without them is
#: scored with their defaults.
RECORDED_WHEN_SET = ("score_form", "no_lane_change_value", "safety_rate_scale_per_km", "collision_exposures")


@dataclass(frozen=True)
class EvaluationConfig:
    """Scoring of the SUT and of the scenario (docs/method.md §5.1-5.2; see :mod:`evoscen_eval.scoring.metrics`).

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
    count_normalisation: str = field(default="method_length", metadata=_check(_Str(lambda: COUNT_NORMALISATIONS)))
    """How the safety score's counts C and E enter I_s: method_length = scaled to the method's
    run length, C*(N_ref/N) and E*(N_ref/N) with N the steps scored and N_ref =
    count_reference_steps (a run of N_ref steps scores its counts as they are; a shorter or
    longer run of the same SUT in the same traffic has the same expected I_s); literal = the
    counts of the run as they are (a longer run scores lower). See docs/evaluation.md §1.1."""
    count_reference_steps: int = field(default=3000, metadata=_check(_Int(1, MAX_STEPS)))
    """N_ref of count_normalisation: method_length, in steps (the method's 3,000-step runs)."""
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
    rear_braking_headway_s (the SUT can have caused it); any = every such braking (the
    earlier rule: counted followers braking 30-160 m behind for reasons of their own). See
    docs/evaluation.md."""
    rear_braking_headway_s: float = field(default=2.0, metadata=_POSITIVE)
    """Time headway below which a follower's hard braking is the SUT's to answer for (s; the
    two-second rule)."""
    hard_braking: str = field(default="conflict", metadata=_check(_Str(lambda: HARD_BRAKING_RULES)))
    """Which hard braking of the SUT makes a state dangerous: conflict = needed (its DRAC to the
    leader above hard_brake_mps2) or imposed on a follower within rear_braking_headway_s; own =
    every SUT deceleration beyond hard_brake_mps2 (the method's words; rewards a SUT that cannot
    brake hard). See docs/evaluation.md."""
    cut_in_gap_m: float = field(default=10.0, metadata=_NON_NEGATIVE)
    """A SUT lane change whose new follower is closer than this (m, bumper to bumper) makes the
    state dangerous (a cut-in; the method's rule constraint for BV lane changes: 10 m); 0 = off,
    the definition before cut-ins counted. See docs/evaluation.md."""
    beside_lane_change: bool = field(default=True, metadata=_check(_Bool()))
    """A SUT lane change while a vehicle in its target lane overlaps it longitudinally (beside
    it) makes the state dangerous, whatever that vehicle does next; false = off, the definition
    before. See docs/evaluation.md §3.7."""
    headway_threshold_s: float = field(default=1.0, metadata=_NON_NEGATIVE)
    """The SUT following its leader with a time headway (gap / own speed) below this (s) without
    falling back (own speed >= the leader's) makes the state dangerous: tailgating; 0 = off, the
    definition before (the method's TTC and hard braking only). See docs/evaluation.md §2."""
    headway_grace_s: float = field(default=2.0, metadata=_NON_NEGATIVE)
    """The tailgating condition makes a state dangerous only once it has held for more than this
    long without a break (s): a SUT that finds itself too close — a vehicle cut in ahead of it — and
    restores the gap within it is not tailgating; 0 = from its first state. See docs/evaluation.md §2."""
    drac_threshold_mps2: float = field(default=3.0, metadata=_POSITIVE)
    """Reported counts of states whose DRAC exceeds this (m/s^2; SUMO SSM's default 3)."""
    ssm_ttc_threshold_s: float = field(default=3.0, metadata=_POSITIVE)
    """Surrogate-safety profile (reported only): TTC below this (s) is a TTC episode and counts
    in TET/TIT (SUMO SSM's default 3; its DRAC threshold is ``drac_threshold_mps2``)."""
    ssm_pet_threshold_s: float = field(default=2.0, metadata=_POSITIVE)
    """Surrogate-safety profile (reported only): a SUT lane change whose PET is below this (s)
    is a PET event (SUMO SSM's default 2)."""
    undefined_terms: str = field(default="exclude", metadata=_check(_Str(lambda: UNDEFINED_TERM_RULES)))
    """A score term undefined in the run (T_l without a completed SUT lane change; I_i without
    any SUT lane change): exclude = left out and the remaining weights renormalised;
    literal = T_l = no_lane_change_time_s and I_i = 1 (the method's arithmetic taken literally)."""
    score_form: str = field(default="comparative", metadata=_check(_Str(lambda: SCORE_FORMS)))
    """The score evoscen's experiments compare SUTs with (sensitivity, intelligence, leaderboard,
    campaigns): comparative = the comparative score D (report.json ``comparative``: every term
    defined in every run, safety per SUT-km without saturation, progress relative to the traffic);
    method = the method's intelligence I (``intelligence``, as shaped by the keys above). Every
    report carries both. See docs/evaluation.md §10."""
    no_lane_change_value: float = field(default=0.5, metadata=_check(_Float(0.0, 1.0)))
    """Comparative score: the value of its lane-change time and interaction terms in a run without
    (completed) SUT lane change, in [0, 1], the same for every SUT; 0.5 = the middle of the
    terms' range (docs/evaluation.md §10)."""
    safety_rate_scale_per_km: float = field(default=1.0, metadata=_POSITIVE)
    """Comparative score: the exposure rate per SUT-km at which its safety term is 1/2,
    S = 1/(1 + r/scale) (docs/evaluation.md §10)."""
    collision_exposures: float = field(default=10.0, metadata=_NON_NEGATIVE)
    """Comparative score: a SUT collision counts as this many exposures in the safety rate
    (docs/evaluation.md §10)."""


#: Values of ``challenge.mode`` (docs/challenges.md).
CHALLENGE_MODES: tuple[str, ...] = ("none", "naturalistic", "nade")


@dataclass(frozen=True)
class ChallengeConfig:
    """The challenge layer (docs/challenges.md): the hard braking of the SUT's leader as a process of the
    simulation, for every BV driver, its onsets drawn from a distribution tilted towards the states where
    they are critical, each run weighted by its likelihood ratio."""

    mode: str = field(default="none", metadata=_check(_Str(lambda: CHALLENGE_MODES)))
    """``none`` (default): no layer; the learned BVs brake hard by their own rule (``models.learned.hard_brake``).
    ``naturalistic``: the layer with the naturalistic onset rate (every BV driver, trucks and rule-based
    drivers included; weight 1). ``nade``: the layer with the tilted rate (weights p/q in the report and the
    bag). Under both the learned BVs' own rule is off; the process's rate, decelerations and durations are
    ``models.learned.hard_brake_*``'s."""
    max_multiplier: float = field(default=300.0, metadata=_check(_Float(1.0, 1.0e4)))
    """``nade``: how many times likelier an onset is at the shortest headways (q/p = M). [choice] 300:
    about one onset in a 30-s episode whose SUT follows within 1 s for 10 s (docs/challenges.md, "The tilt")"""
    headway_full_s: float = field(default=1.0, metadata=_check(_Float(0.0)))
    """``nade``: at the SUT's time headway to its leader at or below this (s), the onset rate is M times the
    naturalistic one. [choice] 1.0 s."""
    headway_none_s: float = field(default=2.0, metadata=_check(_Float(0.0, lo_open=True)))
    """``nade``: at this time headway (s) or above, the naturalistic rate (q/p = 1); linear in between.
    [choice] 2.0 s, the two-second rule."""


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
    """Re-entry of vehicles leaving the map (``traffic.mode: loop``)."""
    traffic: TrafficConfig = _section(TrafficConfig)
    """The traffic window around the SUT."""
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
    challenge: ChallengeConfig = _section(ChallengeConfig)
    """The challenge layer (``challenge.mode``; docs/challenges.md)."""
    models: dict[str, Any] = field(default_factory=dict, metadata={"models": True})
    """Parameters of driver models by model name (``models.mobil.politeness: 0.5``), each
    validated against the model's parameter dataclass (:mod:`evoscen_sim.model_registry`); a model
    not listed uses its defaults."""


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
