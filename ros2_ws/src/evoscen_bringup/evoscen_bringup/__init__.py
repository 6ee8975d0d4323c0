"""evoscen's runners (the in-process runner, the node-graph launcher, scenario building, start states,
domains, the output directory) and its experiments (campaigns, experiments, statistics); docs/architecture.md §1."""

from evoscen_sim.moved_paths import install as _install_moved_paths

_install_moved_paths()  # the import paths 0.5.0 moved keep working until 0.7.0, with a DeprecationWarning
