"""The one package-path lookup of evoscen: share files of an installed workspace or the source tree."""

from __future__ import annotations

import functools
import os
from pathlib import Path

from evoscen_sim.errors import InputError

PACKAGE = "evoscen_sim"


@functools.lru_cache(maxsize=None)
def _source_dir(package: str) -> Path:
    here = Path(__file__).resolve().parents[1]  # ros2_ws/src/evoscen_sim
    return here if package == PACKAGE else here.parent / package


def share_candidates(relative: str, package: str = PACKAGE, source: Path | None = None) -> list[Path]:
    """Where a share file of ``package`` may live: the ament share directory (if any), then the source tree.

    The one package-path lookup of evoscen (:func:`share_path`, the map look-up, the BV
    package's policies and training config use it): ``share/<package>/<relative>`` of an
    installed workspace (the ament index; skipped when ament_index_python, the package or
    ``AMENT_PREFIX_PATH`` is missing), then ``source``, by default
    ``ros2_ws/src/<package>/<relative>`` (for files whose installed path mirrors their source
    path). The paths are returned whether or not they exist.
    """
    candidates: list[Path] = []
    share = _share_dir(package)
    if share is not None:
        candidates.append(share / relative)
    candidates.append(_source_dir(package) / relative if source is None else source)
    return candidates


_SHARE_DIRS: dict[tuple[str, str | None], Path | None] = {}
"""The ament share directory of each package, per ``AMENT_PREFIX_PATH`` (the index is read from the file
system; an experiment resolves thousands of configurations' maps: docs/performance.md, "Start-up")."""


def _share_dir(package: str) -> Path | None:
    """``share/<package>`` of the installed workspace that ``AMENT_PREFIX_PATH`` names; None if none."""
    key = (package, os.environ.get("AMENT_PREFIX_PATH"))
    if key in _SHARE_DIRS:
        return _SHARE_DIRS[key]
    found = None
    try:
        from ament_index_python.packages import (  # type: ignore[import-not-found]
            PackageNotFoundError,
            get_package_share_directory,
        )
    except ImportError:
        pass
    else:
        try:
            found = Path(get_package_share_directory(package))
        except (PackageNotFoundError, OSError, ValueError):
            # not installed, or no AMENT_PREFIX_PATH (OSError): use the source tree
            pass
    _SHARE_DIRS[key] = found
    return found


def share_path(relative: str, package: str = PACKAGE) -> Path:
    """Absolute path of ``relative`` in ``package``'s share directory.

    Tries the ament index (an installed workspace) first, then the source tree
    (``ros2_ws/src/<package>/<relative>``). Raises InputError if the file is in neither.
    """
    tried = share_candidates(relative, package)
    for candidate in tried:
        if candidate.exists():
            return candidate.resolve()
    raise InputError(f"{package} share file '{relative}': not found "
                     f"(tried {', '.join(map(str, tried))})")
