"""A recorded bag replayed on the ROS 2 wire: ``scripts/replay.py``'s work, the part that needs rclpy
(docs/architecture.md §7; the bag side, without ROS, is :mod:`evoscen_eval.scenes.replay`).

:func:`replay_command` checks every argument and the bag before the middleware starts
(:func:`validate`, one-line :class:`~evoscen_sim.errors.InputError`), makes sure every topic's message
class is installed and decodes the topic's first message, then publishes the recorded CDR bytes with
one publisher per topic (its recorded type and ORIGINAL QoS), in log-time order, paced in simulation
time; at the end it waits for every reliable subscriber's acknowledgements and says which topics
reached nobody (:func:`unheard_status`). SIGINT / SIGTERM end it with 128 + the signal's number.
"""

from __future__ import annotations

import os
import signal
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from evoscen_contract.contract import EXIT_OK
from evoscen_sim.errors import InputError

DISCOVERY_RANGES = ("LOCALHOST", "SUBNET", "SYSTEM_DEFAULT")
"""``--discovery-range``: the ROS_AUTOMATIC_DISCOVERY_RANGE of the replay."""
#: Fast DDS profile of the replay's writers: a 100 ms heartbeat (Fast DDS default 3 s), so that a
#: sample lost before the reader matched is repaired, and the final acknowledgements arrive, within
#: ~0.1 s instead of up to 3 s. Used only when the user has no Fast DDS profile file of their own.
FASTDDS_PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<dds xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <profiles>
    <data_writer profile_name="evoscen_replay_writer" is_default_profile="true">
      <times><heartbeatPeriod><sec>0</sec><nanosec>100000000</nanosec></heartbeatPeriod></times>
    </data_writer>
  </profiles>
</dds>
"""
PROFILE_VARS = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")
#: Seconds between retries of a publish the middleware refused (writer history full).
PUBLISH_RETRY_S = 0.005
NOBODY_RECEIVED = 1
"""The exit status of a replay that reached nobody: no subscribers within the wait, or no subscriber
matched on any topic while it was replayed ([choice] a failure a script must see, docs/architecture.md §7)."""


class Interrupted(BaseException):
    """SIGINT / SIGTERM arrived (exit status 128 + signum).

    A BaseException, like KeyboardInterrupt, so that no ``except Exception`` on the way (the
    bag reader turns any exception into "corrupt MCAP data") can swallow it.
    """

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


@dataclass
class ReplayPlan:
    """What :func:`validate` checked: the bag, its topics to replay and how."""

    bag: Path
    topics: list
    """The :class:`~evoscen_eval.scenes.replay.BagTopic` of every topic replayed."""
    rate: float
    loop: bool
    domain_id: int | None
    discovery_range: str
    start_delay: float
    wait_subscribers: int
    wait_timeout: float


def validate(bag: Path, *, rate: str, loop: bool = False, topics: list[str] | None = None, domain_id: str | None = None,
             discovery_range: str = "LOCALHOST", start_delay: str = "0", wait_subscribers: str = "0",
             wait_timeout: str = "30") -> ReplayPlan:
    """Check every argument (as the command line gives them: text) and the bag before the middleware
    starts; InputError otherwise."""
    from evoscen_contract.topics import TOPICS
    from evoscen_eval.scenes.replay import CDR, parse_rate, parse_seconds, read_bag_topics, select_topics
    from evoscen_sim.limits import parse_cli_int

    plan = ReplayPlan(bag=bag, topics=[], rate=parse_rate(rate), loop=loop,
                      domain_id=parse_cli_int("--domain-id", domain_id, 0, 232) if domain_id is not None else None,
                      discovery_range=discovery_range, start_delay=0.0,
                      wait_subscribers=parse_cli_int("--wait-subscribers", wait_subscribers, 0, 1_000_000),
                      wait_timeout=0.0)
    plan.start_delay = parse_seconds("--start-delay", start_delay)
    plan.wait_timeout = parse_seconds("--wait-timeout", wait_timeout)
    plan.topics = select_topics(read_bag_topics(bag), topics, bag=f"bag {str(bag)!r}")
    if not plan.topics:
        raise InputError(f"bag {str(bag)!r}: has no topics to replay")
    for t in plan.topics:
        if t.encoding != CDR:
            raise InputError(f"bag {str(bag)!r}: topic {t.name!r} ({t.type_name}) is encoded as "
                             f"{t.encoding!r}, only {CDR!r} can be published; leave it out with --topics")
        spec = TOPICS.get(t.name)
        if spec is not None and t.type_name != spec.type_name:
            raise InputError(f"bag {str(bag)!r}: topic {t.name!r} is recorded as {t.type_name!r}; the evoscen "
                             f"contract says {spec.type_name!r}: not replayed (leave it out with --topics)")
    return plan


def message_classes(topics, bag: Path) -> dict[str, type]:
    """Import the message class of every topic; InputError naming topic and type if one is missing."""
    import importlib

    from evoscen_eval.scenes.replay import message_class_path

    out = {}
    for t in topics:
        try:
            module, cls = message_class_path(t.type_name)
        except InputError as exc:
            raise InputError(f"bag {str(bag)!r}: topic {t.name!r}: {exc}") from None
        try:
            out[t.name] = getattr(importlib.import_module(module), cls)
        except (ImportError, AttributeError):
            raise InputError(f"bag {str(bag)!r}: topic {t.name!r} has type {t.type_name!r}, which is not installed "
                             f"(no {module}.{cls}): source its package, or leave the topic out with --topics") from None
    return out


def check_first_messages(bag: Path, topics, classes: dict[str, type]) -> None:
    """Deserialize the first message of every topic with its class: InputError if one does not
    decode (a bag whose schema does not match its data), before anything is published."""
    from evoscen_eval.scenes.replay import iter_replay
    from rclpy.serialization import deserialize_message

    todo = {t.name for t in topics if t.message_count != 0}
    types = {t.name: t.type_name for t in topics}
    if not todo:
        return
    for topic, log_time, data in iter_replay(bag, sorted(todo)):
        if topic not in todo:
            continue
        try:
            deserialize_message(data, classes[topic])
        except Exception as exc:  # noqa: BLE001 - any failure: the bytes are not that type
            reason = " ".join(str(exc).split()) or type(exc).__name__
            raise InputError(f"bag {str(bag)!r}: topic {topic!r}: the message at t = {log_time} ns does not decode "
                             f"as its recorded type {types[topic]!r} ({reason})") from None
        todo.discard(topic)
        if not todo:
            return


def set_ros_environment(domain_id: int | None, discovery_range: str) -> tuple[str, Path | None]:
    """Domain, discovery and writer profile of this process (before rclpy.init).

    Returns the domain id used and the temporary Fast DDS profile file written (None if the
    user has one of their own); the caller removes it.
    """
    profile = None
    if not any(os.environ.get(var) for var in PROFILE_VARS):
        import tempfile

        fd, name = tempfile.mkstemp(prefix="evoscen_replay_", suffix=".xml")
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(FASTDDS_PROFILE)
        profile = Path(name)
        os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(profile)
    if domain_id is not None:
        os.environ["ROS_DOMAIN_ID"] = str(domain_id)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = discovery_range
    os.environ.pop("ROS_LOCALHOST_ONLY", None)  # deprecated in Jazzy; the discovery range decides
    os.environ.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    return os.environ.get("ROS_DOMAIN_ID", "0"), profile


def wait_for_subscribers(pubs: dict, n: int, timeout_s: float) -> list[str]:
    """Wait until every publisher has ``n`` matched subscriptions; the topics still short at the timeout."""
    deadline = time.monotonic() + timeout_s
    while True:
        short = [name for name, pub in pubs.items() if pub.get_subscription_count() < n]
        if not short or time.monotonic() >= deadline:
            return short
        time.sleep(0.01)


def publish(pub, data: bytes, deadline_s: float) -> None:
    """``pub.publish(data)``; retried while the middleware refuses it (a full keep-all history)."""
    from rclpy._rclpy_pybind11 import RCLError

    give_up = time.monotonic() + deadline_s
    while True:
        try:
            pub.publish(data)
            return
        except RCLError:
            if time.monotonic() >= give_up:
                raise
            time.sleep(PUBLISH_RETRY_S)


def unheard_status(used: list[str], heard: set[str], sent: int) -> int:
    """The exit status after the replay, saying what reached nobody: no subscriber matched on any
    topic while its messages went out: one ``error:`` line, status 1 (:data:`NOBODY_RECEIVED`);
    some topics without one: a ``warning:`` line naming them, status 0."""
    deaf = [t for t in used if t not in heard]
    if used and len(deaf) == len(used):
        print(f"error: no subscriber matched any of the {len(used)} topics while they were replayed: the {sent} "
              "messages reached nobody; start the receiving node first (same ROS_DOMAIN_ID and discovery range) "
              "or pass --wait-subscribers 1", file=sys.stderr)
        return NOBODY_RECEIVED
    if deaf:
        print(f"warning: no subscriber matched {', '.join(deaf)} while they were replayed: their messages reached "
              "nobody", file=sys.stderr)
    return EXIT_OK


def _plural(n: int, word: str, suffix: str = "s") -> str:
    return f"{n} {word}{suffix if n != 1 else ''}"


def replay(plan: ReplayPlan) -> int:
    """Publish the bag (see the module docstring); returns the exit status."""
    from evoscen_contract.graph import init, make_node, shutdown
    from evoscen_eval.scenes.replay import Pacer, iter_replay
    from rclpy.duration import Duration

    classes = message_classes(plan.topics, plan.bag)
    check_first_messages(plan.bag, plan.topics, classes)
    domain, profile = set_ros_environment(plan.domain_id, plan.discovery_range)
    node = None
    sent = passes = 0
    t_first = t_last = wall0 = None
    try:
        init([])
        node = make_node("evoscen_replay")
        pubs = {t.name: node.create_publisher(classes[t.name], t.name, t.qos.to_rclpy()) for t in plan.topics}
        print(f"replay: {plan.bag} ({_plural(len(plan.topics), 'topic')}: {', '.join(pubs)}) on ROS_DOMAIN_ID="
              f"{domain}, discovery {plan.discovery_range}, rate {'max' if plan.rate == 0 else f'{plan.rate:g}'}"
              f"{', loop' if plan.loop else ''}", file=sys.stderr, flush=True)
        if plan.wait_subscribers > 0:
            short = wait_for_subscribers(pubs, plan.wait_subscribers, plan.wait_timeout)
            if short:
                print(f"error: --wait-subscribers {plan.wait_subscribers}: after {plan.wait_timeout:g} s "
                      f"(--wait-timeout) fewer subscribers on {', '.join(short)}", file=sys.stderr)
                return NOBODY_RECEIVED
        if plan.start_delay > 0:
            time.sleep(plan.start_delay)
        pacer = Pacer(plan.rate)
        heard: set[str] = set()  # topics that had a matched subscriber when one of their messages went out
        used: set[str] = set()  # topics with messages
        wall0 = time.monotonic()
        names = list(pubs)
        while True:
            pacer.restart()
            for topic, log_time, data in iter_replay(plan.bag, names):
                pacer.wait(log_time)
                if topic not in heard and pubs[topic].get_subscription_count() > 0:
                    heard.add(topic)  # a matched subscriber when a message went out: it was received
                publish(pubs[topic], data, plan.wait_timeout)
                sent += 1
                used.add(topic)
                t_first = log_time if t_first is None else min(t_first, log_time)
                t_last = log_time if t_last is None else max(t_last, log_time)
            passes += 1
            if not plan.loop:
                break
        wall = time.monotonic() - wall0
        for name, pub in pubs.items():
            if not pub.wait_for_all_acked(Duration(nanoseconds=int(plan.wait_timeout * 1e9))):
                print(f"warning: {name}: not every subscriber acknowledged every message within "
                      f"{plan.wait_timeout:g} s", file=sys.stderr)
        sim = (t_last - t_first) * 1e-9 if sent else 0.0
        print(f"replayed: {sent} messages on {_plural(len(plan.topics), 'topic')}, {_plural(passes, 'pass', 'es')}, "
              f"simulated {sim:.3f} s, wall {wall:.3f} s", flush=True)
        return unheard_status(sorted(used), heard, sent)
    except Interrupted as exc:
        wall = time.monotonic() - wall0 if wall0 is not None else 0.0
        print(f"interrupted: {sent} messages sent, {passes} full passes, wall {wall:.3f} s", flush=True)
        return 128 + exc.signum
    finally:
        # ignore further signals while tearing down, so a second Ctrl-C cannot leave a traceback
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        if node is not None:
            node.destroy_node()
        shutdown()
        if profile is not None:
            profile.unlink(missing_ok=True)


def replay_command(bag: Path, **options) -> int:
    """``scripts/replay.py``: SIGINT and SIGTERM raise :class:`Interrupted` from here on; the arguments
    checked (:func:`validate`, ``options`` its keywords), then the replay; returns its exit status."""
    def on_signal(signum, frame):
        raise Interrupted(signum)

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    try:
        return replay(validate(bag, **options))
    except Interrupted as exc:
        return 128 + exc.signum
