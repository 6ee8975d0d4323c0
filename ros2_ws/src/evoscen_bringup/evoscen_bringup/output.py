"""The output directory of a run: created, checked writable, its bag and report folders free.

Shared by ``scripts/run_scenario.py``, ``scripts/graph_node.py`` and :func:`evoscen.run_scenario`:
everything a run needs is validated before the output directory is touched, so a bad input never
costs an existing bag, and a bag or report is replaced only with ``overwrite``.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from evoscen_sim.errors import InputError


def prepare_output(out: Path, bag_dir: Path | None, report_dir: Path | None = None, *, overwrite: bool) -> None:
    """Create ``out``; make sure ``bag_dir`` and ``report_dir`` are free (removing old ones only with ``overwrite``)."""
    try:
        out.mkdir(parents=True, exist_ok=True)
        for path, what in ((bag_dir, "a bag"), (report_dir, "a report")):
            if path is None or not (path.exists() or path.is_symlink()):
                continue
            if not path.is_dir() or path.is_symlink():
                raise InputError(f"--out {out}: {path} exists and is not a directory; remove it or choose another --out")
            if any(path.iterdir()):
                if not overwrite:
                    raise InputError(f"--out {out}: {path} already holds {what}; choose another --out or pass --overwrite")
                shutil.rmtree(path)
        probe = out / ".evoscen-write-test"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise InputError(f"--out {out}: cannot write the output directory: {exc.strerror or exc}") from None
