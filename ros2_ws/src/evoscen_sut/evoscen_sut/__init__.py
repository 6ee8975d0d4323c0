"""evoscen systems under test: rule-based SUT models and their mutants (registered with
evoscen_sim.model_registry), the SUT node. May import the simulation and the contract."""

from evoscen_sim.moved_paths import install as _install_moved_paths

_install_moved_paths()  # the 0.6 paths of moved modules keep working until 0.8.0, with a DeprecationWarning
