"""evoscen_eval: what a run is worth and what it looks like (the bag itself: :mod:`evoscen_record`).

Three rooms (docs/architecture.md §1): :mod:`evoscen_eval.scoring` (scores and reports),
:mod:`evoscen_eval.naturalistic` (fidelity against highD) and :mod:`evoscen_eval.scenes` (export,
clips, replay), and the evaluator node ``eval_node``. Import the submodules directly; this
``__init__`` imports only :mod:`evoscen_sim.moved_paths` (the paths the rooms replaced, until 0.8.0).
"""

from evoscen_sim.moved_paths import install as _install_moved_paths

_install_moved_paths()  # the 0.6 paths of the moved modules keep working until 0.8.0, with a DeprecationWarning
