"""The evoscen contract's facts, without ROS: names, columns, codes, events, exit statuses.

This module is pure Python (no ``rclpy``, no message package, no ``rosidl``, directly or
indirectly; a test checks it) and holds the *one* definition of every fact the nodes, the
cores and the scripts share:

* topic names and their ROS 2 type names (:data:`TOPIC_TYPES`), node names and frames;
* the flat tables' columns (:data:`WORLD_FIELDS`, :data:`COMMAND_FIELDS`,
  :data:`ROSTER_FIELDS`), their meaning (:data:`FIELD_DOCS`) and cell layout;
* the ``role`` and ``policy`` codes of those tables;
* event names, kinds, levels and typed keys of ``/evoscen/events``;
* the exit statuses of the nodes and the graph launcher.

The ROS binding, :mod:`evoscen_contract.topics`, adds what needs ROS: the message classes,
the QoS profiles, the publishers/subscribers of each topic (its :class:`TopicSpec` rows) and
the message builders; it re-exports every name defined here, so ``T.WORLD_FIELDS`` and
``contract.WORLD_FIELDS`` are the same object. Cores (the world, the scores, the drivers)
import this module; nodes, the recorder and the graph code import the binding.
"""

from __future__ import annotations

# --------------------------------------------------------------------------- nodes

#: Node names (publishers in the contract).
NODE_SIM: str = "evoscen_sim"
NODE_BV: str = "evoscen_bv"
NODE_SUT: str = "evoscen_sut"
NODE_EVAL: str = "evoscen_eval"

#: Frame of all world-fixed data (the OpenDRIVE inertial frame, x/y in m).
MAP_FRAME: str = "map"
TRUCK_MIN_LENGTH_M: float = 7.0
"""A vehicle longer than this is a truck ([choice] the class travels as the vehicle's length: highD's
trucks p5 7.1 m, its cars p95 6.2 m; docs/bv-profiles.md). Markers, animations, exports and the report's
count of trucks all use it."""
#: Child frame of the SUT odometry.
SUT_BASE_FRAME: str = "sut/base_link"

# --------------------------------------------------------------------------- topics

TOPIC_CLOCK: str = "/clock"
TOPIC_WORLD: str = "/evoscen/world"
TOPIC_COMMANDS_BV: str = "/evoscen/commands/bv"
TOPIC_COMMANDS_SUT: str = "/evoscen/commands/sut"
TOPIC_SUT_ODOM: str = "/evoscen/sut/odom"
TOPIC_EVENTS: str = "/evoscen/events"
TOPIC_ROSTER: str = "/evoscen/roster"
TOPIC_MARKERS: str = "/evoscen/markers"
TOPIC_MAP_MARKERS: str = "/evoscen/map_markers"



def bv_node_name(part: str) -> str:
    """The name of the BV node hosting partition ``part`` of the BVs (``bvs.nodes``;
    docs/architecture.md §5, "BV nodes"): ``evoscen_bv`` for the one node of ``single`` (part
    ``""``), ``evoscen_bv_<part>`` otherwise (``evoscen_bv_competitive``, ``evoscen_bv_0``)."""
    return NODE_BV if not part else f"{NODE_BV}_{part}"


def command_topic(node: str) -> str:
    """The command topic of controller ``node``: ``/evoscen/commands/`` + the node's name without
    ``evoscen_`` (``evoscen_sut`` -> ``/evoscen/commands/sut``, ``evoscen_bv_mutual`` ->
    ``/evoscen/commands/bv_mutual``): one topic per controller node, each with one publisher."""
    return "/evoscen/commands/" + node.removeprefix("evoscen_")


def is_bv_command_topic(topic: str) -> bool:
    """Whether ``topic`` is a BV node's command topic (``/evoscen/commands/bv`` or ``..._<part>``)."""
    return topic == TOPIC_COMMANDS_BV or topic.startswith(TOPIC_COMMANDS_BV + "_")


#: ROS 2 type name (``pkg/msg/Type``) of every topic, in the contract's order (docs/topics.md).
TOPIC_TYPES: dict[str, str] = {
    TOPIC_CLOCK: "rosgraph_msgs/msg/Clock",
    TOPIC_WORLD: "sensor_msgs/msg/PointCloud2",
    TOPIC_COMMANDS_BV: "sensor_msgs/msg/PointCloud2",
    TOPIC_COMMANDS_SUT: "sensor_msgs/msg/PointCloud2",
    TOPIC_SUT_ODOM: "nav_msgs/msg/Odometry",
    TOPIC_EVENTS: "diagnostic_msgs/msg/DiagnosticArray",
    TOPIC_ROSTER: "sensor_msgs/msg/PointCloud2",
    TOPIC_MARKERS: "visualization_msgs/msg/MarkerArray",
    TOPIC_MAP_MARKERS: "visualization_msgs/msg/MarkerArray",
}

# --------------------------------------------------------------------------- codes

#: ``role`` column values.
ROLE_BV: int = 0
ROLE_SUT: int = 1

#: ``policy`` column values (driver model of each vehicle).
POLICY_CODES: dict[str, int] = {
    "level0": 0,
    "mutual": 1,
    "competitive": 2,
    "cooperative": 3,
    "sut": 4,
    "nilsson": 5,
    "mobil": 6,
}
#: Inverse of :data:`POLICY_CODES`.
POLICY_NAMES: dict[int, str] = {code: name for name, code in POLICY_CODES.items()}
#: The learned BVs' social types (policy names of the ``bvs.mix`` split), in code order.
SOCIAL_POLICIES: tuple[str, ...] = ("mutual", "competitive", "cooperative")

# --------------------------------------------------------------------------- tables

#: ``sensor_msgs/msg/PointField.FLOAT64``: the datatype of every table column.
FLOAT64: int = 8
#: Bytes per table cell (one float64).
CELL_BYTES: int = 8

#: Columns of ``/evoscen/world`` (one row per vehicle, float64).
WORLD_FIELDS: tuple[str, ...] = (
    "id", "role", "policy", "x", "y", "yaw", "s", "d", "heading_rel", "speed", "accel",
    "steer", "lane", "target_lane", "lane_change", "length", "width",
)  # fmt: skip

#: Columns of ``/evoscen/commands/bv`` and ``/evoscen/commands/sut``.
COMMAND_FIELDS: tuple[str, ...] = ("id", "throttle", "lane_change")

#: Columns of ``/evoscen/roster``.
ROSTER_FIELDS: tuple[str, ...] = ("id", "role", "policy", "length", "width")

#: Meaning and unit of every table column (rendered in docs/topics.md).
FIELD_DOCS: dict[str, str] = {
    "id": "vehicle id (integer valued), unique in a scenario",
    "role": f"{ROLE_BV} = background vehicle (BV), {ROLE_SUT} = system under test (SUT)",
    "policy": "driver model code: " + ", ".join(f"{c} = {n}" for n, c in POLICY_CODES.items()),
    "x": "position x in the map frame (m), vehicle reference point",
    "y": "position y in the map frame (m)",
    "yaw": "heading in the map frame (rad, counter-clockwise from +x)",
    "s": "arc length along the OpenDRIVE reference line (m)",
    "d": "lateral offset from the reference line (m, positive to the left)",
    "heading_rel": "heading relative to the road direction at s (rad, positive to the left)",
    "speed": "longitudinal speed (m/s)",
    "accel": "longitudinal acceleration (m/s^2)",
    "steer": "front-wheel steering angle (rad, positive to the left)",
    "lane": (
        "current lane index (0 = lane I, the merge lane ... 4 = lane V); a vehicle whose centre "
        "leaves the road keeps its last lane (see the evoscen/off_road event)"
    ),
    "target_lane": "lane index the vehicle is heading for (= lane when keeping lane)",
    "lane_change": (
        "world table: lane change in progress (-1 right, 0 none, +1 left); command tables: the "
        "requested lane change (the world executes it only if the target lane exists and no change "
        "is in progress)"
    ),
    "length": "vehicle length (m)",
    "width": "vehicle width (m)",
    "throttle": (
        "normalized longitudinal command in [-1, 1] (dimensionless; +1 full throttle, "
        "-1 full brake; scaling owned by evoscen_sim)"
    ),
}

# --------------------------------------------------------------------------- time

_NS_PER_S: int = 1_000_000_000
_INT32_MIN: int = -(2**31)
_INT32_MAX: int = 2**31 - 1


def stamp_parts(ns: int) -> tuple[int, int]:
    """Return ``(sec, nanosec)`` of ``builtin_interfaces/msg/Time`` for a time in integer nanoseconds.

    ``sec = ns // 1e9``, ``nanosec = ns % 1e9`` (floor division, so ``nanosec`` is
    always in ``[0, 1e9)`` as ROS requires, also for negative times).

    Raises:
        ValueError: ``ns`` is not an integer or ``sec`` does not fit int32.
    """
    ns_int = int(ns)
    if ns_int != ns:
        raise ValueError(f"stamp_from_ns: time {ns!r} ns is not an integer number of nanoseconds")
    sec, nanosec = divmod(ns_int, _NS_PER_S)
    if not _INT32_MIN <= sec <= _INT32_MAX:
        raise ValueError(f"stamp_from_ns: time {ns_int} ns is outside the int32 seconds range")
    return sec, nanosec


# --------------------------------------------------------------------------- events

EVENT_COLLISION: str = "evoscen/collision"
EVENT_LANE_CHANGE: str = "evoscen/lane_change"
EVENT_REENTRY: str = "evoscen/reentry"
EVENT_FAULT: str = "evoscen/fault"
EVENT_OFF_ROAD: str = "evoscen/off_road"
EVENT_RUN_END: str = "evoscen/run_end"
EVENT_EXPOSURE: str = "evoscen/exposure"
EVENT_SHIFT: str = "evoscen/shift"
EVENT_CHALLENGE: str = "evoscen/challenge"
#: All event names allowed on ``/evoscen/events``.
EVENT_NAMES: tuple[str, ...] = (
    EVENT_COLLISION, EVENT_LANE_CHANGE, EVENT_REENTRY, EVENT_OFF_ROAD, EVENT_FAULT, EVENT_RUN_END,
    EVENT_EXPOSURE, EVENT_SHIFT, EVENT_CHALLENGE,
)

#: Values of the ``kind`` key (see :data:`EVENT_KINDS`).
KIND_COMPLETED: str = "completed"
KIND_ABORTED: str = "aborted"
KIND_INTERRUPTED: str = "interrupted"
KIND_DEADLINE: str = "deadline"
KIND_ABORT: str = "abort"
KIND_START: str = "start"
KIND_END: str = "end"
#: The ``kind`` values of each event that has one: a fault is a missed ``deadline`` (command
#: held) or the ``abort`` of the run; a lane change ``completed`` or ``aborted`` (its target
#: lane ended); a run ``completed``, ``aborted`` (a fault) or ``interrupted`` (SIGINT); an
#: exposure ``start`` or ``end``; a challenge ``start`` (a tilted draw happened: the SUT's leader
#: brakes hard) or ``end`` (the run's likelihood ratio, once, before ``run_end``).
EVENT_KINDS: dict[str, tuple[str, ...]] = {
    EVENT_FAULT: (KIND_DEADLINE, KIND_ABORT),
    EVENT_LANE_CHANGE: (KIND_COMPLETED, KIND_ABORTED),
    EVENT_RUN_END: (KIND_COMPLETED, KIND_ABORTED, KIND_INTERRUPTED),
    EVENT_EXPOSURE: (KIND_START, KIND_END),
    EVENT_CHALLENGE: (KIND_START, KIND_END),
}

#: ``diagnostic_msgs/DiagnosticStatus`` levels (OK, WARN, ERROR, STALE).
LEVEL_OK, LEVEL_WARN, LEVEL_ERROR, LEVEL_STALE = 0, 1, 2, 3
#: Level used when an event dict gives none.
DEFAULT_EVENT_LEVELS: dict[str, int] = {
    EVENT_COLLISION: LEVEL_ERROR,
    EVENT_LANE_CHANGE: LEVEL_OK,
    EVENT_REENTRY: LEVEL_WARN,
    EVENT_OFF_ROAD: LEVEL_ERROR,
    EVENT_FAULT: LEVEL_ERROR,
    EVENT_RUN_END: LEVEL_OK,
    EVENT_EXPOSURE: LEVEL_WARN,
    EVENT_SHIFT: LEVEL_OK,
    EVENT_CHALLENGE: LEVEL_OK,
}
#: ``hardware_id`` of every event status.
EVENT_HARDWARE_ID: str = "evoscen"

#: Typed event keys: values are encoded to / decoded from KeyValue strings by type.
#: ``"int"`` -> ``str(int)``; ``"float"`` -> ``repr(float)`` (exact round trip, also
#: ``inf``/``nan``); ``"ints"`` -> comma separated ints (``"3,7"``, ``""`` = empty);
#: ``"str"`` -> as is. Keys not listed here are written with ``str(value)`` and read back
#: as strings.
EVENT_KEY_TYPES: dict[str, str] = {
    "step": "int",  # step index k
    "time_s": "float",  # simulation time of the event (s)
    "ids": "ints",  # vehicle ids involved
    "duration_s": "float",  # duration (s), e.g. of a lane change or an off-road episode
    "direction": "int",  # lane-change direction (+1 left, -1 right)
    "from_lane": "int",  # lane index before
    "to_lane": "int",  # lane index after
    "misses": "int",  # consecutive missed controller deadlines (fault)
    "controller": "str",  # node name of the controller concerned (fault)
    "kind": "str",  # sub-kind: EVENT_KINDS
    "steps": "int",  # steps simulated (run_end); states an exposure lasted (exposure end)
    "ttc_s": "float",  # the SUT's time to collision with the vehicle ahead in its path (exposure start; inf if none)
    "accel_mps2": "float",  # the SUT's acceleration (exposure start)
    "shift_m": "float",  # distance every vehicle was moved back along the road (shift; docs/method.md §1)
    "multiplier": "float",  # challenge start: q/p, how much likelier the tilted draw made the onset there
    "log_weight": "float",  # challenge: log of the likelihood ratio p/q (start: this onset's; end: the run's)
    "distance_m": "float",  # challenge end: distance the SUT's leaders drove under the onset process (m)
}

# --------------------------------------------------------------------------- exit statuses

#: Exit statuses (docs/recording.md). Every node and the graph launcher end with one of
#: them, never a raw signal number: 0 completed, 2 bad input (one line ``error: ...`` on
#: stderr), 3 a controller fault (the simulation node aborted the run), 4 a node died or
#: ended before the run did (the launcher only; named on stderr), 5 a fault of the host: an
#: output could not be written (disk full, output directory read-only or gone; one line naming
#: the file, the cause and what to do), 130 interrupted.
EXIT_OK: int = 0
EXIT_BAD_INPUT: int = 2
EXIT_FAULT: int = 3
EXIT_NODE_DIED: int = 4
EXIT_HOST_FAULT: int = 5
EXIT_INTERRUPTED: int = 130
#: Statuses with which a node ends by itself; anything else (a signal, 1) is a death.
NODE_EXIT_STATUSES: tuple[int, ...] = (EXIT_OK, EXIT_BAD_INPUT, EXIT_FAULT, EXIT_HOST_FAULT, EXIT_INTERRUPTED)
#: Statuses of the graph launcher (``scripts/run_scenario.py --mode graph``).
GRAPH_EXIT_STATUSES: tuple[int, ...] = (EXIT_OK, EXIT_BAD_INPUT, EXIT_FAULT, EXIT_NODE_DIED, EXIT_HOST_FAULT,
                                         EXIT_INTERRUPTED)
