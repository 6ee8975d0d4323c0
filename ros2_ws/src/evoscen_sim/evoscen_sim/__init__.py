"""evoscen simulation core: OpenDRIVE road, vehicle dynamics, low-level PID control, collision, re-entry and the world step."""

from .moved_paths import install as _install_moved_paths

_install_moved_paths()  # the 0.6 paths of moved modules keep working until 0.8.0, with a DeprecationWarning
