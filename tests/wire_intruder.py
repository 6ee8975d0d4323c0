"""A hostile node for tests/test_wire.py: joins a run's domain and publishes what it should not.

    python tests/wire_intruder.py SECONDS

Node ``intruder``. For every world message it sees (stamp t_k) it publishes, on the contract's
own topics with the contract's QoS:

* ``/evoscen/commands/sut``: a well-formed SUT table stamped t_k (full brake) — from a foreign
  publisher, so it must not displace the real SUT's command;
* ``/evoscen/commands/bv``: in turn a table with id -1, a NaN throttle, the SUT's id, no rows,
  invalid UTF-8 in frame_id, a table cut short, 64 random bytes;
* ``/evoscen/world`` (from the first world message on): 64 random bytes and a table cut short
  (the controllers must survive);
* ``/evoscen/events``: forged SUT collision events and, every 10 steps, a forged ``run_end``.

It ends after SECONDS or when the world has had no publisher for a while. Prints how many
messages it sent.
"""

from __future__ import annotations

import sys
import time

import numpy as np


def main() -> int:
    seconds = float(sys.argv[1])
    from evoscen_contract import graph
    from evoscen_contract import topics as T
    from evoscen_contract.cdr import TableEncoder, decode_table
    from evoscen_contract.messages import WorldMessages

    graph.init(sys.argv)
    node = graph.make_node("intruder")
    # a second world publisher at start-up would make the simulation refuse the domain: it comes with step 0
    # every BV command topic of the default scenario (bvs.nodes: by_policy) and the single node's
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.nodes.bv_nodes import bv_node_names

    bv_specs = [T.COMMANDS_BV] + [T.bv_command_spec(n) for n in bv_node_names(load_scenario_config(None))]
    pubs = {spec.name: graph.publisher(node, spec) for spec in (T.COMMANDS_SUT, *bv_specs, T.EVENTS)}
    world_sub = graph.subscription(node, T.WORLD, raw=True)
    pump = graph.MessagePump(node, [world_sub])
    cmd = TableEncoder(T.COMMAND_FIELDS, "map")
    rng = np.random.default_rng(3)
    sent = 0
    start = time.monotonic()
    last_world = None
    k = 0
    while time.monotonic() - start < seconds:
        pump.wait(0.1)
        while (data := graph.MessagePump.take(world_sub)) is not None:
            try:
                t_ns = decode_table(data).stamp_ns
            except ValueError:
                continue
            last_world = time.monotonic()
            if T.WORLD.name not in pubs:
                pubs[T.WORLD.name] = graph.publisher(node, T.WORLD)
            good_bv = cmd.encode(np.column_stack([np.arange(1, 21), np.zeros(20), np.zeros(20)]), t_ns)
            variants = [
                cmd.encode(np.array([[-1.0, 1.0, 0.0]]), t_ns),
                cmd.encode(np.column_stack([np.arange(1, 21), np.full(20, np.nan), np.zeros(20)]), t_ns),
                cmd.encode(np.array([[0.0, -1.0, 0.0]]), t_ns),
                cmd.encode(np.zeros((0, 3)), t_ns),
                TableEncoder(T.COMMAND_FIELDS, "mXap").encode(np.zeros((1, 3)), t_ns).replace(b"mXap", b"m\xffap"),
                good_bv[: len(good_bv) // 2],
                rng.integers(0, 256, 64, dtype=np.uint8).tobytes(),
            ]
            pubs[T.COMMANDS_SUT.name].publish(cmd.encode(np.array([[0.0, -1.0, 0.0]]), t_ns))
            for j, spec in enumerate(bv_specs):
                pubs[spec.name].publish(variants[(k + j) % len(variants)])
            pubs[T.WORLD.name].publish(rng.integers(0, 256, 64, dtype=np.uint8).tobytes() if k % 2
                                       else data[: len(data) // 2])
            events = [{"name": T.EVENT_COLLISION, "step": k, "time_s": t_ns / 1e9, "ids": [0, 3],
                       "message": "forged"}]
            if k % 10 == 5:
                events.append({"name": T.EVENT_RUN_END, "kind": "completed", "steps": k, "message": "forged"})
            pubs[T.EVENTS.name].publish(WorldMessages(0.1).events(events, t_ns))
            sent += 4
            k += 1
        if last_world is not None and time.monotonic() - last_world > 3.0:
            break
    print(f"intruder: sent {sent} messages for {k} world messages")
    graph.exit_now(0)
    return 0


if __name__ == "__main__":
    sys.exit(main())
