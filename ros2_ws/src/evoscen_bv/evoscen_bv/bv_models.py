"""The BV package's built-in driver models, registered with :mod:`evoscen_sim.model_registry`.

* ``level0`` (roles ``bv`` and ``sut``): the level-0 driver (:mod:`evoscen_bv.level0`),
  parameters from the scenario's ``level0`` section.
* ``learned`` (role ``bv``): the TD3-trained social drivers (:mod:`evoscen_bv.learned`) —
  every BV drives with the trained car-following controller and decides lane changes with
  the policy of its code in the world (competitive, mutual, cooperative: ``bvs.mix``).
  Parameters ``models.learned``: ``policy_dir``, ``on_missing``, ``profile``, ``lane_hold_s``, ``cut_in_decel_mps2``,
  ``into_ending_lane``, ``forced_merge_m``, ``merge_seek``, ``hold_on_entry``
  ``standing_leader_at_once`` and the hard braking of the SUT's leader ``hard_brake``,
  ``hard_brake_per_1000km``, ``hard_brake_decel_min_mps2``, ``hard_brake_decel_max_mps2``,
  ``hard_brake_duration_min_s``, ``hard_brake_duration_max_s``, ``hard_brake_min_speed_mps``
  (:class:`LearnedParams`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from evoscen_sim.config.scenario_config import flag, number, text
from evoscen_sim.errors import InputError
from evoscen_sim.model_registry import ModelSpec, register_makeup_driver, register_model, register_parameter_set
from evoscen_sim.traffic.makeup import HighdMakeupParams, shipped_policy_set

from .level0 import Level0Driver, level0_params_from_config
from .truck import TruckParams

SHIPPED = "shipped"
LC_CALIBRATED = "lc_calibrated"
HIGHD_TRAINED = "highd_trained"
SHIPPED_SETS = {SHIPPED: "", "v0.6.0": "", LC_CALIBRATED: LC_CALIBRATED, HIGHD_TRAINED: HIGHD_TRAINED,
                "v0.1.0": "v0.1.0"}
"""``policy_dir`` keywords of the shipped policy sets (directories under ``share/evoscen_bv/policies``):
``v0.6.0`` = the set of 0.3–0.6 (trained at the method's scale under the ``driver`` profile: the top
directory), ``lc_calibrated`` = its decision policies retrained on the same controller with the
lane-change costs calibrated against highD's lane-change rate (docs/learned-bvs.md, "Lane-change
cost calibrated against highD"), ``highd_trained`` = the decision policies trained among the highD
make-up with those costs (training ``env.makeup: highd``; "Trained among the highD make-up"),
``v0.1.0`` = the first shipped set (0.1.0; 40k controller / 20k decision steps, trained under the
``safety_net`` rules); ``shipped`` = the make-up's set (:func:`shipped_set`)."""


def shipped_set(policy_dir: str, makeup: str) -> str:
    """The shipped directory (relative to ``share/evoscen_bv/policies``) of a ``policy_dir`` keyword.
    [choice] ``shipped`` under ``bvs.makeup: highd`` is ``highd_trained`` (the set trained in the traffic
    it drives in; its cars' lane-change rate nearest highD's, docs/learned-bvs.md), under ``uniform``
    ``v0.6.0`` (its bags unchanged)."""
    if policy_dir == SHIPPED:
        return SHIPPED_SETS[shipped_policy_set(makeup)]
    return SHIPPED_SETS[policy_dir]


@dataclass(frozen=True)
class LearnedParams:
    """Parameters of the ``learned`` BV driver (scenario YAML ``models.learned``)."""

    policy_dir: str = text(SHIPPED)
    """Directory of trained policies (``controller.npz``, ``mutual.npz``, ``competitive.npz``,
    ``cooperative.npz``, ``training.yaml``), as written by ``scripts/train_bv.py --out``;
    ``shipped`` (default) = the shipped set of the make-up (``v0.6.0`` under ``bvs.makeup: uniform``,
    ``highd_trained`` under ``highd``), or one shipped set by name: ``v0.6.0``, ``lc_calibrated``,
    ``highd_trained``, ``v0.1.0`` (:data:`SHIPPED_SETS`). A relative path is relative to the working
    directory."""
    on_missing: str = text("error", ("error", "level0"))
    """What to do when the policy directory lacks policies: ``error`` (one-line error, the
    default) or ``level0`` (drive every BV with the level-0 driver instead)."""
    profile: str = text("driver", ("driver", "safety_net"))
    """The BVs' run-time rule profile (docs/bv-profiles.md): ``driver`` (default: a reaction
    time of 1 s and braking bounded at 7 m/s², so a reckless SUT can cause a conflict) or
    ``safety_net`` (instant, full-brake reactions to any leader: the rules the shipped
    policies were trained with, every SUT mistake absorbed)."""
    lane_hold_s: float = number(20.0, 0.0, 600.0)
    """The lane hold (docs/learned-bvs.md, "Lane hold"): for this long after a BV's lane change
    ends, its decision policy's requests are rewritten to keep (the forced merge excepted).
    [choice] 20 s, SUMO's ``lcSpeedGainRemainTime`` (the minimum time on the new lane after a
    speed-gain change); 0 = no hold, the rule before the hold existed (the BVs then reversed 70 % of
    their changes, a median 5.7 s apart)."""
    cut_in_decel_mps2: float = number(0.0, 0.0, 50.0)
    """Under the ``driver`` profile, b of a further cut-in gap term c²/(2b) (docs/bv-profiles.md,
    R5): a BV changes lanes only where the vehicle closing in on it, reacting after the
    reaction time, can match speeds braking at most b (e.g. 4 m/s², MOBIL's b_safe).
    [choice] 0 = no such term, the linear gap 10 m + 1.5 s·c only: with 4 m/s² merging BVs
    waited at standstill and jams formed. ``safety_net`` keeps its rules and ignores the key."""
    forced_merge_m: float = number(1000.0, 0.0, 100000.0)
    """On the last this-many metres of a lane that ends (the merge lane), a BV requests the change
    to the lane that goes on whatever its policy says; the rule constraints still make it wait for
    a gap (docs/learned-bvs.md, "Merging"). [choice] 1,000 m (longer than the merge lane: from its
    start, as drivers join at the first acceptable gap): with 120 m, the earlier value, BVs on the
    merge lane drove on at 30 m/s, braked hard for its end and, in the dense traffic the window
    keeps around the merge, stopped there and forced their way in at a crawl (traced in the runs)."""
    into_ending_lane: bool = flag(False)
    """Whether a BV may change from a lane that goes on into one that ends (the merge lane) when
    that lane ends 200 m or more ahead (docs/learned-bvs.md, "Into the merge lane"). [choice] false
    (default): never — an acceleration lane is for joining the carriageway, and BVs that moved onto
    it stopped at its end and forced their way back at a crawl, the BV–BV collisions of the
    traffic window (traced in the runs); true: the rule the policies were trained with."""
    merge_seek: bool = flag(True)
    """Whether a BV that must merge adapts its speed to a gap (docs/learned-bvs.md, "Merging";
    :func:`evoscen_bv.lane_change_decision.merge_seek_accel`): it drops back behind the vehicles of the
    lane it must join that block its change. [choice] true (default): without it a BV beside
    traffic at its own speed stayed beside it to the merge lane's end, stopped and merged at a
    crawl in front of traffic 30 m/s faster (six of seven BV–BV collisions of the traffic window,
    traced in the runs); false: the controller's throttle only, as before."""
    hold_on_entry: bool = flag(True)
    """Whether a BV that enters anew (the traffic window's entries at its edges and at the merge
    lane's start) starts with the lane hold (docs/learned-bvs.md, "Lane hold"). [choice] true
    (default): an entry places the vehicle where it can follow safely at a speed that fits the
    gap — the state of a vehicle that has been driving in that lane — so it is held like one that
    has settled there; without it 37 % of the entries were followed by a lane change within 5 s
    (14 % of all BV lane changes of the window; traced in the runs). false: no hold on entry, as
    before. The forced merge is exempt either way."""
    competitive_cut_in: str = text("compete", ("compete", "yield"))
    """How a competitive BV answers the SUT cutting in ahead of it (docs/learned-bvs.md,
    "Competitive BVs and a SUT cutting in"). [choice] ``compete`` (default): it does not make
    room on the SUT's intent — while it keeps its lane it follows its own leader until the SUT's
    body reaches into that lane, as the method's competitive drivers, who put their own progress
    first, do (one changing lanes itself watches its target lane as every BV does); mutual and
    cooperative BVs yield on the intent as before. ``yield``: every BV treats the SUT as in its
    lane from the SUT's request on (before). Towards other BVs every BV yields on the intent either
    way (BV–BV realism, the guard of docs/bv-profiles.md)."""
    standing_leader_at_once: bool = flag(True)
    """Under the ``driver`` profile, the emergency brake acts at once, without the reaction
    time, for a perceived leader at rest (docs/bv-profiles.md, R2) [choice: a vehicle standing
    in front that the BV has perceived is no surprise]; false: the reaction time applies to it
    too (the earlier rule, 0.1.0). ``safety_net`` ignores it."""
    hard_brake: bool = flag(True)
    """Whether the BV that is the SUT's leader (within 100 m) brakes hard now and then, as leaders
    do in naturalistic traffic (docs/learned-bvs.md, "Hard braking";
    :class:`evoscen_bv.learned.HardBrakeParams`): episodes start as a Poisson process per km it
    drives as the SUT's leader, brake at a drawn deceleration for a drawn duration, and end early at
    ``hard_brake_min_speed_mps``. true (default); false: no hard braking, the BVs as before."""
    hard_brake_per_1000km: float = number(11.8, 0.001, 1.0e6)
    """Hard-braking episodes per 1,000 km driven as the SUT's leader: 11.8 = 19 per 1,000 miles, the
    average US driver's hard-braking events in Allstate's Drivewise telematics 2016–2017 (America's
    Best Drivers Report; all roads, not highways only — an upper figure for a highway)."""
    hard_brake_decel_min_mps2: float = number(4.0, 0.1, 8.0)
    """Lower end of the uniform draw of an episode's deceleration. [choice] 4 m/s² (about 0.4 g, the
    upper end of the thresholds naturalistic studies use for "hard braking", 3–4 m/s²): no
    published distribution of the deceleration was found."""
    hard_brake_decel_max_mps2: float = number(7.0, 0.1, 8.0)
    """Upper end of the deceleration draw. [choice] 7 m/s², the ``driver`` profile's braking bound."""
    hard_brake_duration_min_s: float = number(1.0, 0.1, 60.0)
    """Lower end of the uniform draw of an episode's duration. [choice] 1 s: no published
    distribution of the duration was found."""
    hard_brake_duration_max_s: float = number(3.0, 0.1, 60.0)
    """Upper end of the duration draw. [choice] 3 s (at most 21 m/s of speed lost)."""
    hard_brake_min_speed_mps: float = number(10.0, 0.0, 100.0)
    """An episode starts only above, and ends early at, this speed: a leader never brakes into a
    standstill on the main line. [choice] 10 m/s."""


def _level0(vehicles, params, config, rng):
    return Level0Driver(vehicles, level0_params_from_config(config), rng, config.vehicle)


def _learned(vehicles, params: LearnedParams, config, rng):
    from .learned import LearnedDriver, load_policies, shipped_policy_dir

    if params.policy_dir in SHIPPED_SETS:
        directory = shipped_policy_dir() / shipped_set(params.policy_dir, config.bvs.makeup)
    else:
        directory = Path(params.policy_dir)
    try:
        controller, decisions, training = load_policies(directory)
    except InputError as exc:
        if params.on_missing == "level0":
            return _level0(vehicles, None, config, rng)
        raise InputError(f"models.learned.policy_dir = {params.policy_dir}: {exc}") from None
    return LearnedDriver(vehicles, controller, decisions, training, rng, config.vehicle,
                         forced_merge=True, profile=params.profile, lane_hold_s=params.lane_hold_s,
                         cut_in_decel_mps2=params.cut_in_decel_mps2,
                         standing_leader_at_once=params.standing_leader_at_once,
                         into_ending_lane=params.into_ending_lane, forced_merge_m=params.forced_merge_m,
                         merge_seek=params.merge_seek, hold_on_entry=params.hold_on_entry,
                         compete_with_sut=params.competitive_cut_in == "compete",
                         hard_brake=None if _challenge_layer(config) else hard_brake_params(params))


def _challenge_layer(config) -> bool:
    """Whether the simulation's challenge layer runs the leader's hard braking (``challenge.mode`` other than
    ``none``, docs/challenges.md): then the learned BVs' own rule is off."""
    challenge = getattr(config, "challenge", None)
    return challenge is not None and challenge.mode != "none"


def hard_brake_params(params: LearnedParams):
    """The :class:`evoscen_bv.learned.HardBrakeParams` of ``params``; ``None`` with ``hard_brake: false``."""
    from .learned import HardBrakeParams

    if not params.hard_brake:
        return None
    try:
        return HardBrakeParams(params.hard_brake_per_1000km,
                               (params.hard_brake_decel_min_mps2, params.hard_brake_decel_max_mps2),
                               (params.hard_brake_duration_min_s, params.hard_brake_duration_max_s),
                               params.hard_brake_min_speed_mps)
    except ValueError:
        raise InputError("models.learned.hard_brake_*: the minimum of a range exceeds its maximum") from None


LEVEL0 = ModelSpec(name="level0", roles=("bv", "sut"), factory=_level0,
                   description="level-0 traffic: IDM, keep lane, forced merges only (docs/method.md §3.3)")
register_model(LEVEL0)

LEARNED = ModelSpec(name="learned", roles=("bv",), factory=_learned, params_type=LearnedParams,
                    description="TD3-trained social drivers: competitive, mutual, cooperative by bvs.mix (docs/method.md §3)")
register_model(LEARNED)


def _makeup_driver(vehicles, makeup, config, car_driver):
    from .truck import makeup_driver

    return makeup_driver(vehicles, makeup, config, car_driver)


# bvs.makeup: highd (docs/bv-profiles.md, "Traffic make-up"): its parameter sets and its driver
register_parameter_set("highd", HighdMakeupParams)
register_parameter_set("truck", TruckParams)
register_makeup_driver("highd", _makeup_driver)
