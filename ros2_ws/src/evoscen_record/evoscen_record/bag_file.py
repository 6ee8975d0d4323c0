"""The bag's directory and its MCAP file as the recorder writes them: held bytes handed to the
operating system at safe points (:class:`BagFile`), the file cut back to its last complete chunk
after a fault of the host."""

from __future__ import annotations

import contextlib
import errno
import os
from pathlib import Path
from typing import Any

from evoscen_sim.errors import InputError


def prepare_bag_dir(bag_dir: Path) -> None:
    """Create ``bag_dir`` (and parents); InputError if non-empty or not creatable."""
    try:
        if bag_dir.exists() or bag_dir.is_symlink():
            if not bag_dir.is_dir():
                raise InputError(
                    f"bag directory {str(bag_dir)!r}: exists and is not a directory; "
                    "give a new or empty directory"
                )
            if any(bag_dir.iterdir()):
                raise InputError(
                    f"bag directory {str(bag_dir)!r}: exists and is not empty; "
                    "give a new or empty directory"
                )
        else:
            bag_dir.mkdir(parents=True)
    except OSError as exc:
        raise InputError(
            f"bag directory {str(bag_dir)!r}: cannot be created or read: "
            f"{exc.strerror or exc}"
        ) from None


def _open_file(path: Path):  # a raw binary file
    """The bag file, opened for writing unbuffered (tests replace this to simulate a full disk)."""
    return open(path, "wb", buffering=0)


class BagFile:
    """The MCAP file as the writer sees it: what is written is held until :meth:`flush` (the 1-s
    chunks, :meth:`~evoscen_record.recorder.BagRecorder.flush`, the end), which hands it to the
    operating system whole or raises :class:`~evoscen_sim.errors.HostFault` (a full disk, a
    read-only or vanished output); ``owner`` is the :class:`~evoscen_record.recorder.BagRecorder`
    writing it (its fault and safe points).
    A flush that succeeded is a point where every message counted so far is on disk, the point the
    file is cut back to after a fault, so that it ends with a complete chunk. Nothing reaches the
    file between those points (the file stays empty until the first chunk, as with a buffered
    file), so a fault can only leave the bytes of one flush half written."""

    def __init__(self, path: Path, owner: Any) -> None:
        self.path = path
        self._owner = owner
        self._f = _open_file(path)
        self._held: list = []
        self._held_bytes = 0
        self._pos = 0
        self.good = 0  # the end of the last complete chunk on disk
        self.on_disk = 0  # bytes the file holds (more than ``good`` where a fault left it uncut)

    HOLD_BYTES = 16 * 1024 * 1024
    """Bytes held at most between two flushes (bags written without the 1-s bound)."""

    def write(self, data) -> int:
        owner = self._owner
        if owner._fault is not None:  # nothing more after a fault
            raise owner._fault
        n = len(data) if not isinstance(data, memoryview) else data.nbytes
        self._held.append(bytes(data))
        self._pos += n
        self._held_bytes += n
        if self._held_bytes > self.HOLD_BYTES:  # no flush for long (no time bound): out, not a safe point
            self._write_out()
        return n

    def _write_out(self) -> None:
        held, self._held, self._held_bytes = self._held, [], 0
        try:
            for data in held:
                view = memoryview(data)
                while view:
                    n = self._f.write(view)
                    if not n:
                        raise OSError(errno.EIO, "the file took no bytes")
                    view = view[n:]
                    self.on_disk += n
        except OSError as exc:
            raise self._owner._fault_of(exc, self.path) from None

    def tell(self) -> int:
        return self._pos

    def flush(self) -> None:
        """Hand everything written so far to the operating system: a point to cut back to."""
        owner = self._owner
        if owner._fault is not None:
            raise owner._fault
        self._write_out()
        self.good = self._pos
        owner._on_safe_point()

    def cut_back(self) -> None:
        """Truncate the file to its last complete chunk (frees what a fault left half written)."""
        # Where the file cannot be truncated (a file system made read-only, a closed file) it is
        # left as it is: readers and the reindexer stop at the last complete record anyway.
        with contextlib.suppress(OSError, ValueError):
            os.ftruncate(self._f.fileno(), self.good)
            self.on_disk = self.good

    def close(self) -> None:
        try:
            self._f.close()
        except OSError:
            pass

