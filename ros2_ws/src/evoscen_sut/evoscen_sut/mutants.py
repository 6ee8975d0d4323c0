"""The named library of SUT mutants for mutation analysis (docs/method.md §7; docs/mutants.md).

Each :class:`Mutant` is one operator of the ``mutant`` model (:mod:`evoscen_sut.mutant`) with
parameters chosen as a realistic degradation; :func:`mutant_overrides` turns (base model,
mutant name) into the config overrides that make a scenario run that mutant::

    from evoscen_sim.config.scenario_config import load_scenario_config
    cfg = load_scenario_config(path, mutant_overrides("mobil", "blind_behind"))
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from evoscen_sim.errors import InputError

from .mutant import CONTROL, DECISION, NAME, PERCEPTION


@dataclass(frozen=True)
class Mutant:
    """One mutant of the library: an operator and its parameters."""

    name: str
    klass: str
    """``perception``, ``decision`` or ``control``."""
    operator: str
    description: str
    """The defect, and why its parameters are a realistic degradation."""
    params: dict[str, Any] = field(default_factory=dict)
    """Operator parameters (``models.mutant.<key>``), besides ``base`` and ``operator``."""
    bases: tuple[str, ...] = ()
    """The SUT bases of :data:`KNOWN_BASES` the mutant applies to (:func:`applicable_bases`)."""
    applies: str = ""
    """For which base the defect makes sense, in words (also for a base evoscen does not know)."""


KNOWN_BASES = ("level0", "mobil", "nilsson", "stackelberg", "fiss", "sumo_sut")
"""The SUT models whose mutants the library states: the built-ins (``krauss`` is a car-following
parameter set, not a SUT model) and the plug-in examples ``fiss`` (examples/fiss_sut) and
``sumo_sut`` (examples/sumo_sut)."""
LANE_CHANGING = ("mobil", "nilsson", "stackelberg", "fiss", "sumo_sut")
"""Bases that decide lane changes (``level0`` keeps its lane but for the forced merge)."""
SINGLE_INSTANCE = ("sumo_sut",)
"""Bases that allow one driver instance per process (``sumo_sut``: libsumo runs one SUMO simulation per
process, docs/plugins.md): the operators that run two instances of the base (``ignores_new_follower``,
``tailgating``, :mod:`evoscen_sut.mutant`) do not apply to them."""
TWO_INSTANCES = tuple(b for b in KNOWN_BASES if b not in SINGLE_INSTANCE)
ANY_BASE = "any base: the defect acts on what every driver sees or commands"
CHANGES_LANES = "bases that decide lane changes (not level0, which keeps its lane but for the forced merge)"


_CLASS_OF = {op: klass for klass, ops in (("perception", PERCEPTION), ("decision", DECISION), ("control", CONTROL))
             for op in ops}
"""Each operator of the ``mutant`` model (:mod:`evoscen_sut.mutant`) -> its class."""


def _mutant(operator: str, description: str, *, bases: tuple[str, ...], applies: str, **params: Any) -> Mutant:
    """The mutant named after ``operator``, of the operator's class (KeyError: not an operator)."""
    return Mutant(operator, _CLASS_OF[operator], operator, description, params, bases, applies)


_ENTRIES = (
    _mutant("blind_behind",
            "No rear perception (rear radar/camera failed): vehicles behind the SUT in every lane are "
            "invisible, so lane changes ignore the new follower and the own lane's follower.", bases=LANE_CHANGING,
            applies="bases that decide lane changes: what is behind matters to a lane change (level0 "
                    "follows its leader only)"),
    _mutant("short_view",
            "Perception range ahead cut to 50 m (dense fog / dirty front sensor): slower traffic "
            "ahead is seen late, lane utilities ignore everything beyond 50 m.", view_m=50.0, bases=KNOWN_BASES, applies=ANY_BASE),
    _mutant("stale",
            "Object list 0.5 s old (a slow sensor-fusion pipeline): other vehicles are seen where "
            "they were 5 steps ago; a closing follower seems farther than it is.", delay_steps=5, bases=KNOWN_BASES, applies=ANY_BASE),
    _mutant("ignores_new_follower",
            "Gap acceptance without regard to the new follower: the lane-change decision does not "
            "see vehicles behind the SUT in the adjacent lanes (car following is intact).",
            bases=tuple(b for b in LANE_CHANGING if b in TWO_INSTANCES),
            applies=CHANGES_LANES + "; two instances of the base (not sumo_sut: one SUMO per process)"),
    _mutant("late_lane_change",
            "Lane changes executed 1 s (10 steps) after the decision: the gap judged acceptable may "
            "have closed.", delay_steps=10, bases=LANE_CHANGING, applies=CHANGES_LANES),
    _mutant("over_eager",
            "Over-eager lane changes: no incentive threshold, no keep-right bias and a new-follower "
            "safety margin only an emergency manoeuvre honours (the base model's parameters "
            "re-tuned, evoscen_sut.mutant.EAGER_PRESETS).", retune="preset",
            bases=("mobil", "nilsson", "stackelberg"),
            applies="bases with an over-eager preset (EAGER_PRESETS); any other base with parameters through retune"),
    _mutant("timid",
            "Timid: the desired speed at 60 % of the base's (every desired-speed parameter of the base, and "
            "the Krauss car follower's for the built-in models): 72 km/h where the built-in models want "
            "120 km/h, below the mainline's 90 km/h minimum, so the SUT gives away progress the traffic "
            "allows.", bases=KNOWN_BASES,
            applies="bases with a desired speed evoscen knows (models.<base>.desired_speed_mps or speed_factor, "
                    "the Krauss car follower, level0's range)", speed_factor=0.6),
    _mutant("frozen",
            "Frozen in its lane: no discretionary lane change (the base's requests pass only while the SUT "
            "is on the merge lane, where leaving is mandatory), so it stays behind every slower leader.",
            bases=LANE_CHANGING, applies=CHANGES_LANES),
    _mutant("reaction_time",
            "Reaction time 1 s (10 steps) longer: throttle and lane-change commands are executed "
            "1 s late, a human-like reaction time instead of an automated system's.", delay_steps=10, bases=KNOWN_BASES, applies=ANY_BASE),
    _mutant("weak_braking",
            "Braking commands reach the wheels at 40 % (worn brakes / saturated actuator): the "
            "follower cannot stop in the distance it planned for.", brake_factor=0.4, bases=KNOWN_BASES, applies=ANY_BASE),
    _mutant("late_braking",
            "No gentle braking: brake demands below 25 % (2 m/s² with the default 8 m/s² full "
            "brake) are ignored, so braking starts later and harder.", brake_onset=0.25, bases=KNOWN_BASES, applies=ANY_BASE),
    _mutant("tailgating",
            "Tailgating: the car follower sees the vehicles ahead in its lane 15 m farther, so it "
            "follows at ~0.5 s instead of ~1 s at highway speed.", extra_gap_m=15.0, bases=TWO_INSTANCES,
            applies="any base that allows two instances of its driver in one process (the throttle and the lane "
                    "change come from two views; not sumo_sut: one SUMO per process)"),
)

LIBRARY: dict[str, Mutant] = {m.name: m for m in _ENTRIES}
"""The mutants by name, perception first, then decision and control."""


def applicable_bases(name: str) -> tuple[str, ...]:
    """The bases of :data:`KNOWN_BASES` mutant ``name`` applies to (InputError: not in :data:`LIBRARY`)."""
    mutant = LIBRARY.get(name)
    if mutant is None:
        raise InputError(f"mutant '{name}': expected one of {', '.join(LIBRARY)}")
    return mutant.bases


def applicability() -> dict[str, dict[str, Any]]:
    """Every mutant of :data:`LIBRARY` with its class, the bases of :data:`KNOWN_BASES` it applies
    to and the rule in words (for a listing such as ``--list-mutants``)."""
    return {m.name: {"class": m.klass, "bases": m.bases, "applies": m.applies, "description": m.description}
            for m in LIBRARY.values()}


def mutants_for(base: str) -> list[str]:
    """The mutants of :data:`LIBRARY` that apply to ``base``; for a base not in :data:`KNOWN_BASES`
    (a plug-in of your own) those whose rule needs no knowledge of the base (:data:`ANY_BASE`)."""
    if base in KNOWN_BASES:
        return [m.name for m in LIBRARY.values() if base in m.bases]
    return [m.name for m in LIBRARY.values() if m.applies == ANY_BASE]


def mutant_overrides(base: str, name: str) -> dict[str, str]:
    """Config overrides (dotted keys -> strings, for
    :func:`evoscen_sim.config.scenario_config.load_scenario_config`) that make the SUT mutant ``name`` of
    :data:`LIBRARY` of SUT model ``base``. The base's own ``models.<base>`` section is kept."""
    mutant = LIBRARY.get(name)
    if mutant is None:
        raise InputError(f"mutant '{name}': expected one of {', '.join(LIBRARY)}")
    out = {"sut.model": NAME, f"models.{NAME}.base": str(base), f"models.{NAME}.operator": mutant.operator}
    for key, value in mutant.params.items():
        out[f"models.{NAME}.{key}"] = str(value)
    return out
