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


_CLASS_OF = {op: klass for klass, ops in (("perception", PERCEPTION), ("decision", DECISION), ("control", CONTROL))
             for op in ops}
"""Each operator of the ``mutant`` model (:mod:`evoscen_sut.mutant`) -> its class."""


def _mutant(operator: str, description: str, **params: Any) -> Mutant:
    """The mutant named after ``operator``, of the operator's class (KeyError: not an operator)."""
    return Mutant(operator, _CLASS_OF[operator], operator, description, params)


_ENTRIES = (
    _mutant("blind_behind",
            "No rear perception (rear radar/camera failed): vehicles behind the SUT in every lane are "
            "invisible, so lane changes ignore the new follower and the own lane's follower."),
    _mutant("short_view",
            "Perception range ahead cut to 50 m (dense fog / dirty front sensor): slower traffic "
            "ahead is seen late, lane utilities ignore everything beyond 50 m.", view_m=50.0),
    _mutant("stale",
            "Object list 0.5 s old (a slow sensor-fusion pipeline): other vehicles are seen where "
            "they were 5 steps ago; a closing follower seems farther than it is.", delay_steps=5),
    _mutant("ignores_new_follower",
            "Gap acceptance without regard to the new follower: the lane-change decision does not "
            "see vehicles behind the SUT in the adjacent lanes (car following is intact)."),
    _mutant("late_lane_change",
            "Lane changes executed 1 s (10 steps) after the decision: the gap judged acceptable may "
            "have closed.", delay_steps=10),
    _mutant("over_eager",
            "Over-eager lane changes: no incentive threshold, no keep-right bias and a new-follower "
            "safety margin only an emergency manoeuvre honours (the base model's parameters "
            "re-tuned, evoscen_sut.mutant.EAGER_PRESETS).", retune="preset"),
    _mutant("reaction_time",
            "Reaction time 1 s (10 steps) longer: throttle and lane-change commands are executed "
            "1 s late, a human-like reaction time instead of an automated system's.", delay_steps=10),
    _mutant("weak_braking",
            "Braking commands reach the wheels at 40 % (worn brakes / saturated actuator): the "
            "follower cannot stop in the distance it planned for.", brake_factor=0.4),
    _mutant("late_braking",
            "No gentle braking: brake demands below 25 % (2 m/s² with the default 8 m/s² full "
            "brake) are ignored, so braking starts later and harder.", brake_onset=0.25),
    _mutant("tailgating",
            "Tailgating: the car follower sees the vehicles ahead in its lane 15 m farther, so it "
            "follows at ~0.5 s instead of ~1 s at highway speed.", extra_gap_m=15.0),
)

LIBRARY: dict[str, Mutant] = {m.name: m for m in _ENTRIES}
"""The mutants by name, perception first, then decision and control."""


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
