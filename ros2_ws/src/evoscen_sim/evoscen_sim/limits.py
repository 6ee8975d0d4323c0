"""Upper bounds on what evoscen reads, and the one bounded file reader every loader uses.

Every limit is listed, with its value and its reason, in ``docs/input-limits.md``. A value
over a limit raises :class:`evoscen_sim.errors.InputError` with a one-line message naming the
file (or key), the value and the limit, before anything large is read or allocated.

:func:`read_bytes_limited` reads at most ``limit + 1`` bytes of a *regular* file, so a huge
file, ``/dev/zero``, a FIFO or a terminal fail at once instead of filling the memory (today
``--config /dev/zero`` reached 7 GB in 6 s).
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from evoscen_sim.errors import InputError

__all__ = [
    "MAX_CONFIG_BYTES",
    "MAX_DT_NS_RESIDUE",
    "MAX_HIGHD_META_BYTES",
    "MAX_HIGHD_TRACKS_BYTES",
    "MAX_MAP_BYTES",
    "MAX_METADATA_YAML_BYTES",
    "MAX_SECONDS_ARG",
    "MAX_STEPS",
    "MAX_TRAINING_STEPS",
    "MAX_YAML_DEPTH",
    "MIN_DT_S",
    "check_regular_file",
    "check_yaml_depth",
    "decode_text",
    "parse_cli_int",
    "parse_cli_path",
    "read_bytes_limited",
    "read_text_limited",
]

#: Most simulation steps of one run (``steps``, ``--steps``, ``train_bv.py --steps``).
MAX_STEPS: int = 1_000_000
#: Smallest ``dt_s`` (s): 1000 ns, so the 1 ns stamp resolution is <= 0.1 % of a step.
MIN_DT_S: float = 1e-6
#: ``dt_s * 1e9`` must be within this many ns of a whole number (stamps are exact multiples).
MAX_DT_NS_RESIDUE: float = 1e-6
#: Scenario and training YAML files (the shipped ones are ~10 KiB).
MAX_CONFIG_BYTES: int = 1 << 20
#: OpenDRIVE maps (the shipped one is 11 KiB).
MAX_MAP_BYTES: int = 16 << 20
#: A bag's ``metadata.yaml`` (rosbag2 writes ~2 KiB for evoscen's 8 topics).
MAX_METADATA_YAML_BYTES: int = 1 << 20
#: HighD ``NN_recordingMeta.csv`` and ``NN_tracksMeta.csv`` (real ones: < 1 MiB).
MAX_HIGHD_META_BYTES: int = 64 << 20
#: HighD ``NN_tracks.csv`` (the largest real recording is ~200 MB).
MAX_HIGHD_TRACKS_BYTES: int = 4 << 30
#: Deepest nesting of mappings/sequences in a YAML file (evoscen's configs use 3).
MAX_YAML_DEPTH: int = 32
#: Largest duration argument in seconds (``replay.py --start-delay``/``--wait-timeout``): one day.
MAX_SECONDS_ARG: float = 86_400.0


def _size_text(n: int) -> str:
    for unit, size in (("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= size and n % size == 0:
            return f"{n // size} {unit}"
    return f"{n} bytes"


def check_regular_file(path: Path | str, label: str, what: str, limit: int) -> int:
    """Size of the regular file ``path``; InputError if missing, not regular or over ``limit``."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise InputError(f"{label}: {what} not found") from None
    except OSError as exc:
        raise InputError(f"{label}: cannot read {what} ({exc.strerror or exc})") from None
    if not stat.S_ISREG(st.st_mode):
        kind = ("a directory" if stat.S_ISDIR(st.st_mode) else "a device" if stat.S_ISCHR(st.st_mode)
                or stat.S_ISBLK(st.st_mode) else "a FIFO" if stat.S_ISFIFO(st.st_mode) else "a socket"
                if stat.S_ISSOCK(st.st_mode) else "not a regular file")
        raise InputError(f"{label}: {what} is {kind}; expected a regular file")
    if st.st_size > limit:
        raise InputError(f"{label}: {what} is {st.st_size} bytes; expected at most {_size_text(limit)}")
    return st.st_size


def read_bytes_limited(path: Path | str, label: str, what: str, limit: int) -> bytes:
    """The bytes of the regular file ``path``, at most ``limit`` of them (InputError otherwise).

    ``label`` names the file in messages (as the user gave it), ``what`` says what it is
    (``"scenario config"``). The file is checked with ``stat`` before it is opened and read
    with a ``limit + 1`` byte cap, so a file growing meanwhile cannot exceed the limit either.
    """
    check_regular_file(path, label, what, limit)
    try:
        with open(path, "rb") as f:
            if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):  # replaced since the stat
                raise InputError(f"{label}: {what} is not a regular file")
            data = f.read(limit + 1)
    except OSError as exc:
        raise InputError(f"{label}: cannot read {what} ({exc.strerror or exc})") from None
    if len(data) > limit:
        raise InputError(f"{label}: {what} is over {_size_text(limit)}; expected at most {_size_text(limit)}")
    return data


def decode_text(data: bytes, label: str, what: str, *, allow_nul: bool = False) -> str:
    """``data`` as UTF-8 text without NUL bytes; one-line InputError naming line and byte otherwise."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise InputError(f"{label}: {what} is not UTF-8 text ({exc.reason} at byte {exc.start}, line {line}); "
                         "expected a UTF-8 text file") from None
    if not allow_nul:
        nul = data.find(b"\0")
        if nul >= 0:
            line = data.count(b"\n", 0, nul) + 1
            raise InputError(f"{label}: {what} holds a NUL byte at byte {nul} (line {line}); "
                             "expected a text file without NUL bytes")
    return text


def read_text_limited(path: Path | str, label: str, what: str, limit: int) -> str:
    """:func:`read_bytes_limited` then :func:`decode_text`."""
    return decode_text(read_bytes_limited(path, label, what, limit), label, what)


def check_yaml_depth(text: str, label: str, what: str, loader: type | None = None,
                     limit: int = MAX_YAML_DEPTH) -> None:
    """InputError if ``text``'s mappings/sequences nest deeper than ``limit``.

    PyYAML's composer and constructor recurse once per level (a RecursionError at ~1000
    levels, a traceback); its parser does not, so the depth is measured from the parser's
    events before anything is composed. YAML errors are left to the real load.
    """
    import yaml

    depth = 0
    try:
        for event in yaml.parse(text, Loader=loader or yaml.SafeLoader):
            if isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
                depth += 1
                if depth > limit:
                    mark = event.start_mark
                    raise InputError(f"{label}: {what} nests mappings/sequences deeper than {limit} levels "
                                     f"(line {mark.line + 1}); expected at most {limit}")
            elif isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
                depth -= 1
    except yaml.YAMLError:
        return


#: Most training steps of one stage (``train_bv.py --steps``, the training YAML's ``steps.*``).
MAX_TRAINING_STEPS: int = 100_000_000

_DECIMAL_CHARS = frozenset("0123456789")


def parse_cli_int(name: str, text: str, lo: int, hi: int) -> int:
    """A command-line integer: plain decimal digits (an optional leading ``-``/``+``) in [lo, hi].

    Python's ``int()`` also takes ``1_000`` and surrounding spaces, YAML ``0x10``; neither is
    what a user means on a command line, so both are refused (InputError naming ``name``).
    """
    body = text[1:] if text[:1] in "+-" else text
    if not body or not set(body) <= _DECIMAL_CHARS or len(body) > 30 or not lo <= int(text) <= hi:
        shown = text if text and text.strip() == text else repr(text)
        raise InputError(f"{name} {shown}: expected a decimal integer in [{lo}, {hi}]")
    return int(text)


def parse_cli_path(name: str, text: str) -> Path:
    """A command-line path: not empty or blank (``Path('')`` would be the current directory)."""
    if not text.strip() or "\0" in text:
        raise InputError(f"{name} {text!r}: expected a non-empty path")
    return Path(text)
