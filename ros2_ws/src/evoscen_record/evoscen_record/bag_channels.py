"""What a bag declares before its first message (:class:`evoscen_record.recorder.BagRecorder`): the
recorder's arguments checked, and one schema per message type and one channel per topic registered.

The order is the topics' order (types deduplicated, first appearance wins), so the file layout depends
only on the arguments; each channel carries rosbag2's ``offered_qos_profiles`` and ``topic_type_hash``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from mcap.writer import CompressionType, Writer

from evoscen_contract.qos import rosbag2_qos_yaml
from evoscen_contract.topics import TopicSpec
from evoscen_record.schemas import type_description_hash
from evoscen_sim.errors import InputError

COMPRESSIONS: dict[str, CompressionType] = {
    "zstd": CompressionType.ZSTD,
    "lz4": CompressionType.LZ4,
    "none": CompressionType.NONE,
}


@dataclass
class TopicState:
    """Per-topic bookkeeping of a recorder."""

    spec: TopicSpec
    channel_id: int
    message_count: int = 0


def check_arguments(compression: str, chunk_size: int, chunk_duration_ns: int, topics: Sequence[TopicSpec]) -> None:
    """The recorder's arguments, checked before anything touches the disk (InputError otherwise)."""
    if compression not in COMPRESSIONS:
        raise InputError(
            f"BagRecorder compression: {compression!r} is not one of {sorted(COMPRESSIONS)}"
        )
    if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1:
        raise InputError(f"BagRecorder chunk_size: {chunk_size!r} is not an integer >= 1 byte")
    if isinstance(chunk_duration_ns, bool) or not isinstance(chunk_duration_ns, int) or chunk_duration_ns < 0:
        raise InputError(f"BagRecorder chunk_duration_ns: {chunk_duration_ns!r} is not an integer >= 0 ns")
    names = [spec.name for spec in topics]
    dups = sorted({n for n in names if names.count(n) > 1})
    if dups:
        raise InputError(f"BagRecorder topics: duplicate topic names {dups}")


def register_topics(writer: Writer, topics: Sequence[TopicSpec], definitions: Mapping[str, str]) -> dict[str, TopicState]:
    """Each topic's schema (types deduplicated, first appearance wins) and channel, registered in order."""
    schema_ids: dict[str, int] = {}
    states: dict[str, TopicState] = {}
    for spec in topics:
        if spec.type_name not in schema_ids:
            schema_ids[spec.type_name] = writer.register_schema(
                name=spec.type_name, encoding="ros2msg", data=definitions[spec.type_name].encode("utf-8"))
        channel_id = writer.register_channel(
            topic=spec.name, message_encoding="cdr", schema_id=schema_ids[spec.type_name],
            metadata={"offered_qos_profiles": rosbag2_qos_yaml([spec.qos]),
                      "topic_type_hash": type_description_hash(spec.type_name)})
        states[spec.name] = TopicState(spec=spec, channel_id=channel_id)
    return states
