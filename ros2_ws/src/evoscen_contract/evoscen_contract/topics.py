"""THE evoscen topic contract, ROS binding: every topic, its type, QoS, publisher, rate and meaning.

The contract's facts (topic and type names, table columns, role and policy codes, event
names and keys, exit statuses) are defined once, without ROS, in
:mod:`evoscen_contract.contract`, which the cores import; this module re-exports them and
binds them to ROS: the message classes, the QoS profiles, the :class:`TopicSpec` rows and
the message builders. Every node, the recorder and the replayer import it
(:func:`contract_markdown` renders the table of docs/topics.md). Nothing else in evoscen may spell a
topic name, a table's column list or a QoS profile.

Time: every message is stamped with *simulation* time (integer nanoseconds in the
cores, ``builtin_interfaces/Time`` on the wire). Step ``k`` happens at ``t_k``.

Lockstep (docs/architecture.md §4): the sim publishes ``/clock`` and
``/evoscen/world`` stamped ``t_k``; every controller answers on its command topic with
a table stamped with the *same* ``t_k`` (``header.stamp`` of the world message it
answers, ``frame_id = "map"``). The stamp alone identifies the step (the sim keeps
``t_k`` exactly, as integer nanoseconds), so no step counter is put in ``frame_id``.

QoS choices:

* Per-step topics (``/clock``, world, commands, odom, events) are **reliable**,
  volatile, **keep_all**. Reliable because the run is lockstep and the bag must
  hold every step: a lost world or command message would stall a step (or, with the
  deadline policy, turn into a spurious fault), and a lost ``/clock`` would make
  ``use_sim_time`` nodes skip time. Many ROS 2 tools publish ``/clock`` best effort;
  a reliable writer still matches best-effort readers (e.g. ``rclcpp``'s default
  clock subscription), so nothing is lost by choosing reliable. Keep-all because the
  recorder is outside the lockstep loop and may lag behind the simulation: with
  ``keep_last(N)`` a lag of more than N steps silently overwrites samples (seen: a
  3,000-step run losing 3 % of its world messages); with keep-all the middleware keeps
  every unacknowledged sample, so a slow recorder costs memory for a while, never data.
  Lockstep controllers never lag more than one step. (rosbag2 reports keep-all with
  depth 0.)
* ``/evoscen/roster`` is reliable, **transient_local**, ``keep_last(1)``: published
  once, delivered to late joiners (the recorder, RViz, a replay tool).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import PointCloud2
from visualization_msgs.msg import MarkerArray

from evoscen_contract.qos import QosSpec
from evoscen_contract.tables import stamp_from_ns

# The facts (names, columns, codes, events, exit statuses) are defined once, ROS-free, in
# evoscen_contract.contract; re-exported here so that ``T.<name>`` works in ROS code.
from evoscen_contract.contract import (  # noqa: F401  (re-exported)
    COMMAND_FIELDS,
    DEFAULT_EVENT_LEVELS,
    EVENT_COLLISION,
    EVENT_EXPOSURE,
    EVENT_FAULT,
    EVENT_HARDWARE_ID,
    EVENT_KEY_TYPES,
    EVENT_KINDS,
    EVENT_LANE_CHANGE,
    EVENT_NAMES,
    EVENT_OFF_ROAD,
    EVENT_REENTRY,
    EVENT_RUN_END,
    EXIT_BAD_INPUT,
    EXIT_FAULT,
    EXIT_HOST_FAULT,
    EXIT_INTERRUPTED,
    EXIT_NODE_DIED,
    EXIT_OK,
    FIELD_DOCS,
    GRAPH_EXIT_STATUSES,
    KIND_ABORT,
    KIND_ABORTED,
    KIND_COMPLETED,
    KIND_DEADLINE,
    KIND_END,
    KIND_INTERRUPTED,
    KIND_START,
    LEVEL_ERROR,
    LEVEL_OK,
    LEVEL_STALE,
    LEVEL_WARN,
    MAP_FRAME,
    NODE_BV,
    NODE_EVAL,
    NODE_EXIT_STATUSES,
    NODE_SIM,
    NODE_SUT,
    POLICY_CODES,
    POLICY_NAMES,
    ROLE_BV,
    ROLE_SUT,
    ROSTER_FIELDS,
    SOCIAL_POLICIES,
    SUT_BASE_FRAME,
    TOPIC_CLOCK,
    TOPIC_COMMANDS_BV,
    TOPIC_COMMANDS_SUT,
    TOPIC_EVENTS,
    TOPIC_MAP_MARKERS,
    TOPIC_MARKERS,
    TOPIC_ROSTER,
    TOPIC_SUT_ODOM,
    TOPIC_TYPES,
    TOPIC_WORLD,
    WORLD_FIELDS,
    bv_node_name,
    command_topic,
    is_bv_command_topic,
)

_RESERVED_EVENT_KEYS = ("name", "level", "message")

# --------------------------------------------------------------------------- spec


@dataclass(frozen=True)
class TopicSpec:
    """One row of the topic contract.

    Attributes:
        name: absolute topic name.
        type_name: ROS 2 type name, ``pkg/msg/Type``.
        msg_class: the rclpy message class.
        qos: QoS of publishers and subscriptions (:class:`QosSpec`).
        publisher: name of the node that publishes it.
        rate: publication rate, in words.
        description: meaning (one line).
        fields: column names for flat-table topics (PointCloud2 tables), else ``()``.
    """

    name: str
    type_name: str
    msg_class: type
    qos: QosSpec
    publisher: str
    rate: str
    description: str
    fields: tuple[str, ...] = ()
    subscribers: tuple[str, ...] = ()
    """evoscen's own subscribers (any other node may subscribe too)."""

    def qos_profile(self) -> Any:
        """Return the ``rclpy.qos.QoSProfile`` of this topic."""
        return self.qos.to_rclpy()

    def offered_qos_profiles(self) -> list[dict[str, Any]]:
        """Return rosbag2's ``offered_qos_profiles`` list (one profile: the contract's)."""
        return [self.qos.to_rosbag2()]


#: QoS of every per-step topic (see module docstring for why).
STEP_QOS = QosSpec(reliability="reliable", durability="volatile", history="keep_all", depth=0)
#: QoS of once-published, latched data.
LATCHED_QOS = QosSpec(
    reliability="reliable", durability="transient_local", history="keep_last", depth=1
)


def _row(name: str, msg_class: type, publisher: str, subscribers: tuple[str, ...], rate: str, description: str,
         qos: QosSpec = STEP_QOS, fields: tuple[str, ...] = ()) -> TopicSpec:
    """A row of the contract, its type the one :data:`TOPIC_TYPES` names for the topic."""
    return TopicSpec(name=name, type_name=TOPIC_TYPES[name], msg_class=msg_class, qos=qos, publisher=publisher,
                     rate=rate, description=description, fields=fields, subscribers=subscribers)


# the rows: topic, message class, publisher, evoscen's subscribers, rate, meaning (QoS: STEP_QOS unless named)
CLOCK = _row(TOPIC_CLOCK, Clock, NODE_SIM, (NODE_EVAL,), "every step", "simulation time t_k, for use_sim_time")
WORLD = _row(TOPIC_WORLD, PointCloud2, NODE_SIM, (NODE_BV, NODE_SUT, NODE_EVAL), "every step",
             "world state at t_k: flat table, one row per vehicle, columns WORLD_FIELDS, frame 'map'",
             fields=WORLD_FIELDS)
COMMANDS_BV = _row(
    TOPIC_COMMANDS_BV, PointCloud2, NODE_BV, (NODE_SIM, NODE_EVAL), "every step (answer to the world at t_k)",
    "BV commands: flat table, one row per hosted BV, columns COMMAND_FIELDS; "
    "stamp = t_k of the world step answered, frame 'map'. One topic per BV node, "
    "`/evoscen/commands/bv_<part>` from node `evoscen_bv_<part>` (`bvs.nodes`: by_policy, the default, "
    "as listed here; `bv_level0`, ... for a rule-based driver; `bv_0` ... `bv_<N-1>` for N nodes; "
    "`/evoscen/commands/bv` from `evoscen_bv` for `single`)",
    fields=COMMAND_FIELDS)
COMMANDS_SUT = _row(TOPIC_COMMANDS_SUT, PointCloud2, NODE_SUT, (NODE_SIM, NODE_EVAL),
                    "every step (answer to the world at t_k)",
                    "SUT command: flat table, one row, columns COMMAND_FIELDS; "
                    "stamp = t_k of the world step answered, frame 'map'",
                    fields=COMMAND_FIELDS)
SUT_ODOM = _row(TOPIC_SUT_ODOM, Odometry, NODE_SIM, (NODE_EVAL,), "every step",
                f"SUT pose in '{MAP_FRAME}' and twist in '{SUT_BASE_FRAME}' "
                "(linear.x = speed m/s, angular.z = yaw rate rad/s)")
EVENTS = _row(TOPIC_EVENTS, DiagnosticArray, NODE_SIM, (NODE_EVAL,),
              "every step (after the integration; empty when nothing happened)",
              "one DiagnosticStatus per event: " + ", ".join(EVENT_NAMES) + "; key/values " + ", ".join(EVENT_KEY_TYPES))
ROSTER = _row(TOPIC_ROSTER, PointCloud2, NODE_SIM, (NODE_EVAL,), "once, at start (latched)",
              "vehicles of the scenario: flat table, one row per vehicle, columns ROSTER_FIELDS",
              qos=LATCHED_QOS, fields=ROSTER_FIELDS)
MARKERS = _row(TOPIC_MARKERS, MarkerArray, NODE_SIM, (NODE_EVAL,), "every recording.markers_every steps (default 5)",
               "vehicles as oriented boxes sized to each vehicle, coloured by policy (competitive red, "
               "mutual blue, cooperative green, level-0 grey, SUT amber), with id and speed as text; frame 'map'")
MAP_MARKERS = _row(TOPIC_MAP_MARKERS, MarkerArray, NODE_SIM, (NODE_EVAL,), "once, at start (latched)",
                   "lane lines (broken) and road edges (solid) as LINE_LIST markers; frame 'map'", qos=LATCHED_QOS)

#: The whole contract, in the order of docs/topics.md.
CONTRACT: tuple[TopicSpec, ...] = (CLOCK, WORLD, COMMANDS_BV, COMMANDS_SUT, SUT_ODOM, EVENTS, ROSTER, MARKERS, MAP_MARKERS)
#: Contract by topic name.
TOPICS: dict[str, TopicSpec] = {spec.name: spec for spec in CONTRACT}


def bv_command_spec(node: str) -> TopicSpec:
    """The command topic of BV node ``node`` (:func:`evoscen_contract.contract.bv_node_name`): the
    row of :data:`COMMANDS_BV` under the node's own topic name and publisher (docs/architecture.md
    §5, "BV nodes": one topic per node)."""
    if node == NODE_BV:
        return COMMANDS_BV
    import dataclasses

    return dataclasses.replace(COMMANDS_BV, name=command_topic(node), publisher=node)


def contract_for(bv_nodes: Sequence[str]) -> tuple[TopicSpec, ...]:
    """The contract of a run whose BVs are hosted by ``bv_nodes`` (in partition order): :data:`CONTRACT`
    with :data:`COMMANDS_BV` replaced by one command topic per BV node, in that order (the bag's
    channels and its per-step topic order). No BV nodes (no BVs): :data:`CONTRACT` as it is."""
    if not bv_nodes or list(bv_nodes) == [NODE_BV]:
        return CONTRACT
    out: list[TopicSpec] = []
    for spec in CONTRACT:
        out += [bv_command_spec(n) for n in bv_nodes] if spec is COMMANDS_BV else [spec]
    return tuple(out)


def spec_of(topic: str) -> TopicSpec | None:
    """The contract row of ``topic``, a BV node's command topic (``/evoscen/commands/bv_<part>``)
    included; None for a topic outside the contract."""
    if topic in TOPICS:
        return TOPICS[topic]
    if is_bv_command_topic(topic):
        return bv_command_spec(NODE_BV + topic[len(TOPIC_COMMANDS_BV):])
    return None


def contract_markdown() -> str:
    """Render the contract as Markdown for docs/topics.md.

    Returns the topic table (topic | type | publisher | subscribers | QoS | rate | meaning; a meaning
    already given reads "as" the first topic with it), followed
    by the table columns with their meaning/units, the policy codes and the event keys.
    Deterministic (depends only on this module).
    """
    lines = [
        "| topic | type | publisher | subscribers | QoS | rate | meaning |",
        "|---|---|---|---|---|---|---|",
    ]
    def shown(name: str) -> str:  # the BV nodes: one per share of bvs.nodes (docs/architecture.md §5)
        return f"`{bv_node_name('<part>')}`" if name == NODE_BV else f"`{name}`"

    # the BV nodes' rows: those of the default scenario (bvs.nodes: by_policy, the learned mix)
    rows = contract_for([bv_node_name(p) for p in ("competitive", "mutual", "cooperative")])
    first_with: dict[str, str] = {}  # a meaning already given (the BV nodes' rows): "as" its first topic
    for spec in rows:
        subs = ", ".join(shown(s) for s in spec.subscribers)
        meaning = f"as `{first_with[spec.description]}`" if spec.description in first_with else spec.description
        first_with.setdefault(spec.description, spec.name)
        lines.append(
            f"| `{spec.name}` | `{spec.type_name}` | {shown(spec.publisher)} | {subs} | {spec.qos.short()} "
            f"| {spec.rate} | {meaning} |"
        )
    lines += ["", "Table columns (float64, one row per vehicle):", ""]
    lines += ["| table | columns |", "|---|---|"]
    for spec in rows:
        if spec.fields:
            lines.append(f"| `{spec.name}` | {', '.join(f'`{f}`' for f in spec.fields)} |")
    lines += ["", "| column | meaning (unit) |", "|---|---|"]
    for name, doc in FIELD_DOCS.items():
        lines.append(f"| `{name}` | {doc} |")
    lines += ["", "| event key | type |", "|---|---|"]
    for key, typ in EVENT_KEY_TYPES.items():
        lines.append(f"| `{key}` | {typ} |")
    return "\n".join(lines) + "\n"


CONTRACT_BEGIN, CONTRACT_END = "<!-- contract:begin -->", "<!-- contract:end -->"
"""The markers around the contract section of docs/topics.md (``scripts/contract_table.py --write``)."""


def contract_section(text: str) -> str:
    """The text between the contract markers of ``text`` (stripped); ValueError without them."""
    if CONTRACT_BEGIN not in text or CONTRACT_END not in text:
        raise ValueError(f"docs/topics.md: contract markers {CONTRACT_BEGIN} ... {CONTRACT_END} not found")
    return text.split(CONTRACT_BEGIN, 1)[1].split(CONTRACT_END, 1)[0].strip()


def write_contract_section(page: Path) -> bool:
    """Rewrite the contract section of ``page`` (docs/topics.md) as :func:`contract_markdown`; whether
    the section changed."""
    table = contract_markdown().strip()
    text = page.read_text(encoding="utf-8")
    old = contract_section(text)
    head, rest = text.split(CONTRACT_BEGIN, 1)
    page.write_text(f"{head}{CONTRACT_BEGIN}\n{table}\n{CONTRACT_END}{rest.split(CONTRACT_END, 1)[1]}", encoding="utf-8")
    return old != table


# --------------------------------------------------------------------------- builders


def clock_message(stamp_ns: int) -> Clock:
    """Return a ``rosgraph_msgs/Clock`` for simulation time ``stamp_ns`` (ns)."""
    return Clock(clock=stamp_from_ns(stamp_ns))


def odometry_message(
    x: float, y: float, yaw: float, speed: float, yaw_rate: float, stamp_ns: int
) -> Odometry:
    """Return the SUT odometry.

    Args:
        x, y: position in the map frame (m).
        yaw: heading in the map frame (rad, counter-clockwise from +x).
        speed: longitudinal speed (m/s), written to ``twist.twist.linear.x``.
        yaw_rate: yaw rate (rad/s), written to ``twist.twist.angular.z``.
        stamp_ns: simulation time (ns).

    Pose is in ``"map"``, twist in the child frame ``"sut/base_link"`` (REP 105);
    the orientation is the quaternion of a pure yaw rotation. Covariances stay zero
    (simulated, exact state).
    """
    msg = Odometry()
    msg.header.stamp = stamp_from_ns(stamp_ns)
    msg.header.frame_id = MAP_FRAME
    msg.child_frame_id = SUT_BASE_FRAME
    pose = msg.pose.pose
    pose.position.x = float(x)
    pose.position.y = float(y)
    pose.orientation.z = math.sin(0.5 * float(yaw))
    pose.orientation.w = math.cos(0.5 * float(yaw))
    msg.twist.twist.linear.x = float(speed)
    msg.twist.twist.angular.z = float(yaw_rate)
    return msg


def _encode_event_value(key: str, value: Any) -> str:
    """Encode one event value as a KeyValue string (see :data:`EVENT_KEY_TYPES`)."""
    typ = EVENT_KEY_TYPES.get(key, "str")
    try:
        if typ == "int":
            if isinstance(value, bool) or int(value) != value:
                raise ValueError
            return str(int(value))
        if typ == "float":
            if isinstance(value, bool):
                raise ValueError
            return repr(float(value))
        if typ == "ints":
            items = [int(v) for v in value]
            if any(isinstance(v, bool) or int(v) != v for v in value):
                raise ValueError
            return ",".join(str(v) for v in items)
    except (TypeError, ValueError):
        raise ValueError(
            f"event key {key!r}: value {value!r} is not of type {typ!r}"
        ) from None
    return str(value)


def _decode_event_value(key: str, text: str) -> Any:
    """Decode one KeyValue string (inverse of :func:`_encode_event_value`)."""
    typ = EVENT_KEY_TYPES.get(key, "str")
    try:
        if typ == "int":
            return int(text)
        if typ == "float":
            return float(text)
        if typ == "ints":
            return [int(v) for v in text.split(",")] if text else []
    except ValueError:
        raise ValueError(
            f"event key {key!r}: value {text!r} is not of type {typ!r}"
        ) from None
    return text


def events_message(events: Sequence[Mapping[str, Any]], stamp_ns: int) -> DiagnosticArray:
    """Return the ``/evoscen/events`` message for the events of one step.

    Args:
        events: one mapping per event. ``"name"`` (required, one of
            :data:`EVENT_NAMES`) -> ``DiagnosticStatus.name``; ``"level"`` (optional int
            0..3, default :data:`DEFAULT_EVENT_LEVELS`) -> ``level``; ``"message"``
            (optional str, default ``""``) -> ``message``; every other key becomes a
            KeyValue, in the mapping's order, encoded per :data:`EVENT_KEY_TYPES`.
        stamp_ns: simulation time (ns) of the step.

    Raises:
        ValueError: unknown event name, bad level, or a typed key with a wrong value.
    """
    msg = DiagnosticArray()
    msg.header.stamp = stamp_from_ns(stamp_ns)
    msg.header.frame_id = MAP_FRAME
    msg.status = [
        DiagnosticStatus(level=bytes((level,)), name=name, message=message, hardware_id=EVENT_HARDWARE_ID,
                         values=[KeyValue(key=key, value=value) for key, value in values])
        for level, name, message, values in event_statuses(events)
    ]
    return msg


def event_statuses(events: Sequence[Mapping[str, Any]]) -> list[tuple[int, str, str, list[tuple[str, str]]]]:
    """The ``DiagnosticStatus`` fields of each event as :func:`events_message` fills them (and checks
    them): ``(level, name, message, [(key, value), ...])``; the hardware id is
    :data:`EVENT_HARDWARE_ID`. What :func:`evoscen_contract.cdr.encode_event_statuses` writes.

    Raises:
        ValueError: as :func:`events_message`.
    """
    statuses = []
    for i, event in enumerate(events):
        name = event.get("name")
        if name not in EVENT_NAMES:
            raise ValueError(f"event {i}: name {name!r} is not one of {list(EVENT_NAMES)}")
        level = event.get("level", DEFAULT_EVENT_LEVELS[name])
        if isinstance(level, bool) or level not in (0, 1, 2, 3):
            raise ValueError(f"event {i} ({name}): level {level!r} is not one of 0, 1, 2, 3")
        statuses.append((int(level), name, str(event.get("message", "")), [
            (str(key), _encode_event_value(str(key), value))
            for key, value in event.items()
            if key not in _RESERVED_EVENT_KEYS
        ]))
    return statuses


def parse_events(msg: Any) -> list[dict[str, Any]]:
    """Return the events of an ``/evoscen/events`` message as dicts.

    Inverse of :func:`events_message`: each dict has ``"name"``, ``"level"`` (int) and
    ``"message"``, then the key/values decoded per :data:`EVENT_KEY_TYPES` (unknown
    keys as strings). Accepts rclpy, ``mcap_ros2`` and ``rosbags`` messages (``level``
    as bytes or int).

    Raises:
        ValueError: a typed value does not parse.
    """
    out: list[dict[str, Any]] = []
    for status in msg.status:
        level = status.level
        if isinstance(level, (bytes, bytearray)):
            level = level[0] if level else 0
        event: dict[str, Any] = {
            "name": str(status.name),
            "level": int(level),
            "message": str(status.message),
        }
        for kv in status.values:
            event[str(kv.key)] = _decode_event_value(str(kv.key), str(kv.value))
        out.append(event)
    return out

