"""Core of the bag replay tool (``scripts/replay.py``), without ROS.

What the replayer needs from a rosbag2 bag (MCAP storage), read without rosbag2 and
without rclpy, so it can be validated before the middleware starts and tested alone:

* :func:`read_bag_topics` - the bag's topics: name, type, message encoding, message
  count and the *original* QoS, from the channel metadata ``offered_qos_profiles``
  (a rosbag2 YAML string) or, failing that, from ``metadata.yaml``;
* :func:`parse_offered_qos` - rosbag2's offered profiles (metadata version 9 strings
  ``keep_all``/``reliable``/..., or version <= 8 enum integers, as a YAML string or an
  already parsed list) reduced to one :class:`~evoscen_contract.qos.QosSpec` the way
  ``ros2 bag play`` adapts recorded offers;
* :func:`select_topics`, :func:`message_class_path`, :func:`parse_rate`,
  :func:`parse_seconds` - argument checks (one-line :class:`InputError`);
* :func:`iter_replay` - the messages of the selected topics in log-time order;
* :class:`Pacer` - paces the messages in simulation time (``rate`` 1.0 = real time,
  0 = as fast as possible).

Everything that touches rclpy (message classes, publishers, matching, acks) lives in
:mod:`evoscen_eval.scenes.replay_wire`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from evoscen_contract.qos import QosSpec
from evoscen_record.bag_reader import bag_file, open_bag_reader, read_bag_metadata
from evoscen_sim.limits import MAX_SECONDS_ARG
from evoscen_sim.errors import InputError

#: QoS used when a topic has no recorded offer (rclcpp's default profile).
DEFAULT_QOS = QosSpec(reliability="reliable", durability="volatile", history="keep_last", depth=10)
#: Message encoding the replayer can publish.
CDR = "cdr"

# rosbag2 writes the policies as lower-case names (metadata version 9) or as the rmw
# enum values (version <= 8). "system_default" / "unknown" / "best_available" are mapped
# to what an rmw publisher would offer for them.
_HISTORY = {"system_default": None, "keep_last": "keep_last", "keep_all": "keep_all", "unknown": None,
            0: None, 1: "keep_last", 2: "keep_all", 3: None}
_RELIABILITY = {"system_default": None, "reliable": "reliable", "best_effort": "best_effort", "unknown": None,
                "best_available": "reliable", 0: None, 1: "reliable", 2: "best_effort", 3: None, 4: "reliable"}
_DURABILITY = {"system_default": None, "transient_local": "transient_local", "volatile": "volatile",
               "unknown": None, "best_available": "transient_local",
               0: None, 1: "transient_local", 2: "volatile", 3: None, 4: "transient_local"}


@dataclass(frozen=True)
class BagTopic:
    """One topic of a bag, as the replayer publishes it.

    Attributes:
        name: topic name.
        type_name: ``pkg/msg/Type``.
        encoding: message encoding of the channel (``cdr`` for ROS 2).
        qos: the QoS to offer (adapted from the recorded offers).
        message_count: messages on the topic (-1 if the bag does not say).
    """

    name: str
    type_name: str
    encoding: str
    qos: QosSpec
    message_count: int


def _policy(table: Mapping[Any, str | None], value: Any, what: str, where: str) -> str | None:
    key = value.lower() if isinstance(value, str) else value
    if isinstance(key, bool) or key not in table:
        allowed = sorted(str(k) for k in table if isinstance(k, str))
        raise InputError(f"{where}: offered_qos_profiles {what} = {value!r}: expected one of {allowed}")
    return table[key]


def _one_profile(profile: Any, where: str) -> QosSpec:
    if not isinstance(profile, Mapping):
        raise InputError(f"{where}: offered_qos_profiles entry {profile!r}: expected a mapping")
    history = _policy(_HISTORY, profile.get("history", "system_default"), "history", where) or "keep_last"
    reliability = _policy(_RELIABILITY, profile.get("reliability", "system_default"), "reliability", where)
    durability = _policy(_DURABILITY, profile.get("durability", "system_default"), "durability", where)
    depth = profile.get("depth", 0)
    if isinstance(depth, bool) or not isinstance(depth, int) or depth < 0:
        raise InputError(f"{where}: offered_qos_profiles depth = {depth!r}: expected an integer >= 0")
    if history == "keep_last" and depth == 0:
        depth = DEFAULT_QOS.depth  # "system default" depth
    if history == "keep_all":
        depth = 0  # ignored by keep_all; rosbag2 writes 0
    return QosSpec(reliability=reliability or DEFAULT_QOS.reliability,
                   durability=durability or DEFAULT_QOS.durability, history=history, depth=depth)


def parse_offered_qos(value: Any, where: str = "bag") -> QosSpec:
    """Reduce rosbag2's ``offered_qos_profiles`` to the one profile to offer on replay.

    Args:
        value: a YAML string (MCAP channel metadata, ``metadata.yaml`` before version 9),
            an already parsed list of profile mappings, or None / ``""`` (no offer
            recorded).
        where: names the bag and topic in error messages.

    Returns:
        One offer: the recorded profile if there is one (or all are equal); with several
        different offers, as ``ros2 bag play`` adapts them: reliable only if every offer is
        reliable, transient_local only if every offer is, keep_all if any offer is, else
        keep_last with the largest depth. No offer: :data:`DEFAULT_QOS`.

    Raises:
        InputError: not YAML, not a list of mappings, or an unknown policy value.
    """
    if value is None:
        return DEFAULT_QOS
    if isinstance(value, (bytes, str)):
        text = value.decode("utf-8", "replace") if isinstance(value, bytes) else value
        if not text.strip():
            return DEFAULT_QOS
        try:
            value = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise InputError(f"{where}: offered_qos_profiles is not YAML: {reason}") from None
        if value is None:
            return DEFAULT_QOS
    if isinstance(value, Mapping):
        value = [value]
    if not isinstance(value, list):
        raise InputError(f"{where}: offered_qos_profiles = {value!r}: expected a list of QoS profiles")
    specs = [_one_profile(p, where) for p in value]
    if not specs:
        return DEFAULT_QOS
    if all(s == specs[0] for s in specs):
        return specs[0]
    keep_all = any(s.history == "keep_all" for s in specs)
    return QosSpec(
        reliability="reliable" if all(s.reliability == "reliable" for s in specs) else "best_effort",
        durability="transient_local" if all(s.durability == "transient_local" for s in specs) else "volatile",
        history="keep_all" if keep_all else "keep_last",
        depth=0 if keep_all else max(s.depth for s in specs),
    )


def _metadata_topics(bag_dir: Path) -> dict[str, dict[str, Any]]:
    """``{topic: topic_metadata (+ message_count)}`` from ``metadata.yaml`` ({} if absent)."""
    if not bag_dir.is_dir():
        return {}
    info = read_bag_metadata(bag_dir)
    if info is None:
        return {}
    try:
        out = {}
        for entry in info.get("topics_with_message_count") or []:
            md = dict(entry["topic_metadata"])
            md["message_count"] = entry.get("message_count", -1)
            out[str(md["name"])] = md
        return out
    except (KeyError, TypeError, AttributeError, ValueError) as exc:
        raise InputError(f"bag {str(bag_dir)!r}: metadata.yaml is unreadable or not rosbag2 metadata: {exc}") from None


def _channels_and_schemas(path: Path) -> tuple[dict[int, Any], dict[int, Any], dict[int, int] | None]:
    """Channels, schemas and per-channel message counts of an MCAP file (summary, else a scan)."""
    from mcap.reader import make_reader
    from mcap.records import Channel, Message, Schema
    from mcap.stream_reader import StreamReader

    try:
        with open(path, "rb") as stream:
            reader = make_reader(stream)
            reader.get_header()
            summary = reader.get_summary()
            if summary is not None:
                counts = dict(summary.statistics.channel_message_counts) if summary.statistics else None
                return dict(summary.channels), dict(summary.schemas), counts
            stream.seek(0)
            channels: dict[int, Any] = {}
            schemas: dict[int, Any] = {}
            counted: dict[int, int] = {}
            for record in StreamReader(stream, skip_magic=False).records:
                if isinstance(record, Channel):
                    channels[record.id] = record
                elif isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Message):
                    counted[record.channel_id] = counted.get(record.channel_id, 0) + 1
            return channels, schemas, counted
    except OSError as exc:
        raise InputError(f"bag {str(path)!r}: cannot open: {exc.strerror or exc}") from None
    except Exception as exc:  # noqa: BLE001 - any decoder failure is a bad file
        raise InputError(f"bag {str(path)!r}: not a readable MCAP file: {exc!r}") from None


def read_bag_topics(bag_dir: Path | str) -> list[BagTopic]:
    """The topics of a rosbag2 MCAP bag, in channel order (topics of several channels once).

    The QoS comes from the channel metadata ``offered_qos_profiles`` (what rosbag2 and
    :class:`~evoscen_record.recorder.BagRecorder` write), else from ``metadata.yaml``, else
    :data:`DEFAULT_QOS`. The type is the channel's schema name (else ``metadata.yaml``'s).

    Raises:
        InputError: the bag is missing, unreadable or corrupt, a topic has no type, a
            topic is recorded with two types, or a QoS entry is malformed (names the path).
    """
    bag_dir = Path(bag_dir)
    path = bag_file(bag_dir)
    meta = _metadata_topics(bag_dir)
    channels, schemas, counts = _channels_and_schemas(path)
    merged: dict[str, dict[str, Any]] = {}
    for cid in sorted(channels):
        ch = channels[cid]
        schema = schemas.get(ch.schema_id)
        md = meta.get(ch.topic, {})
        type_name = (schema.name if schema is not None and schema.name else "") or str(md.get("type", ""))
        where = f"bag {str(bag_dir)!r}: topic {ch.topic!r}"
        if not type_name:
            raise InputError(f"{where}: no message type recorded (no schema, no metadata.yaml entry)")
        offered = ch.metadata.get("offered_qos_profiles") if ch.metadata else None
        if offered is None or (isinstance(offered, str) and not offered.strip()):
            offered = md.get("offered_qos_profiles")
        qos = parse_offered_qos(offered, where)
        count = counts.get(cid, 0) if counts is not None else int(md.get("message_count", -1))
        entry = merged.get(ch.topic)
        if entry is None:
            merged[ch.topic] = {"type": type_name, "encoding": ch.message_encoding, "qos": [qos], "count": count}
        else:
            if entry["type"] != type_name:
                raise InputError(f"{where}: recorded with two types, {entry['type']!r} and {type_name!r}")
            entry["qos"].append(qos)
            entry["count"] = -1 if min(entry["count"], count) < 0 else entry["count"] + count
    topics = []
    for name, e in merged.items():
        qos = e["qos"][0] if len(e["qos"]) == 1 else parse_offered_qos([q.to_rosbag2() for q in e["qos"]])
        topics.append(BagTopic(name, e["type"], e["encoding"], qos, e["count"]))
    return topics


def select_topics(topics: Sequence[BagTopic], wanted: Iterable[str] | None, bag: str = "bag") -> list[BagTopic]:
    """The topics to replay: all (``wanted`` None) or the named ones, in bag order.

    Raises:
        InputError: a name is not a topic of the bag (the message lists the bag's topics).
    """
    if wanted is None:
        return list(topics)
    names = list(dict.fromkeys(wanted))
    known = {t.name for t in topics}
    missing = [n for n in names if n not in known]
    if missing:
        raise InputError(f"--topics {' '.join(missing)}: not in {bag} (its topics: "
                         f"{', '.join(t.name for t in topics) or 'none'})")
    return [t for t in topics if t.name in names]


def message_class_path(type_name: str) -> tuple[str, str]:
    """``("sensor_msgs.msg", "PointCloud2")`` for ``"sensor_msgs/msg/PointCloud2"``.

    ``pkg/Type`` (ROS 1 style, as some tools write) is read as ``pkg/msg/Type``.

    Raises:
        InputError: not a ``pkg/msg/Type`` name.
    """
    parts = type_name.split("/")
    if len(parts) == 2:
        parts = [parts[0], "msg", parts[1]]
    if len(parts) != 3 or parts[1] != "msg" or not all(p.isidentifier() for p in parts):
        raise InputError(f"message type {type_name!r}: expected 'pkg/msg/Type'")
    return f"{parts[0]}.msg", parts[2]


def parse_rate(text: str | float) -> float:
    """``--rate``: a finite number >= 0 (0 = as fast as possible).

    Raises:
        InputError: anything else (names the argument and value).
    """
    try:
        rate = float(text)
    except (TypeError, ValueError):
        rate = math.nan
    if not math.isfinite(rate) or rate < 0:
        raise InputError(f"--rate {text}: expected a finite number >= 0 (1 = real time, 0 = as fast as possible)")
    return rate


def parse_seconds(name: str, text: str | float) -> float:
    """A duration argument (``--start-delay``, ``--wait-timeout``): a number of seconds in
    [0, :data:`~evoscen_sim.limits.MAX_SECONDS_ARG`] (one day; ``time.sleep(1e300)`` overflows)."""
    try:
        value = float(text)
    except (TypeError, ValueError):
        value = math.nan
    if not math.isfinite(value) or not 0 <= value <= MAX_SECONDS_ARG:
        raise InputError(f"{name} {text}: expected a number of seconds in [0, {MAX_SECONDS_ARG:g}]")
    return value


def iter_replay(bag_dir: Path | str, topics: Iterable[str]) -> Iterator[tuple[str, int, bytes]]:
    """``(topic, log_time_ns, cdr_bytes)`` of the named topics, in log-time order (ties: file order).

    Raises:
        InputError: the bag is unreadable or corrupt (possibly during iteration).
    """
    wanted = frozenset(topics)
    for topic, _type, log_time, data in open_bag_reader(bag_dir, log_time_order=True):
        if topic in wanted:
            yield topic, log_time, data


class Pacer:
    """Paces messages in simulation (log) time.

    The first message of a pass goes out at once; message ``i`` at ``(t_i - t_0) / rate``
    wall-clock seconds after it. ``rate`` 0 never waits. :meth:`restart` starts a new
    pass (``--loop``).

    Args:
        rate: simulated seconds per wall-clock second (1.0 = real time; 0 = no pacing).
        clock: monotonic clock (s); ``sleep``: sleeps (s) - both injectable for tests.
    """

    def __init__(self, rate: float, clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        self.rate = parse_rate(rate)
        self._clock = clock
        self._sleep = sleep
        self._origin: tuple[int, float] | None = None

    def restart(self) -> None:
        """Forget the pass origin: the next message goes out at once."""
        self._origin = None

    def target(self, log_time_ns: int) -> float:
        """Wall-clock time (``clock`` units) at which a message of ``log_time_ns`` is due."""
        if self._origin is None:
            self._origin = (int(log_time_ns), self._clock())
        t0, w0 = self._origin
        if self.rate == 0:
            return w0
        return w0 + (int(log_time_ns) - t0) * 1e-9 / self.rate

    def wait(self, log_time_ns: int) -> None:
        """Sleep until the message of ``log_time_ns`` is due (messages before t_0 are not delayed)."""
        due = self.target(log_time_ns)
        while True:
            left = due - self._clock()
            if left <= 0:
                return
            self._sleep(left)
