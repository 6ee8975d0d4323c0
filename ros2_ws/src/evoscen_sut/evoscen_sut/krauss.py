"""SUMO's default car-following model ``Krauss``: the longitudinal control of every SUT (docs/method.md §4).

A port of SUMO's default ``carFollowModel="Krauss"`` with the default *semi-implicit Euler*
position update (``--step-method.ballistic false``) and ``actionStepLength`` = the step
``Δt``. Sources (eclipse-sumo/sumo): ``src/microsim/cfmodels/MSCFModel_Krauss.cpp``
(``followSpeed``, ``dawdle2``, ``patchSpeedBeforeLC``), ``MSCFModel_KraussOrig1.cpp`` (the
original ``vsafe``), ``MSCFModel.cpp`` (``maximumSafeFollowSpeed``,
``maximumSafeStopSpeedEuler``, ``brakeGapEuler``, ``calculateEmergencyDeceleration``,
``finalizeSpeed``, ``maxNextSpeed``, ``minNextSpeed[Emergency]``), ``MSVehicle.cpp``
(``planMoveInternal``: the lane speed cap), ``MSCFModel.h``
(``EMERGENCY_DECEL_AMPLIFIER = 1.2``), ``NUMERICAL_EPS = 0.001``.

Notation: ``v`` own speed, ``v_l`` leader speed, ``a`` = accel, ``b`` = decel, ``e`` =
emergencyDecel, ``τ`` = tau, ``σ`` = sigma, ``Δt`` the step, ``v_max = min(desired speed,
lane speed limit)`` (SUMO: ``lane->getVehicleMaxSpeed`` = min(vType maxSpeed, speed limit ×
speedFactor); ``desired_speed_mps`` plays the role of speedFactor × limit, speedFactor 1).

**Gaps.** Our gaps are bumper-to-bumper (:mod:`evoscen_sim.physics.neighbors`). SUMO's follow gap is
``leader's rear bumper − (follower's front bumper + minGap)``, so this module uses::

    g = gap_bumper_to_bumper − min_gap_m

A follower that comes to rest behind a stopped leader therefore stops ``min_gap_m`` (+ 1 mm,
``NUMERICAL_EPS``) behind it. Vehicle length does not enter the model (SUMO's default
length is 5 m, our vehicles are 4.8 m; only the bumper gap matters).

**Safe speed, continuous form** (Krauss 1998; SUMO ``MSCFModel_KraussOrig1::vsafe``),
:func:`krauss_safe_speed`::

    v_safe = −τ b + √((τ b)² + v_l² + 2 b g)

**Safe speed as SUMO's default Krauss computes it** (Euler, per step),
:func:`sumo_follow_speed`:

1. the leader's braking distance, stepwise with ``b' = max(b, b_leader)`` (``brakeGapEuler``,
   headway 0): ``k = ⌊v_l / (b' Δt)⌋``, ``D = Δt (k v_l − b' Δt k (k+1)/2)``;
2. the largest speed from which the follower, reacting after ``τ`` and then braking by
   ``b Δt`` per step, stops within ``G = g + D − 0.001`` (``maximumSafeStopSpeedEuler``;
   0 if ``G < 0``)::

       n = ⌊1/2 − (τ − √((2τ − Δt)² + 8 Δt G / (b Δt)) / 2) / Δt⌋
       h = n (n − 1) b Δt² / 2 + n b Δt τ,   x = n b Δt + (G − h) / (n Δt + τ)

3. emergency braking (``maximumSafeFollowSpeed``, when ``e ≠ b``): if reaching ``x`` needs a
   deceleration ``d0 = (v − x)/Δt > b + 0.001``, the deceleration becomes
   ``d = min(d0, max(b, 1.2 · d_e))`` with ``d_e`` from ``calculateEmergencyDeceleration``
   (``d_e = v² / (2 (g + v_l²/(2 b_leader))))`` if that is ≤ ``b_leader``, else
   ``(v² − v_l²) / (2 g)``, or ``−e Δt`` when ``g ≤ 0``) and ``x = max(0, v − d Δt)``.
   SUMO quirk kept: with ``g ≤ 0`` (bumper gap below ``min_gap_m``) and a leader that cannot
   be avoided with ``b_leader``, ``d_e < 0`` and the braking stays at ``b``.

**Next speed** (``followSpeed`` + ``finalizeSpeed`` + ``dawdle2``), with ``U ~ uniform[0, 1)``
(one draw per vehicle per step)::

    v_pos  = min(v + a Δt, max(v_max, v − b Δt), x)        (x = +∞ without a leader)
    v_min  = min(max(0, v − b Δt), max(v_pos, max(0, v − e Δt)))
    v_high = max(v_min, v_pos)
    v_next = max(v_min, max(0, v_high − σ Δt U · (v_high if v_high < a else a)))

(the comparison of a speed with ``a`` is SUMO's, unit quirk included; ``max(v_max, v − b Δt)``
is ``MSVehicle::planMoveInternal``'s "speed limits are not emergencies": above the cap the
vehicle slows at ``b``). The acceleration returned is ``(v_next − v) / Δt``, always within
``[−max(b, e), a]``; the position update SUMO pairs with it is ``s += v_next Δt``.

**Free-road mean speed.** Once ``v ≥ v_max − σ a Δt`` (and ``v_max ≥ a``, σ < 1) every
step gives ``v_high = v_max`` and ``v_next = v_max − σ a Δt U``, so the speeds are i.i.d.
uniform on ``(v_max − σ a Δt, v_max]``: mean ``v_max − σ a Δt / 2`` (defaults, Δt = 0.1 s:
33.33 − 0.065 m/s), standard deviation ``σ a Δt / √12``. With σ = 0 the speed is exactly
``v_max``.

Not ported (not used by the default setup): the ballistic update, ``sigmaStep`` > Δt,
driver-state perception errors, junction/stop handling, ``apparentDecel`` ≠ decel.

**Parameters.** :class:`KraussParams` is the scenario YAML's ``models.krauss`` section
(registered by :mod:`evoscen_sut.sut_models`, validated like every key): every model that drives
with Krauss (Nilsson, MOBIL and Stackelberg, as SUT or as BV driver, and the mutants of them)
builds its car follower with :func:`krauss_for`, which reads it; absent, SUMO's defaults.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from evoscen_sim.config.scenario_config import number
from evoscen_sim.jit import kernel
from evoscen_sim.physics.neighbors import OWN

__all__ = [
    "EMERGENCY_DECEL_AMPLIFIER",
    "NAME",
    "NUMERICAL_EPS",
    "KraussCarFollowing",
    "KraussParams",
    "krauss_for",
    "krauss_next_speed",
    "krauss_params_from_config",
    "krauss_safe_speed",
    "sumo_follow_speed",
]

NAME = "krauss"
"""The parameter set's name: the scenario YAML's ``models.krauss``."""

NUMERICAL_EPS = 0.001
"""SUMO's ``NUMERICAL_EPS`` (m): the stop gap is shortened by it."""
EMERGENCY_DECEL_AMPLIFIER = 1.2
"""SUMO's ``EMERGENCY_DECEL_AMPLIFIER`` (MSCFModel.h)."""


@dataclass(frozen=True)
class KraussParams:
    """Krauss parameters, the scenario YAML's ``models.krauss``; defaults are SUMO's default
    passenger vType (SUMO docs, "Vehicle Type Parameter Defaults")."""

    accel_mps2: float = number(2.6, 0.0, 20.0, lo_open=True)
    """Maximum acceleration ``accel`` (m/s²); SUMO default 2.6."""
    decel_mps2: float = number(4.5, 0.0, 20.0, lo_open=True)
    """Comfortable (safe-speed) deceleration ``decel`` (m/s²); SUMO default 4.5. Also taken
    as every leader's deceleration (SUMO: the leader's ``apparentDecel`` = its decel)."""
    emergency_decel_mps2: float = number(9.0, 0.0, 30.0, lo_open=True)
    """Maximum deceleration ``emergencyDecel`` (m/s²) when ``decel`` is not enough; SUMO
    default 9.0 for passenger cars."""
    sigma: float = number(0.5, 0.0, 1.0)
    """Driver imperfection ``sigma`` (dawdling, dimensionless, 0..1); SUMO default 0.5."""
    tau_s: float = number(1.0, 0.0, 10.0, lo_open=True)
    """Reaction time / desired time headway ``tau`` (s); SUMO default 1.0."""
    min_gap_m: float = number(2.5, 0.0, 20.0)
    """Standstill gap ``minGap`` (m, bumper to bumper); SUMO default 2.5."""
    desired_speed_mps: float = number(33.33, 0.0, 60.0, lo_open=True)
    """Desired speed (m/s): SUMO's speedFactor (1) × the 120 km/h limit of the evoscen road;
    the speed is also capped by the lane speed limit (so above 33.33 it changes nothing on the
    shipped map)."""
    speed_factor_sd: float = number(0.1, 0.0, 1.0)
    """Standard deviation of the speed factor of every Krauss-driven vehicle but the SUT (the
    Nilsson and MOBIL BVs): each gets desired_speed_mps × f, f drawn once from a normal
    distribution of mean 1 cut to [0.2, 2] (SUMO's default passenger vType: speedDev 0.1,
    ``normc(1, 0.1, 0.2, 2)``). [choice] 0.1: with every BV at the SUT's desired speed (0, the
    earlier form) rule-based BVs in the traffic window formed one platoon with the SUT: no BV
    changed lanes in 3,000 steps (traced). The SUT (vehicle 0) always has f = 1."""


# ------------------------------------------------------------------------ scalar kernels
@kernel
def _brake_gap_euler(speed, decel, dt):
    """SUMO ``brakeGapEuler(speed, decel, headwayTime=0)``: distance braking by ``decel Δt`` per step."""
    reduction = decel * dt
    steps = int(speed / reduction)
    return dt * (steps * speed - reduction * steps * (steps + 1) / 2.0)


@kernel
def _max_safe_stop_speed_euler(gap, decel, tau, dt):
    """SUMO ``maximumSafeStopSpeedEuler(gap, decel, onInsertion, headway=tau)``."""
    g = gap - NUMERICAL_EPS
    if g < 0.0:
        return 0.0
    b = decel * dt
    t = tau
    s = dt
    n = np.floor(0.5 - ((t + (np.sqrt((s * s) + (4.0 * ((s * (2.0 * g / b - t)) + (t * t))))) * -0.5) / s))
    h = 0.5 * n * (n - 1.0) * b * s + n * b * t
    r = (g - h) / (n * s + t)
    return n * b + r


@kernel
def _emergency_decel(gap, speed, leader_speed, leader_decel, emergency_decel, dt):
    """SUMO ``calculateEmergencyDeceleration`` (its ``−ACCEL2SPEED(e)`` return for ``g ≤ 0`` kept)."""
    denom = gap + 0.5 * leader_speed * leader_speed / leader_decel
    if denom != 0.0:  # 0 gives inf or nan in C++: neither is <= leader_decel
        b1 = 0.5 * speed * speed / denom
        if b1 <= leader_decel:
            return b1
    if gap <= 0.0:
        return -emergency_decel * dt
    return 0.5 * (speed * speed - leader_speed * leader_speed) / gap


@kernel
def follow_speed_scalar(gap, speed, leader_speed, decel, emergency_decel, tau, dt):
    """SUMO ``maximumSafeFollowSpeed`` for one vehicle; ``gap`` is SUMO's (bumper gap − minGap).

    The leader's deceleration is taken equal to ``decel``. ``gap = inf`` or a NaN leader
    speed (no leader) gives ``inf``.
    """
    if not (gap < np.inf) or np.isnan(leader_speed):
        return np.inf
    leader_decel = decel
    x = _max_safe_stop_speed_euler(gap + _brake_gap_euler(leader_speed, max(decel, leader_decel), dt),
                                   decel, tau, dt)
    if decel != emergency_decel:
        orig = (speed - x) / dt
        if orig > decel + NUMERICAL_EPS:
            safe = EMERGENCY_DECEL_AMPLIFIER * _emergency_decel(gap, speed, leader_speed, leader_decel,
                                                                emergency_decel, dt)
            safe = max(safe, decel)
            safe = min(safe, orig)
            x = max(speed - safe * dt, 0.0)
    return x


@kernel
def next_speed_scalar(speed, max_speed, gap, leader_speed, u, accel, decel, emergency_decel, sigma, tau, dt):
    """Krauss speed after one step for one vehicle (module docstring); ``gap`` is SUMO's gap."""
    # MSVehicle::planMoveInternal: "speed limits are not emergencies" (laneMaxV >= minNextSpeed)
    v_pos = min(speed + accel * dt, max(max_speed, max(speed - decel * dt, 0.0)))
    v_pos = min(v_pos, follow_speed_scalar(gap, speed, leader_speed, decel, emergency_decel, tau, dt))
    v_min = min(max(speed - decel * dt, 0.0), max(v_pos, max(speed - emergency_decel * dt, 0.0)))
    v_high = max(v_min, v_pos)
    if v_high < accel:
        dawdled = v_high - sigma * v_high * u * dt
    else:
        dawdled = v_high - sigma * accel * u * dt
    return max(v_min, max(0.0, dawdled))


@kernel
def _next_speed_kernel(speed, max_speed, gap_bb, leader_speed, u, min_gap, accel, decel,
                       emergency_decel, sigma, tau, dt):
    n = speed.shape[0]
    out = np.empty(n)
    for k in range(n):
        out[k] = next_speed_scalar(speed[k], max_speed[k], gap_bb[k] - min_gap, leader_speed[k], u[k],
                                   accel, decel, emergency_decel, sigma, tau, dt)
    return out


@kernel
def _follow_speed_kernel(gap_bb, speed, leader_speed, min_gap, decel, emergency_decel, tau, dt):
    n = gap_bb.shape[0]
    out = np.empty(n)
    for k in range(n):
        out[k] = follow_speed_scalar(gap_bb[k] - min_gap, speed[k], leader_speed[k], decel, emergency_decel, tau, dt)
    return out


def _flat(*arrays) -> tuple[tuple[int, ...], list[np.ndarray]]:
    shape = np.broadcast_shapes(*(np.shape(a) for a in arrays))
    return shape, [np.ascontiguousarray(np.broadcast_to(np.asarray(a, dtype=float), shape)).ravel() for a in arrays]


# ------------------------------------------------------------------------ public functions
def krauss_safe_speed(gap_m, leader_speed_mps, tau_s: float, decel_mps2: float) -> np.ndarray:
    """Continuous Krauss safe speed ``−τb + √((τb)² + v_l² + 2 b g)`` (m/s); no randomness.

    ``gap_m`` is SUMO's gap: the bumper-to-bumper gap **minus** ``min_gap_m``. Broadcasts like
    numpy. No leader (``gap_m = inf`` or a NaN leader speed) gives ``inf``; a radicand below
    0 (a negative gap) gives 0. This is the prediction form (``MSCFModel_KraussOrig1::vsafe``
    without its small-gap workaround); the stepped form the model drives with is
    :func:`sumo_follow_speed`.
    """
    g = np.asarray(gap_m, dtype=float)
    vl = np.asarray(leader_speed_mps, dtype=float)
    tb = tau_s * decel_mps2
    no_leader = ~(g < np.inf) | np.isnan(vl)
    with np.errstate(invalid="ignore"):
        rad = tb * tb + np.where(no_leader, 0.0, vl) ** 2 + 2.0 * decel_mps2 * np.where(no_leader, 0.0, g)
        v = np.maximum(-tb + np.sqrt(np.maximum(rad, 0.0)), 0.0)
    return np.where(no_leader, np.inf, v)


def sumo_follow_speed(gap_m, speed_mps, leader_speed_mps, params: KraussParams, dt_s: float) -> np.ndarray:
    """SUMO's per-step safe follow speed (``maximumSafeFollowSpeed``, module docstring) (m/s).

    ``gap_m`` is the **bumper-to-bumper** gap (``min_gap_m`` is subtracted here); no leader
    (``inf`` gap or NaN leader speed) gives ``inf``. Broadcasts like numpy; no randomness.
    """
    shape, (g, v, vl) = _flat(gap_m, speed_mps, leader_speed_mps)
    p = params
    out = _follow_speed_kernel(g, v, vl, p.min_gap_m, p.decel_mps2, p.emergency_decel_mps2, p.tau_s, float(dt_s))
    return out.reshape(shape)


def krauss_next_speed(speed_mps, max_speed_mps, gap_m, leader_speed_mps, uniform, params: KraussParams,
                      dt_s: float) -> np.ndarray:
    """Krauss speed after one step (m/s), SUMO's ``finalizeSpeed`` with dawdling.

    ``gap_m`` bumper-to-bumper (``inf`` / NaN leader speed: no leader), ``max_speed_mps`` the
    speed cap ``v_max``, ``uniform`` the dawdling draws in [0, 1). Broadcasts like numpy.
    """
    shape, (v, vmax, g, vl, u) = _flat(speed_mps, max_speed_mps, gap_m, leader_speed_mps, uniform)
    p = params
    out = _next_speed_kernel(v, vmax, g, vl, u, p.min_gap_m, p.accel_mps2, p.decel_mps2, p.emergency_decel_mps2,
                             p.sigma, p.tau_s, float(dt_s))
    return out.reshape(shape)


class KraussCarFollowing:
    """Krauss longitudinal control for vehicles of a traffic view (:mod:`evoscen_sim.loop.view`).

    Args:
        params: the model parameters.
        rng: the seeded generator of the dawdling draws (one ``rng.random`` per vehicle per
            :meth:`acceleration` call, in the order of ``vehicles``; drawn also when σ = 0).
        dt_s: the step the acceleration is held for (the scenario's ``dt_s``).
    """

    def __init__(self, params: KraussParams, rng: np.random.Generator, dt_s: float,
                 speed_factors: dict[int, float] | None = None) -> None:
        if not dt_s > 0.0:
            raise ValueError(f"KraussCarFollowing: dt_s = {dt_s} must be > 0")
        self.params = params
        self.rng = rng
        self.dt_s = float(dt_s)
        self.speed_factors = dict(speed_factors or {})
        """Speed factor by world index (missing: 1), :func:`draw_speed_factors`."""

    def factors(self, idx: np.ndarray) -> np.ndarray:
        """The speed factor of each vehicle ``idx`` (1 where none was drawn)."""
        f = self.speed_factors
        return np.array([f.get(int(i), 1.0) for i in idx], dtype=float) if f else np.ones(len(idx))

    def acceleration(self, view, vehicles: np.ndarray, lane_offset: np.ndarray | None = None) -> np.ndarray:
        """Next-step acceleration (m/s²) of ``vehicles`` (world indices).

        Each vehicle follows the nearest leader in lane ``lane + lane_offset`` (offsets in
        -2..+2, +1 = left; default 0, the own lane), from the view's neighbourhood; no leader
        means free road. The speed cap is ``min(desired_speed_mps, speed limit of the
        vehicle's own lane at its position)`` (a missing limit is ignored). Result: ``(v_next −
        v) / dt_s`` with ``v_next`` from :func:`krauss_next_speed`, always in
        ``[−max(decel, emergency_decel), accel]``.
        """
        idx = np.asarray(vehicles, dtype=np.int64)
        m = idx.shape[0]
        col = np.full(m, OWN, dtype=np.int64)
        if lane_offset is not None:
            off = np.asarray(lane_offset, dtype=np.int64)
            if off.shape != (m,) or np.any(np.abs(off) > 2):
                raise ValueError(f"lane_offset: expected {m} offsets in -2..+2, got {off!r}")
            col = col + off
        u = self.rng.random(m)
        if m == 0:
            return np.zeros(0)
        nb = view.neighborhood()
        gap = nb.gap_front_m[idx, col]
        v_lead = nb.leader_speed_mps[idx, col]
        v = np.asarray(view.v, dtype=float)[idx]
        p = self.params
        v_max = np.fmin(np.asarray(view.speed_limit_mps, dtype=float)[idx], p.desired_speed_mps * self.factors(idx))
        v_next = _next_speed_kernel(np.ascontiguousarray(v), np.ascontiguousarray(v_max),
                                    np.ascontiguousarray(gap), np.ascontiguousarray(v_lead), u,
                                    p.min_gap_m, p.accel_mps2, p.decel_mps2, p.emergency_decel_mps2,
                                    p.sigma, p.tau_s, self.dt_s)
        return (v_next - v) / self.dt_s


def krauss_params_from_config(config) -> KraussParams:
    """The scenario's ``models.krauss`` (:class:`KraussParams`; its defaults when the section is
    absent or ``config`` has no ``models``)."""
    params = (getattr(config, "models", None) or {}).get(NAME)
    return KraussParams() if params is None else params


SUT_INDEX = 0
"""The SUT's world index: it never gets a speed factor other than 1."""


def draw_speed_factors(params: KraussParams, vehicles, rng: np.random.Generator) -> dict[int, float]:
    """One speed factor per vehicle but the SUT, in the order of ``vehicles``: normal(1,
    ``speed_factor_sd``), drawn again until it lies in [0.2, 2] (SUMO's ``normc``); none (no
    draw) when ``speed_factor_sd`` is 0."""
    out: dict[int, float] = {}
    if params.speed_factor_sd <= 0.0:
        return out
    for i in np.asarray(vehicles, dtype=np.int64):
        if int(i) == SUT_INDEX:
            continue
        f = rng.normal(1.0, params.speed_factor_sd)
        while not 0.2 <= f <= 2.0:
            f = rng.normal(1.0, params.speed_factor_sd)
        out[int(i)] = float(f)
    return out


def krauss_for(config, rng: np.random.Generator, vehicles=None) -> KraussCarFollowing:
    """The Krauss car follower of a scenario: ``models.krauss``, dawdling from ``rng``, the step
    ``config.dt_s``; the speed factors of ``vehicles`` (all but the SUT) drawn first from ``rng``."""
    params = krauss_params_from_config(config)
    factors = draw_speed_factors(params, vehicles, rng) if vehicles is not None else None
    return KraussCarFollowing(params, rng, config.dt_s, factors)
