#!/usr/bin/env python3
"""Replay a recorded rosbag2 (MCAP) bag on the ROS 2 wire.

    python scripts/replay.py BAG [--rate R] [--loop] [--topics T ...] [--domain-id N]
                             [--discovery-range LOCALHOST|SUBNET|SYSTEM_DEFAULT]
                             [--start-delay S] [--wait-subscribers N] [--wait-timeout S]

One publisher per topic, with the topic's recorded type and its ORIGINAL QoS (the
channel's ``offered_qos_profiles``); the recorded CDR bytes are published as they are
(no deserialization), in log-time order, paced in simulation time by ``--rate`` (1 = real
time, 0 = as fast as possible). ``/clock`` is replayed like any other topic, so
``use_sim_time`` nodes follow the bag. ``--wait-subscribers N`` holds the first message
until every publisher has N matched subscriptions; at the end the tool stays until every
reliable subscriber has acknowledged every message. Discovery is local
(``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``) unless ``--discovery-range`` says otherwise.

Exit status: 0 done (a ``warning:`` line names the topics no subscriber matched while their
messages went out, if some had none); 1 nobody received the messages: no subscribers within
``--wait-timeout``, or no subscriber matched on any topic during the replay (one ``error:`` line;
[choice] a replay that reached nobody is a failure a script must see, docs/architecture.md §7);
2 bad input (one line ``error: ...`` naming the bag/argument); 130 Ctrl-C (143 SIGTERM).
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import time
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_OK

DISCOVERY_RANGES = ("LOCALHOST", "SUBNET", "SYSTEM_DEFAULT")
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


class Interrupted(BaseException):
    """SIGINT / SIGTERM arrived (exit status 128 + signum).

    A BaseException, like KeyboardInterrupt, so that no ``except Exception`` on the way (the
    bag reader turns any exception into "corrupt MCAP data") can swallow it.
    """

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="replay.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("bag", type=Path, help="bag directory (metadata.yaml + .mcap) or the .mcap file")
    ap.add_argument("--rate", default="1.0",
                    help="simulated seconds per wall-clock second: 1 = real time (default), 0 = as fast as possible")
    ap.add_argument("--loop", action="store_true", help="replay again and again until Ctrl-C")
    ap.add_argument("--topics", nargs="+", metavar="T", help="replay only these topics (default: all)")
    ap.add_argument("--domain-id", help="ROS_DOMAIN_ID (default: the environment's, else 0)")
    ap.add_argument("--discovery-range", default="LOCALHOST", choices=DISCOVERY_RANGES,
                    help="ROS_AUTOMATIC_DISCOVERY_RANGE (default LOCALHOST; SUBNET reaches other machines)")
    ap.add_argument("--start-delay", default="0", metavar="S", help="seconds to wait before the first message")
    ap.add_argument("--wait-subscribers", default="0", metavar="N",
                    help="start only when every publisher has N matched subscriptions (default 0)")
    ap.add_argument("--wait-timeout", default="30", metavar="S",
                    help="give up waiting for subscribers after S s (exit 1), and for acknowledgements at the "
                         "end after S s (warning) (default 30)")
    return ap.parse_args(argv)


def validate(args: argparse.Namespace):
    """Check every argument and the bag before the middleware starts; InputError otherwise."""
    from evoscen_eval.scenes.replay import (
        CDR,
        parse_rate,
        parse_seconds,
        read_bag_topics,
        select_topics,
    )
    from evoscen_sim.limits import parse_cli_int
    from evoscen_sim.errors import InputError

    rate = parse_rate(args.rate)
    if args.domain_id is not None:
        args.domain_id = parse_cli_int("--domain-id", args.domain_id, 0, 232)
    args.wait_subscribers = parse_cli_int("--wait-subscribers", args.wait_subscribers, 0, 1_000_000)
    start_delay = parse_seconds("--start-delay", args.start_delay)
    wait_timeout = parse_seconds("--wait-timeout", args.wait_timeout)
    if args.domain_id is not None and not 0 <= args.domain_id <= 232:
        raise InputError(f"--domain-id {args.domain_id}: expected an integer in [0, 232]")
    if args.wait_subscribers < 0:
        raise InputError(f"--wait-subscribers {args.wait_subscribers}: expected an integer >= 0")
    topics = select_topics(read_bag_topics(args.bag), args.topics, bag=f"bag {str(args.bag)!r}")
    if not topics:
        raise InputError(f"bag {str(args.bag)!r}: has no topics to replay")
    from evoscen_contract.topics import TOPICS

    for t in topics:
        if t.encoding != CDR:
            raise InputError(f"bag {str(args.bag)!r}: topic {t.name!r} ({t.type_name}) is encoded as "
                             f"{t.encoding!r}, only {CDR!r} can be published; leave it out with --topics")
        spec = TOPICS.get(t.name)
        if spec is not None and t.type_name != spec.type_name:
            raise InputError(f"bag {str(args.bag)!r}: topic {t.name!r} is recorded as {t.type_name!r}; the evoscen "
                             f"contract says {spec.type_name!r}: not replayed (leave it out with --topics)")
    return rate, start_delay, wait_timeout, topics


def message_classes(topics, bag: Path) -> dict[str, type]:
    """Import the message class of every topic; InputError naming topic and type if one is missing."""
    import importlib

    from evoscen_eval.scenes.replay import message_class_path
    from evoscen_sim.errors import InputError

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
    from evoscen_sim.errors import InputError
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


def set_ros_environment(args: argparse.Namespace) -> tuple[str, Path | None]:
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
    if args.domain_id is not None:
        os.environ["ROS_DOMAIN_ID"] = str(args.domain_id)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = args.discovery_range
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
    topic while its messages went out: one ``error:`` line, status 1;
    some topics without one: a ``warning:`` line naming them, status 0."""
    deaf = [t for t in used if t not in heard]
    if used and len(deaf) == len(used):
        print(f"error: no subscriber matched any of the {len(used)} topics while they were replayed: the {sent} "
              "messages reached nobody; start the receiving node first (same ROS_DOMAIN_ID and discovery range) "
              "or pass --wait-subscribers 1", file=sys.stderr)
        return 1  # nobody received the messages (the module docstring)
    if deaf:
        print(f"warning: no subscriber matched {', '.join(deaf)} while they were replayed: their messages reached "
              "nobody", file=sys.stderr)
    return EXIT_OK


def replay(args: argparse.Namespace, rate: float, start_delay: float, wait_timeout: float, topics) -> int:
    """Publish the bag (see the module docstring); returns the exit status."""
    from evoscen_contract.graph import init, make_node, shutdown
    from evoscen_eval.scenes.replay import Pacer, iter_replay
    from rclpy.duration import Duration

    classes = message_classes(topics, args.bag)
    check_first_messages(args.bag, topics, classes)
    domain, profile = set_ros_environment(args)
    node = None
    sent = 0
    passes = 0
    t_first = t_last = None
    wall0 = None
    try:
        init([])
        node = make_node("evoscen_replay")
        pubs = {t.name: node.create_publisher(classes[t.name], t.name, t.qos.to_rclpy()) for t in topics}
        print(f"replay: {args.bag} ({len(topics)} topic{'s' if len(topics) != 1 else ''}: {', '.join(pubs)}) on ROS_DOMAIN_ID={domain}, "
              f"discovery {args.discovery_range}, rate {'max' if rate == 0 else f'{rate:g}'}"
              f"{', loop' if args.loop else ''}", file=sys.stderr, flush=True)
        if args.wait_subscribers > 0:
            short = wait_for_subscribers(pubs, args.wait_subscribers, wait_timeout)
            if short:
                print(f"error: --wait-subscribers {args.wait_subscribers}: after {wait_timeout:g} s (--wait-timeout) "
                      f"fewer subscribers on {', '.join(short)}", file=sys.stderr)
                return 1  # nobody received the messages (the module docstring)
        if start_delay > 0:
            time.sleep(start_delay)
        pacer = Pacer(rate)
        heard: set[str] = set()  # topics that had a matched subscriber when one of their messages went out
        used: set[str] = set()  # topics with messages
        wall0 = time.monotonic()
        names = list(pubs)
        while True:
            pacer.restart()
            for topic, log_time, data in iter_replay(args.bag, names):
                pacer.wait(log_time)
                if topic not in heard and pubs[topic].get_subscription_count() > 0:
                    heard.add(topic)  # a matched subscriber when a message went out: it was received
                publish(pubs[topic], data, wait_timeout)
                sent += 1
                used.add(topic)
                t_first = log_time if t_first is None else min(t_first, log_time)
                t_last = log_time if t_last is None else max(t_last, log_time)
            passes += 1
            if not args.loop:
                break
        wall = time.monotonic() - wall0
        for name, pub in pubs.items():
            if not pub.wait_for_all_acked(Duration(nanoseconds=int(wait_timeout * 1e9))):
                print(f"warning: {name}: not every subscriber acknowledged every message within {wait_timeout:g} s",
                      file=sys.stderr)
        sim = (t_last - t_first) * 1e-9 if sent else 0.0
        print(f"replayed: {sent} messages on {len(topics)} topic{'s' if len(topics) != 1 else ''}, {passes} pass{'es' if passes != 1 else ''}, "
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


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)

    def on_signal(signum, frame):
        raise Interrupted(signum)

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    from evoscen_sim.errors import InputError

    try:
        rate, start_delay, wait_timeout, topics = validate(args)
        return replay(args, rate, start_delay, wait_timeout, topics)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except Interrupted as exc:
        return 128 + exc.signum


if __name__ == "__main__":
    sys.exit(main())
