"""evoscen systems under test: rule-based SUT models (registered with evoscen_sim.model_registry)."""

from evoscen_sim.moved_paths import install as _install_moved_paths

_install_moved_paths()  # the import paths 0.5.0 moved keep working until 0.7.0, with a DeprecationWarning
