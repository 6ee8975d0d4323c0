"""Reading a rosbag2 MCAP bag (as :class:`~evoscen_record.recorder.BagRecorder` writes it, or any
other): its ``metadata.yaml`` (:func:`read_bag_metadata`), its ``.mcap`` file (:func:`bag_file`)
and its raw messages (:func:`open_bag_reader`, for offline evaluation and replay), each with the
limits of docs/input-limits.md: anything unreadable is one :class:`~evoscen_sim.errors.InputError` line.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any, BinaryIO

import yaml
from evoscen_sim.errors import InputError
from mcap.exceptions import McapError
from mcap.reader import make_reader


def bag_or_run_dir(path: Path, label: str = "") -> Path:
    """A bag directory from ``path``: the bag itself, or a run directory's ``bag/`` (what
    ``run_scenario.py --out`` writes). ``label`` prefixes the error (e.g. ``"--bags "``)."""
    if not path.exists():
        raise InputError(f"{label}{path}: no such bag or run directory")
    if (path.is_dir() and not (path / "metadata.yaml").exists() and not any(path.glob("*.mcap"))
            and (path / "bag").is_dir()):
        return path / "bag"
    return path


def read_bag_metadata(bag_dir: Path) -> dict[str, Any] | None:
    """The ``rosbag2_bagfile_information`` mapping of ``bag_dir/metadata.yaml`` (None if absent).

    Read with the limits of docs/input-limits.md (at most
    :data:`~evoscen_sim.limits.MAX_METADATA_YAML_BYTES`, UTF-8 without NUL bytes, nesting at
    most :data:`~evoscen_sim.limits.MAX_YAML_DEPTH`); anything else is one InputError line.
    """
    from evoscen_sim.limits import MAX_METADATA_YAML_BYTES, check_yaml_depth, read_text_limited

    meta_path = bag_dir / "metadata.yaml"
    if not (meta_path.exists() or meta_path.is_symlink()):
        return None
    label = f"bag {str(bag_dir)!r}: metadata.yaml"
    text = read_text_limited(meta_path, label, "the file", MAX_METADATA_YAML_BYTES)
    check_yaml_depth(text, label, "the file")
    try:
        meta = yaml.safe_load(text)
        info = meta["rosbag2_bagfile_information"]
    except (yaml.YAMLError, KeyError, TypeError) as exc:
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise InputError(
            f"bag {str(bag_dir)!r}: metadata.yaml is unreadable or not rosbag2 metadata: {reason}"
        ) from None
    if not isinstance(info, dict):
        raise InputError(f"bag {str(bag_dir)!r}: metadata.yaml rosbag2_bagfile_information is not a mapping")
    return info


def _contained_file(bag_dir: Path, name: Any) -> Path:
    """``bag_dir / name`` if ``name`` is a relative path that stays inside ``bag_dir``."""
    where = f"bag {str(bag_dir)!r}: metadata.yaml relative_file_paths entry {name!r}"
    if not isinstance(name, str) or not name or "\0" in name:
        raise InputError(f"{where}: expected a file name inside the bag directory")
    rel = Path(name)
    if rel.is_absolute() or ".." in rel.parts:
        raise InputError(f"{where}: points outside the bag directory; expected a file name inside it")
    path = bag_dir / rel
    try:
        inside = path.resolve().is_relative_to(bag_dir.resolve())
    except (OSError, RuntimeError):
        inside = False
    if not inside:
        raise InputError(f"{where}: resolves outside the bag directory (a link?); expected a file inside it")
    return path


def bag_file(bag_dir: Path) -> Path:
    """Return the .mcap file of a bag directory (or the file itself if given one).

    The file named by ``metadata.yaml``'s ``relative_file_paths`` must lie inside the bag
    directory (an absolute path, ``..`` or a link leading out is refused)."""
    if bag_dir.is_file():
        return bag_dir
    if not bag_dir.is_dir():
        raise InputError(f"bag {str(bag_dir)!r}: no such bag directory or .mcap file")
    info = read_bag_metadata(bag_dir)
    if info is not None:
        files = info.get("relative_file_paths")
        if not isinstance(files, list) or len(files) != 1:
            raise InputError(
                f"bag {str(bag_dir)!r}: metadata.yaml relative_file_paths {files!r}; "
                "exactly one .mcap file is supported"
            )
        path = _contained_file(bag_dir, files[0])
        if not path.is_file():
            raise InputError(f"bag {str(bag_dir)!r}: file {files[0]!r} named in metadata.yaml is missing")
        return path
    mcaps = sorted(bag_dir.glob("*.mcap"))
    if len(mcaps) != 1:
        raise InputError(
            f"bag {str(bag_dir)!r}: no metadata.yaml and {len(mcaps)} .mcap files "
            "(expected exactly one)"
        )
    return mcaps[0]


def open_bag_reader(
    bag_dir: Path | str, *, log_time_order: bool = False
) -> Iterator[tuple[str, str, int, bytes]]:
    """Iterate over the raw messages of a bag.

    Args:
        bag_dir: a bag directory (or directly its ``.mcap`` file).
        log_time_order: False (default): file order, i.e. the order written (for a bag
            of :class:`~evoscen_record.recorder.BagRecorder` the recording order); True: sorted by log time
            (ties in file order).

    Returns:
        An iterator of ``(topic, type_name, log_time_ns, cdr_bytes)``.

    Raises:
        InputError: the bag is missing, not an MCAP file, truncated or corrupt (the
            message names the path). Raised by this call for what the file's start and
            summary show, and during iteration for corrupt data further on.
    """
    path = bag_file(Path(bag_dir))
    try:
        stream = open(path, "rb")  # noqa: SIM115
    except OSError as exc:
        raise InputError(f"bag {str(path)!r}: cannot open: {exc.strerror or exc}") from None
    try:
        reader = make_reader(stream)
        reader.get_header()
        reader.get_summary()
    except (McapError, ValueError, KeyError, EOFError, OSError, IndexError) as exc:
        stream.close()
        raise InputError(f"bag {str(path)!r}: not a readable MCAP file: {exc}") from None
    except Exception as exc:  # noqa: BLE001 - any decoder failure is a bad file
        stream.close()
        raise InputError(f"bag {str(path)!r}: not a readable MCAP file: {exc!r}") from None
    return _iter_messages(stream, reader, path, log_time_order)


def _iter_messages(
    stream: BinaryIO, reader: Any, path: Path, log_time_order: bool
) -> Iterator[tuple[str, str, int, bytes]]:
    """Yield ``(topic, type, log_time_ns, data)``; close ``stream`` at the end."""
    try:
        for schema, channel, message in reader.iter_messages(log_time_order=log_time_order):
            type_name = schema.name if schema is not None else ""
            yield channel.topic, type_name, int(message.log_time), bytes(message.data)
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - corrupt data anywhere in the file
        raise InputError(f"bag {str(path)!r}: corrupt MCAP data: {exc!r}") from None
    finally:
        stream.close()
