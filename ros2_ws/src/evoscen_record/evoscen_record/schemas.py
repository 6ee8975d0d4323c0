"""Message-definition text for MCAP schemas, exactly as rosbag2 writes it.

rosbag2 stores, for every topic type, a *complete message definition* with encoding
``ros2msg`` (rosbag2 ``docs/message_definition_encoding.md``): the top-level ``.msg``
file text, then every dependency preceded by a two-line delimiter::

    <text of pkg/msg/Type.msg>
    ================================================================================
    MSG: other_pkg/Dep
    <text of other_pkg/msg/Dep.msg>
    ...

This module reproduces rosbag2's ``LocalMessageDefinitionSource::get_full_text``
(rosbag2_cpp, Jazzy) byte for byte:

* the ``.msg`` files are read verbatim (comments and blank lines kept) from
  ``<prefix>/share/<pkg>/msg/<Type>.msg``;
* the dependencies of one definition are the non-primitive field types found by
  rosbag2's regex ``(?:^|\\n)\\s*([a-zA-Z0-9_/]+)(?:\\[[^\\]]*\\])?\\s+``, written
  ``pkg/Type`` as in the ``.msg`` (a bare ``Type`` gets the containing package), kept in
  a *sorted set* (``std::set``);
* they are appended depth-first (each dependency followed by its own dependencies),
  each type once, in that sorted order. (So the order is "sorted, depth-first", not
  strictly "order of first appearance"; every consumer - ``mcap_ros2``, Foxglove,
  ``rosbags`` - accepts any order, and matching rosbag2 keeps our bags identical to a
  ``ros2 bag record`` of the same data.)

The package share directories are searched in ``AMENT_PREFIX_PATH`` order, then in
``sys.prefix`` (the venv the PyPI ROS 2 wheels install into), so nothing is hard-coded.

:func:`type_description_hash` returns the ``RIHS01_...`` type hash that rosidl
installs next to the ``.msg`` (``<Type>.json``), which rosbag2 stores as
``type_description_hash`` / ``topic_type_hash``.
"""

from __future__ import annotations

import json
import os
import re
import sys
from functools import lru_cache
from pathlib import Path

from evoscen_sim.errors import InputError

#: 80 ``=`` characters: the rosbag2 / ROS 1 definition delimiter line.
DELIMITER: str = "=" * 80

_MSG_FIELD_TYPE_RE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
_PRIMITIVE_TYPES = frozenset(
    {
        "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
        "int32", "uint32", "int64", "uint64", "string",
    }
)  # fmt: skip
_ROS_NAME = r"[a-zA-Z][a-zA-Z0-9_]*"
_TYPE_RE = re.compile(rf"^({_ROS_NAME})/(?:({_ROS_NAME})/)?({_ROS_NAME})$")


def _split_type(type_name: str) -> tuple[str, str, str]:
    """Split ``pkg/Type`` or ``pkg/msg/Type`` into ``(pkg, namespace, Type)``."""
    match = _TYPE_RE.match(type_name)
    if match is None:
        raise InputError(
            f"message type {type_name!r}: not of the form 'pkg/msg/Type' or 'pkg/Type'"
        )
    pkg, namespace, name = match.groups()
    return pkg, namespace or "msg", name


def share_prefixes() -> tuple[Path, ...]:
    """Return the install prefixes searched for ``share/<pkg>/``, in search order.

    ``AMENT_PREFIX_PATH`` entries first (as rosbag2 / ament_index do), then
    ``sys.prefix`` and ``sys.base_prefix`` (a venv with the ROS 2 PyPI wheels).
    Duplicates are removed, order kept.
    """
    candidates: list[str] = []
    env = os.environ.get("AMENT_PREFIX_PATH", "")
    candidates += [p for p in env.split(os.pathsep) if p]
    candidates += [sys.prefix, sys.base_prefix]
    seen: dict[str, None] = {}
    for c in candidates:
        seen.setdefault(c, None)
    return tuple(Path(c) for c in seen)


@lru_cache(maxsize=None)
def _find_interface_file(type_name: str, extension: str) -> Path | None:
    """Return the installed ``<Type><extension>`` file of a message type, or None."""
    pkg, namespace, name = _split_type(type_name)
    for prefix in share_prefixes():
        path = prefix / "share" / pkg / namespace / f"{name}{extension}"
        if path.is_file():
            return path
    return None


@lru_cache(maxsize=None)
def msg_text(type_name: str) -> str:
    """Return the verbatim ``.msg`` text of one type (``pkg/Type`` or ``pkg/msg/Type``).

    Raises:
        InputError: the type name is malformed or no ``.msg`` file is installed for it
            (names the type and the prefixes searched).
    """
    path = _find_interface_file(type_name, ".msg")
    if path is None:
        searched = ", ".join(str(p / "share") for p in share_prefixes())
        raise InputError(
            f"message type {type_name!r}: no .msg definition found under {searched} "
            "(is its interface package installed / AMENT_PREFIX_PATH set?)"
        )
    # newline="" keeps the bytes as installed (rosbag2 reads the file unmodified).
    with path.open("r", encoding="utf-8", newline="") as f:
        return f.read()


def msg_dependencies(text: str, package: str) -> list[str]:
    """Return the non-primitive field types of a ``.msg`` text, sorted, as rosbag2 does.

    Args:
        text: ``.msg`` file text.
        package: package of the message (context for bare type names).

    Returns:
        Sorted unique type names in ``pkg/Type`` form (as written in the ``.msg``).
    """
    deps: set[str] = set()
    for match in _MSG_FIELD_TYPE_RE.finditer(text):
        typ = match.group(1)
        if typ in _PRIMITIVE_TYPES:
            continue
        deps.add(typ if "/" in typ else f"{package}/{typ}")
    return sorted(deps)


@lru_cache(maxsize=None)
def message_definition(type_name: str) -> str:
    """Return the complete ``ros2msg`` definition of a type, as rosbag2 Jazzy writes it.

    Args:
        type_name: ``pkg/msg/Type`` (e.g. ``"sensor_msgs/msg/PointCloud2"``).

    Returns:
        The concatenated definition text (see the module docstring).

    Raises:
        InputError: a definition (the type or a dependency) is not installed.
    """
    seen: set[str] = set()

    def append_recursive(name: str, depth: int) -> str:
        if depth <= 0:
            raise InputError(f"message type {type_name!r}: dependency recursion too deep")
        text = msg_text(name)
        out = text
        for dep in msg_dependencies(text, _split_type(name)[0]):
            if dep not in seen:
                seen.add(dep)
                out += "\n" + DELIMITER + "\nMSG: " + dep + "\n" + append_recursive(dep, depth - 1)
        return out

    return append_recursive(type_name, 50)


@lru_cache(maxsize=None)
def type_description_hash(type_name: str) -> str:
    """Return the ``RIHS01_<sha256>`` type hash of a type, or ``""`` if unavailable.

    Read from the ``<Type>.json`` type description rosidl installs next to the
    ``.msg`` (entry whose ``type_name`` is the full ``pkg/msg/Type`` name).
    """
    pkg, namespace, name = _split_type(type_name)
    full = f"{pkg}/{namespace}/{name}"
    path = _find_interface_file(type_name, ".json")
    if path is None:
        return ""
    try:
        with path.open("r", encoding="utf-8") as f:
            doc = json.load(f)
        for entry in doc.get("type_hashes", []):
            if entry.get("type_name") == full:
                return str(entry.get("hash_string", ""))
    except (OSError, ValueError, AttributeError):
        return ""
    return ""
