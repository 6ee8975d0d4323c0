"""rclpy plumbing shared by the evoscen nodes: node set-up, parameters, QoS, message pump.

Every evoscen node is an ordinary rclpy node, but none spins an executor: a lockstep
simulation waits for specific messages, and rclpy's executors cost ~10× more per message
than taking them directly. :class:`MessagePump` keeps one ``WaitSet`` over the node's
subscriptions and takes messages with ``take_message`` (``raw`` bytes or typed), in ~10 µs.
Consequences, documented in docs/architecture.md §4: the nodes' parameters are read once at start-up
(no parameter services, ``ros2 param`` does not reach them), and SIGINT is handled by
Python (``KeyboardInterrupt``) rather than by rclpy's signal handler.

Parameters. A node gets its parameters from a ROS 2 parameter file
(``node_name: ros__parameters: ...``) written by the launcher: the node's own settings at
the top level and the whole scenario configuration under ``scenario.`` (nested mappings,
i.e. dotted names ``scenario.bvs.count``). :func:`node_parameters` rebuilds the nested
mapping; ``evoscen_sim.nodes.node_params.scenario_from_node`` validates the scenario part like a
YAML file, and ``evoscen_sim.nodes.node_params.own_parameters`` the node's own parameters (a
dataclass per node) with the same validator, so a bad value is the same one-line error,
naming the parameter file (:func:`parameter_sources`), the parameter and what is allowed.
"""

from __future__ import annotations

import array
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import rclpy
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from .host_locks import participant_start_lock
from .topics import TopicSpec


class NodeParameterError(ValueError):
    """A node parameter is missing or invalid (the message names it)."""


FASTDDS_PROFILES = Path(__file__).with_name("fastdds_profiles.xml")
"""evoscen's Fast DDS settings (see the file's comment): the NACK-suppression timer of reliable
writers armed for 50 ms instead of firing for every sample sent."""


_init_args: list[str] = []
"""The arguments of the last :func:`init` (for :func:`parameter_sources`)."""


def init(args: list[str] | None = None) -> list[str]:
    """``rclpy.init`` without rclpy's signal handlers; returns the non-ROS arguments.

    Fast DDS reads :data:`FASTDDS_PROFILES` (through ``FASTRTPS_DEFAULT_PROFILES_FILE``, set
    here before the middleware starts) unless the environment names a profiles file already
    — then that file is the user's choice and is used as it is.
    """
    import os

    global _init_args
    os.environ.setdefault("FASTRTPS_DEFAULT_PROFILES_FILE", str(FASTDDS_PROFILES))
    _init_args = list(args if args is not None else sys.argv)
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    return rclpy.utilities.remove_ros_args(args=args if args is not None else sys.argv)


def make_node(name: str) -> Node:
    """A node that accepts every parameter of its parameter file (validated by us). Its DDS participant
    is created under the host's participant-start lock: one at a time on a host
    (:func:`evoscen_contract.host_locks.participant_start_lock`, docs/architecture.md §5)."""
    with participant_start_lock():
        return Node(
            name,
            allow_undeclared_parameters=True,
            automatically_declare_parameters_from_overrides=True,
            start_parameter_services=False,
            enable_rosout=False,
        )


def _plain(value: Any) -> Any:
    if isinstance(value, (array.array, tuple)):
        return list(value)
    return value


def node_parameters(node: Node) -> dict[str, Any]:
    """All parameters of ``node`` as a nested mapping (dotted names split)."""
    out: dict[str, Any] = {}
    for name, param in node.get_parameters_by_prefix("").items():
        parts = name.split(".")
        cursor = out
        for part in parts[:-1]:
            cursor = cursor.setdefault(part, {})
        cursor[parts[-1]] = _plain(param.value)
    return out


def parameter_sources(node_name: str, args: list[str] | None = None) -> tuple[list[str], set[str]]:
    """Where the node's parameters come from: the ``--params-file`` paths (in order; a later
    file overrides an earlier one) and the names set with ``-p name:=value`` (``-p``
    overrides the files), from the ROS arguments of ``args`` (default: those given to the
    last :func:`init`). Used to name the file (or ``command line``) in parameter errors."""
    if args is None:
        args = _init_args
    files: list[str] = []
    cli: set[str] = set()
    in_ros = False
    it = iter(args)
    for arg in it:
        if arg == "--ros-args":
            in_ros = True
        elif arg == "--":
            in_ros = False
        elif in_ros and arg == "--params-file":
            files.append(next(it, ""))
        elif in_ros and arg in ("-p", "--param"):
            name = next(it, "").split(":=", 1)[0]
            target, _, key = name.rpartition(":")
            if not target or target.lstrip("/") == node_name:
                cli.add(key)
    return [f for f in files if f], cli


def publisher(node: Node, spec: TopicSpec):
    """A publisher for a contract topic with the contract's QoS."""
    return node.create_publisher(spec.msg_class, spec.name, spec.qos_profile())


def subscription(node: Node, spec: TopicSpec, *, raw: bool = True):
    """A subscription for a contract topic with the contract's QoS (no callback: use a pump)."""
    return node.create_subscription(spec.msg_class, spec.name, lambda _msg: None, spec.qos_profile(), raw=raw)


class MessagePump:
    """Take messages from a fixed set of subscriptions without an executor."""

    def __init__(self, node: Node, subscriptions: Iterable[Any]) -> None:
        self.subscriptions = list(subscriptions)
        self._wait_set = _rclpy.WaitSet(len(self.subscriptions), 0, 0, 0, 0, 0, node.context.handle)

    @staticmethod
    def take(sub) -> Any:
        """The next message of ``sub`` (bytes for a raw subscription), or None."""
        got = sub.handle.take_message(sub.msg_type, sub.raw)
        return None if got is None else got[0]

    def wait(self, timeout_s: float) -> None:
        """Block until a subscription has data or ``timeout_s`` passes."""
        ws = self._wait_set
        ws.clear_entities()
        for sub in self.subscriptions:
            ws.add_subscription(sub.handle)
        ws.wait(max(0, int(timeout_s * 1e9)))


def shutdown() -> None:
    """``rclpy.shutdown`` if the context is still up."""
    if rclpy.ok():
        rclpy.shutdown()


def exit_now(status: int) -> None:
    """End the process at once with ``status``, without tearing down the middleware.

    Fast DDS can busy-wait forever while destroying a participant under load (seen: a finished
    simulation node spinning in ``DomainParticipant::set_listener`` inside ``rmw_destroy_node``).
    Our nodes have finished their work by then — publications acknowledged
    (``wait_for_all_acked``), the bag closed — so nothing is lost by letting the OS clean up.
    """
    import os

    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)


def peers_missing(node: Node, topic: str, kind: str, matched: int, required: Iterable[str] = (),
                  at_least: int = 1) -> str | None:
    """Why ``topic`` is not ready yet (None when it is), for start-up waits.

    ``kind`` is ``"subscribers"`` (we publish: ``matched`` = the publisher's matched
    subscriptions) or ``"publishers"`` (we subscribe). Ready means: every ``required`` node
    has an endpoint on the topic, at least ``at_least`` endpoints exist, and every discovered
    endpoint is matched — counting alone is not enough, since a user's own node on the topic
    could stand in for a missing one of ours.
    """
    infos = (node.get_subscriptions_info_by_topic(topic) if kind == "subscribers"
             else node.get_publishers_info_by_topic(topic))
    names = {info.node_name for info in infos}
    lacking = [name for name in required if name not in names]
    if lacking:
        return f"{topic}: no {kind[:-1]} from {', '.join(lacking)}"
    if len(infos) < at_least:
        return f"{topic}: needs {at_least} {kind}, has {len(infos)}"
    if matched < len(infos):
        return f"{topic}: {len(infos) - matched} discovered {kind} not matched yet"
    return None


def duration(seconds: float):
    """An ``rclpy.duration.Duration`` of ``seconds``."""
    from rclpy.duration import Duration

    return Duration(nanoseconds=int(seconds * 1e9))


# --------------------------------------------------------------------------- message sources

GID_BYTES = 16
"""Bytes of a publisher GID compared (``RMW_GID_STORAGE_SIZE`` in Jazzy)."""
UNKNOWN_NODE = "_NODE_NAME_UNKNOWN_"
"""What the graph shows for an endpoint whose node is not (yet) known."""


class _Rcl:
    """``rcl_take_serialized_message`` through ctypes: rclpy (Jazzy) hands a raw subscription the
    bytes, the timestamps and sequence numbers of a message, but not its ``publisher_gid``; rcl
    does (``rmw_message_info_t``). Loaded once; :attr:`error` says why not when it cannot be."""

    _instance = None

    def __init__(self) -> None:
        import ctypes

        self.ctypes = ctypes
        self.error = ""

        class Alloc(ctypes.Structure):
            _fields_ = [("allocate", ctypes.c_void_p), ("deallocate", ctypes.c_void_p),
                        ("reallocate", ctypes.c_void_p), ("zero_allocate", ctypes.c_void_p),
                        ("state", ctypes.c_void_p)]

        class U8Array(ctypes.Structure):
            _fields_ = [("buffer", ctypes.c_void_p), ("buffer_length", ctypes.c_size_t),
                        ("buffer_capacity", ctypes.c_size_t), ("allocator", Alloc)]

        class Gid(ctypes.Structure):
            _fields_ = [("implementation_identifier", ctypes.c_char_p), ("data", ctypes.c_uint8 * GID_BYTES)]

        class Info(ctypes.Structure):
            _fields_ = [("source_timestamp", ctypes.c_int64), ("received_timestamp", ctypes.c_int64),
                        ("publication_sequence_number", ctypes.c_uint64),
                        ("reception_sequence_number", ctypes.c_uint64),
                        ("publisher_gid", Gid), ("from_intra_process", ctypes.c_bool)]

        self.U8Array, self.Info, self.Alloc = U8Array, Info, Alloc
        try:
            rcl = ctypes.CDLL("librcl.so")  # already loaded by rclpy: the same library
            rcutils = ctypes.CDLL("librcutils.so")
            rcutils.rcutils_get_default_allocator.restype = Alloc
            rcutils.rcutils_uint8_array_init.argtypes = [ctypes.POINTER(U8Array), ctypes.c_size_t,
                                                         ctypes.POINTER(Alloc)]
            rcl.rcl_take_serialized_message.argtypes = [ctypes.c_void_p, ctypes.POINTER(U8Array),
                                                        ctypes.POINTER(Info), ctypes.c_void_p]
            rcl.rcl_take_serialized_message.restype = ctypes.c_int32
            self.rcl, self.rcutils = rcl, rcutils
        except (OSError, AttributeError) as exc:
            self.error = f"rcl not reachable through ctypes ({exc})"

    @classmethod
    def get(cls) -> _Rcl:
        if cls._instance is None:
            cls._instance = cls()
        return cls._instance


RCL_RET_OK, RCL_RET_SUBSCRIPTION_TAKE_FAILED = 0, 401


class SourceTaker:
    """Takes the messages of one raw subscription together with their publisher's GID.

    :meth:`take` returns ``(bytes, gid)`` — ``gid`` the 16 bytes of the publishing endpoint,
    equal to ``TopicEndpointInfo.endpoint_gid`` of that publisher in the graph — or None when
    nothing is waiting. Where rcl cannot be reached through ctypes (:attr:`per_message` False)
    it falls back to rclpy's take with ``gid`` None; the callers then check publisher counts.
    """

    def __init__(self, sub) -> None:
        self.sub = sub
        rcl = _Rcl.get()
        self.per_message = not rcl.error
        self.why_not = rcl.error
        if self.per_message:
            self._rcl = rcl
            self._ptr = sub.handle.pointer
            self._msg = rcl.U8Array()
            self._info = rcl.Info()
            alloc = rcl.rcutils.rcutils_get_default_allocator()
            if rcl.rcutils.rcutils_uint8_array_init(rcl.ctypes.byref(self._msg), 1024, rcl.ctypes.byref(alloc)):
                self.per_message, self.why_not = False, "rcutils_uint8_array_init failed"

    def take(self) -> tuple[bytes, bytes | None] | None:
        if not self.per_message:
            data = MessagePump.take(self.sub)
            return None if data is None else (data, None)
        c = self._rcl.ctypes
        ret = self._rcl.rcl.rcl_take_serialized_message(self._ptr, c.byref(self._msg), c.byref(self._info), None)
        if ret == RCL_RET_SUBSCRIPTION_TAKE_FAILED:
            return None
        if ret != RCL_RET_OK:
            raise RuntimeError(f"rcl_take_serialized_message on {self.sub.topic_name}: rcl error {ret}")
        return c.string_at(self._msg.buffer, self._msg.buffer_length), bytes(self._info.publisher_gid.data)


def gid_text(gid: bytes | None) -> str:
    """A GID as rclpy prints endpoint GIDs (dotted hex), or ``unknown``."""
    return ".".join(f"{b:02x}" for b in gid) if gid is not None else "unknown"


def publisher_names(node: Node, topic: str) -> dict[bytes, str]:
    """``{publisher GID: node name}`` of every publisher of ``topic`` the graph knows now."""
    return {bytes(info.endpoint_gid[:GID_BYTES]): str(info.node_name)
            for info in node.get_publishers_info_by_topic(topic)}


class SourceGate:
    """Which publishers a subscriber trusts on each topic: those of the nodes the contract names.

    ``trusted``: ``{topic: node names}`` (None: any node but ``exclude``; the first such
    publisher is then pinned and no other is trusted — an external SUT node). A GID is looked
    up in the graph once (retried for up to ``resolve_s`` while its node name is not known yet,
    as happens just after discovery) and the verdict kept. ``resolve_s`` is 10 s: a node's name
    reaches the graph cache later than its endpoints; with 2 s, one graph test on a loaded machine
    (two cores, other suites in parallel) recorded "messages not recorded (untrusted)" and a bag that
    differed from the in-process one (a late name is the one cause known; not reproduced since). A
    publisher whose name never resolves costs this wait once.
    """

    def __init__(self, node: Node, trusted: Mapping[str, Iterable[str] | None], *,
                 exclude: Iterable[str] = (), resolve_s: float = 10.0) -> None:
        self.node = node
        self.trusted = {t: (None if names is None else frozenset(names)) for t, names in trusted.items()}
        self.exclude = frozenset(exclude)
        self.resolve_s = resolve_s
        self._verdicts: dict[tuple[str, bytes], bool] = {}
        self._pinned: dict[str, bytes] = {}
        self._names: dict[tuple[str, bytes], str] = {}

    def name_of(self, topic: str, gid: bytes | None) -> str:
        """The publisher as text: its GID and, when known, its node name."""
        name = self._names.get((topic, gid)) if gid is not None else None
        return gid_text(gid) + (f" (node '{name}')" if name and name != UNKNOWN_NODE else "")

    def allows(self, topic: str, gid: bytes | None) -> bool:
        """Whether a message of ``topic`` from ``gid`` is trusted (None: no per-message GID: yes)."""
        if gid is None or topic not in self.trusted:
            return True
        key = (topic, gid)
        verdict = self._verdicts.get(key)
        if verdict is None:
            import time

            end = time.monotonic() + self.resolve_s
            while True:
                name = publisher_names(self.node, topic).get(gid)
                if (name is not None and name != UNKNOWN_NODE) or time.monotonic() > end:
                    break
                time.sleep(0.01)
            self._names[key] = name or UNKNOWN_NODE
            names = self.trusted[topic]
            if names is None:
                ok = name is not None and name != UNKNOWN_NODE and name not in self.exclude
                if ok and topic in self._pinned:
                    ok = False
                if ok:
                    self._pinned[topic] = gid
            else:
                ok = name in names
            verdict = self._verdicts[key] = ok
        return verdict
