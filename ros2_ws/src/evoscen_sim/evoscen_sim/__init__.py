"""evoscen simulation core: OpenDRIVE road, vehicle dynamics, low-level PID control, collision, re-entry and the world step."""

from .moved_paths import install as _install_moved_paths

_install_moved_paths()  # the import paths 0.5.0 moved keep working until 0.7.0, with a DeprecationWarning
