"""The SUT package's built-in models, registered with :mod:`evoscen_sim.model_registry`.

Every model decides lane changes its own way and drives longitudinally with SUMO's Krauss
model (:mod:`evoscen_sut.krauss`), through the same PID low-level control as every vehicle:

* ``nilsson`` (SUT and BV driver): lane utilities of Nilsson et al. (:mod:`evoscen_sut.nilsson`);
* ``mobil`` (SUT and BV driver): MOBIL with IDM accelerations (:mod:`evoscen_sut.mobil`);
* ``stackelberg`` (SUT): a leader/followers game (:mod:`evoscen_sut.stackelberg`);
* ``mutant`` (SUT): any registered SUT model with one deliberate defect
  (:mod:`evoscen_sut.mutant`, docs/mutants.md).

Their parameters are the scenario YAML's ``models.<name>`` sections; their Krauss car
following's, one set for all of them, ``models.krauss`` (:class:`evoscen_sut.krauss.KraussParams`,
registered here as a parameter set: no model of its own).
"""

from __future__ import annotations

from evoscen_sim.model_registry import register_model, register_parameter_set

from . import krauss, mobil, mutant, nilsson, stackelberg

register_parameter_set(krauss.NAME, krauss.KraussParams)
for _spec in (nilsson.SPEC, mobil.SPEC, stackelberg.SPEC, mutant.SPEC):
    register_model(_spec)
