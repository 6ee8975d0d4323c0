"""evoscen_eval: metrics and evaluation of recorded runs (the bag itself: :mod:`evoscen_record`).

Import the submodules directly; this ``__init__`` imports only :mod:`evoscen_sim.moved_paths` (the
0.4 import paths, until 0.7.0).
"""

from evoscen_sim.moved_paths import install as _install_moved_paths

_install_moved_paths()  # the import paths 0.5.0 moved keep working until 0.7.0, with a DeprecationWarning
