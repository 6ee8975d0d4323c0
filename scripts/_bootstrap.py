"""Make the evoscen packages importable from a plain ``python scripts/<tool>.py``.

If the workspace overlay is not sourced (``. ros2_ws/install/setup.sh``), add the colcon
install tree's site-packages to ``sys.path`` and its prefixes to ``AMENT_PREFIX_PATH``
(so share files resolve); if there is no install tree either, fall back to the package
sources. Nothing changes when the packages are already importable.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("evoscen_contract", "evoscen_sim", "evoscen_bv", "evoscen_sut", "evoscen_record", "evoscen_eval",
            "evoscen_bringup", "evoscen_experiments", "evoscen")


def ensure_packages() -> None:
    """Put the evoscen packages on ``sys.path`` if they are not importable yet."""
    try:
        import evoscen_bringup  # noqa: F401

        return
    except ImportError:
        pass
    install = REPO / "ros2_ws" / "install"
    prefixes = []
    for pkg in PACKAGES:
        prefix = install / pkg
        site = prefix / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}" / "site-packages"
        if site.is_dir():
            sys.path.insert(0, str(site))
            # a symlink install (make build) leaves an .egg-link naming the package's directory
            # instead of the package itself; Python reads those only through the overlay's setup
            for link in site.glob("*.egg-link"):
                target = link.read_text(encoding="utf-8").splitlines()[0].strip()
                if target:
                    sys.path.insert(0, target)
            prefixes.append(str(prefix))
        else:
            sys.path.insert(0, str(REPO / "ros2_ws" / "src" / pkg))
    if prefixes:
        old = os.environ.get("AMENT_PREFIX_PATH", "")
        os.environ["AMENT_PREFIX_PATH"] = os.pathsep.join(prefixes + ([old] if old else []))


ensure_packages()
