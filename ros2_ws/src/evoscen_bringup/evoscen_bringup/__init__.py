"""evoscen's runners (the in-process runner, the node-graph launcher, scenario building, start states,
domains, the output directory, a run into it from a command line or the face (``runs``), one node of the
graph in a container (``one_node``), the model listings (``model_lists``)) and its experiments
(campaigns, experiments, statistics); docs/architecture.md §1."""

from evoscen_sim.moved_paths import install as _install_moved_paths

_install_moved_paths()  # the 0.6 paths of moved modules keep working until 0.8.0, with a DeprecationWarning
