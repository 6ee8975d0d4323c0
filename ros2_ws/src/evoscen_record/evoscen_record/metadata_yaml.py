"""The rosbag2 ``metadata.yaml`` of a bag (version 9, as Jazzy writes it): its content
(:func:`bagfile_information`) and its deterministic YAML text, the same text in the MCAP file's
``rosbag2`` metadata record (:func:`dump_metadata_yaml`)."""

from __future__ import annotations

import re
from collections.abc import Iterable
from typing import Any

import yaml

from evoscen_record.schemas import type_description_hash

#: rosbag2 metadata version written (Jazzy).
METADATA_VERSION: int = 9
#: ``ros_distro`` written to the metadata.
ROS_DISTRO: str = "jazzy"


def bagfile_information(topics: Iterable[tuple[Any, int]], file_name: str, start_ns: int | None,
                        end_ns: int | None, message_count: int) -> dict[str, Any]:
    """The rosbag2 ``metadata.yaml`` content of a one-file bag: ``topics`` as ``(TopicSpec,
    messages)`` in declaration order, the earliest and latest log times (None: no message).

    Times: ``starting_time`` = earliest log time, ``duration`` = latest - earliest
    (both 0 for an empty bag), in ns of simulation time.
    """
    start = start_ns if start_ns is not None else 0
    duration = (end_ns - start) if end_ns is not None else 0
    return {
        "rosbag2_bagfile_information": {
            "version": METADATA_VERSION,
            "storage_identifier": "mcap",
            "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": message_count,
            "topics_with_message_count": [
                {
                    "topic_metadata": {
                        "name": spec.name,
                        "type": spec.type_name,
                        "serialization_format": "cdr",
                        "offered_qos_profiles": spec.offered_qos_profiles(),
                        "type_description_hash": type_description_hash(spec.type_name),
                    },
                    "message_count": count,
                }
                for spec, count in topics
            ],
            "compression_format": "",
            "compression_mode": "",
            "relative_file_paths": [file_name],
            "files": [
                {
                    "path": file_name,
                    "starting_time": {"nanoseconds_since_epoch": start},
                    "duration": {"nanoseconds": duration},
                    "message_count": message_count,
                }
            ],
            "custom_data": {},
            "ros_distro": ROS_DISTRO,
        }
    }


def _dump_yaml(data: Any) -> str:
    """Dump YAML deterministically (insertion key order, block style)."""
    return yaml.safe_dump(data, sort_keys=False, default_flow_style=False)


_PLAIN = re.compile(r"[A-Za-z0-9_./-]{0,100}")
_METADATA_KEY = "rosbag2_bagfile_information"


def _plain_strings(data: Any) -> bool:
    """Whether every string in ``data`` (keys and values) is at most 100 characters of
    ``[A-Za-z0-9_./-]``: no space, quote, colon, newline or non-ASCII character, nothing the
    YAML emitters could quote, escape or wrap differently."""
    if isinstance(data, str):
        return _PLAIN.fullmatch(data) is not None
    if isinstance(data, dict):
        return all(_plain_strings(k) and _plain_strings(v) for k, v in data.items())
    if isinstance(data, list):
        return all(_plain_strings(v) for v in data)
    return isinstance(data, (int, float, bool)) or data is None


def dump_metadata_yaml(info: dict[str, Any]) -> tuple[str, str]:
    """``(_dump_yaml(info), _dump_yaml({"rosbag2_bagfile_information": info}))``: the rosbag2 metadata
    record's text and ``metadata.yaml``'s.

    With only plain strings in ``info`` (:func:`_plain_strings`; always so for evoscen's topics and
    a bag directory named with letters, digits, ``_ . -``) one dump by libyaml's emitter (~1 ms
    instead of two of ~5 ms by the Python emitter) gives both: the nested document is the same
    lines indented by two spaces (block style; a sequence in a mapping is not indented, and no
    plain string can wrap). Otherwise the two dumps as before. A test compares the texts.
    """
    dumper = getattr(yaml, "CSafeDumper", None)
    if dumper is None or not _plain_strings(info):
        return _dump_yaml(info), _dump_yaml({_METADATA_KEY: info})
    text = yaml.dump(info, Dumper=dumper, sort_keys=False, default_flow_style=False)
    return text, f"{_METADATA_KEY}:\n" + "".join("  " + line for line in text.splitlines(True))

