"""The node graph's log files: each node's output copied to ``OUT/logs/<node>.log``, the terminal kept
for the launcher's own lines (docs/recording.md, "Node logs").

A node's stdout and stderr (its one-line messages, rclpy's console log lines, a traceback) go to one
pipe; a thread of the launcher (:class:`NodeLog`) copies it to the node's log file line by line and
keeps its ``error:`` lines, of which the launcher repeats the one that decides the run's status
(:func:`the_error_line`). A node never writes to the output directory's file itself: a write that fails
(a full disk, an output made read-only) stops the copying, not the node, and the lines are still read
(``complete`` is then False, and the error line does not point to logs that are not whole).
:class:`LauncherLog` keeps the launcher's own events (which node ended how, when) in ``launcher.log``.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import IO

from evoscen_contract.contract import EXIT_INTERRUPTED, EXIT_OK

LOG_DIR = "logs"
"""The log folder of a run's output directory."""
LAUNCHER_LOG = "launcher.log"
"""The launcher's own events, in the log folder beside the nodes' ``<node>.log``."""
ERROR_PREFIX = b"error: "


class Errors:
    """The ``error:`` lines of every node, in the order the launcher read them (thread-safe)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._lines: list[tuple[str, str]] = []

    def add(self, node: str, line: str) -> None:
        with self._lock:
            self._lines.append((node, line))

    def lines(self) -> list[tuple[str, str]]:
        """(node, line without ``error: ``), in order."""
        with self._lock:
            return list(self._lines)


class NodeLog:
    """Copies a node's output (``stream``, its stdout and stderr) to ``path`` from a thread of its own;
    its ``error:`` lines go to ``errors``."""

    def __init__(self, node: str, stream: IO[bytes], path: Path, errors: Errors) -> None:
        self.node = node
        self.path = path
        self.complete = True
        """False once a write to the log file failed (the rest of the output was read, not written)."""
        self._stream = stream
        self._errors = errors
        self._thread = threading.Thread(target=self._copy, name=f"log {node}", daemon=True)
        self._thread.start()

    def _copy(self) -> None:
        try:
            out = open(self.path, "wb", buffering=0)  # noqa: SIM115 (closed below; unbuffered: a line per write)
        except OSError:
            out, self.complete = None, False
        with self._stream:
            for line in iter(self._stream.readline, b""):
                if line.startswith(ERROR_PREFIX):
                    self._errors.add(self.node, line[len(ERROR_PREFIX):].decode("utf-8", "replace").rstrip("\r\n"))
                if out is not None:
                    try:
                        out.write(line)
                    except OSError:
                        out, self.complete = self._close(out), False
        self._close(out)

    @staticmethod
    def _close(out) -> None:
        if out is not None:
            try:
                out.close()
            except OSError:
                pass

    def join(self, timeout_s: float) -> None:
        """Until the node's output has ended (every process holding its pipe has), at most ``timeout_s``."""
        self._thread.join(timeout_s)


class LauncherLog:
    """The launcher's own events, one line each with the seconds since launch, in ``launcher.log``
    (a write that fails is dropped: these lines are for reading after the run)."""

    def __init__(self, path: Path, t0: float) -> None:
        self.path = path
        self.t0 = t0
        self.complete = True

    def __call__(self, text: str) -> None:
        try:
            with open(self.path, "a", encoding="utf-8") as f:
                f.write(f"{time.monotonic() - self.t0:7.1f} s  {text}\n")
        except OSError:
            self.complete = False


def the_error_line(status: int, node_status: dict[str, int | None], errors: list[tuple[str, str]]) -> str | None:
    """The one line (without ``error: ``) that says why a run ended with ``status`` that a node said: the
    first ``error:`` line of a node that ended with ``status`` itself (a controller's driver that raised,
    3; the recorder that could not write, 5; a bad parameter, 2; the simulation's deadline abort, 3), else
    of any node but for a run that completed or was interrupted; None if no node said one."""
    if status in (EXIT_OK, EXIT_INTERRUPTED):
        return None
    deciding = [line for node, line in errors if node_status.get(node) == status]
    return deciding[0] if deciding else errors[0][1] if errors else None
