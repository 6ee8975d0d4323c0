"""evoscen simulation core: OpenDRIVE road, vehicle dynamics, low-level PID control, collision, the
traffic window and the world step, in rooms (docs/architecture.md §1: config, road, physics, traffic,
danger, loop, nodes). Imports only the contract among the other packages."""

from .moved_paths import install as _install_moved_paths

_install_moved_paths()  # the 0.6 paths of moved modules keep working until 0.8.0, with a DeprecationWarning
