"""evoscen's runners: the in-process runner (``inprocess``) and the run's plan (``plan``), the node-graph
launcher (``graph_runner``) and its nodes' log files (``node_logs``), scenario building and start states
(``scenario``, ``starts``), ROS domains (``domains``), the output directory (``output``), a run into it from
a command line or the face (``runs``), one node of the graph in a container (``one_node``), the model
listings (``model_lists``) and the models' test helpers (``model_testing``); docs/architecture.md §1.
Experiments are :mod:`evoscen_experiments`."""

from evoscen_sim.moved_paths import install as _install_moved_paths

_install_moved_paths()  # the 0.6 paths of moved modules keep working until 0.8.0, with a DeprecationWarning
