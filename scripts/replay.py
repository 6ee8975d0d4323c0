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
docs/architecture.md §7); 2 bad input (one line ``error: ...`` naming the bag/argument); 130 Ctrl-C
(143 SIGTERM). The work is :func:`evoscen_eval.scenes.replay_wire.replay_command`.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli
from evoscen_eval.scenes.replay_wire import DISCOVERY_RANGES


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = cli.parser("replay.py", __doc__)
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


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_eval.scenes.replay_wire import replay_command

    return cli.run(lambda: replay_command(
        args.bag, rate=args.rate, loop=args.loop, topics=args.topics, domain_id=args.domain_id,
        discovery_range=args.discovery_range, start_delay=args.start_delay, wait_subscribers=args.wait_subscribers,
        wait_timeout=args.wait_timeout))


if __name__ == "__main__":
    sys.exit(main())
