"""ROS_DOMAIN_ID reservation: no two evoscen graphs on one host share a domain.

Graphs started at the same moment (a test module, a campaign, two users) used to draw their
domains independently at random in 1..100; two equal draws put two simulations on one domain,
and both aborted at start-up ("already has 1 other publisher of /evoscen/world"). Seen in CI:
three graphs at once, about a 3 % chance per run.

:func:`reserve_domain` holds an exclusive ``flock`` on ``<lock dir>/domain-<N>.lock`` for as long
as the graph runs (the kernel drops it when the process ends, however it ends, so a crashed
launcher never leaves a domain reserved). Without an explicit domain it tries the domains of
1..100 in a random order (drawn from the OS: the domain is not part of the scenario, so not
from its seed) and takes the first free one; an explicit domain held by another graph is an
error. Only graphs on this host are seen (the lock directory is per host, as is LOCALHOST
discovery); the simulation node's start-up check (no other publisher of ``/evoscen/world``)
still catches everything else: a replay, a graph of an older version, another machine on SUBNET.
See docs/architecture.md (node graph).

A caller that starts nodes of its own on the domain before the graph (a user's observer, a test's
intruder or probe) reserves the domain first and then hands it to the launcher with
``--domain-id N`` and ``EVOSCEN_DOMAIN_RESERVED=N`` in the launcher's environment
(:func:`reserved_by_caller_env`): the launcher then trusts that reservation instead of failing
on the lock its caller holds. Drawing such a domain at random without a reservation is what
put two of a test module's graphs on one domain (seen in CI: 101..232, two graphs at once).

Lock directory: ``$EVOSCEN_DOMAIN_LOCK_DIR`` or ``<tmp>/evoscen-domains`` (mode 1777, lock files
0666, so graphs of different users on one host see each other's reservations).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import random
import sys
from collections.abc import Iterator
from pathlib import Path

from evoscen_contract.host_locks import lock_dir, open_lock_file
from evoscen_sim.errors import InputError

AUTO_DOMAINS = range(1, 101)
"""Where an automatic domain is drawn from (explicit ones may be 0..232)."""

RESERVED_ENV = "EVOSCEN_DOMAIN_RESERVED"
"""Environment variable: the domain the launcher's caller has reserved for it (see module doc)."""
DISCOVERY_RANGES = ("LOCALHOST", "SUBNET", "SYSTEM_DEFAULT")
"""The ROS_AUTOMATIC_DISCOVERY_RANGE a graph may run with (LOCALHOST unless asked: the domain is per host)."""


def reserved_by_caller_env(domain: int) -> dict[str, str]:
    """Environment entries for a process that joins ``domain``, reserved by this process."""
    return {"ROS_DOMAIN_ID": str(domain), RESERVED_ENV: str(domain)}


def _try_lock(directory: Path, domain: int) -> int | None:
    """An fd holding the exclusive lock of ``domain``, or None if another process holds it."""
    fd = open_lock_file(directory / f"domain-{domain}.lock")
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        os.close(fd)
        if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN):
            return None
        raise
    return fd


@contextlib.contextmanager
def reserve_domain(domain_id: int | None, rng: random.Random | None = None) -> Iterator[int]:
    """Reserve ``domain_id`` (or a free one of :data:`AUTO_DOMAINS` if None) for the ``with`` block.

    Raises :class:`InputError` if the explicit domain, or every automatic one, is held by another
    evoscen graph on this host. If the lock directory cannot be used (read-only ``/tmp``), says so
    in one line on stderr and goes on without a reservation (the start-up check remains).
    An explicit domain equal to ``$EVOSCEN_DOMAIN_RESERVED`` is taken as reserved by the caller.
    """
    if domain_id is not None and os.environ.get(RESERVED_ENV, "").strip() == str(domain_id):
        yield domain_id  # the caller holds the lock for us (reserved_by_caller_env)
        return
    try:
        directory = lock_dir()
        candidates = [domain_id] if domain_id is not None else list(AUTO_DOMAINS)
        if domain_id is None:
            (rng or random.SystemRandom()).shuffle(candidates)
        fd, chosen = None, None
        for candidate in candidates:
            fd = _try_lock(directory, candidate)
            if fd is not None:
                chosen = candidate
                break
    except OSError as exc:
        chosen = domain_id if domain_id is not None else (rng or random.SystemRandom()).choice(AUTO_DOMAINS)
        print(f"warning: ROS_DOMAIN_ID {chosen} not reserved: the lock directory is not usable ({exc}); "
              "set EVOSCEN_DOMAIN_LOCK_DIR to a writable directory", file=sys.stderr)
        yield chosen
        return
    if chosen is None:
        if domain_id is not None:
            raise InputError(f"--domain-id {domain_id}: another evoscen graph on this host runs on ROS_DOMAIN_ID "
                             f"{domain_id} (lock {directory / f'domain-{domain_id}.lock'}); choose another domain "
                             "or leave --domain-id out")
        raise InputError(f"no free ROS_DOMAIN_ID in {AUTO_DOMAINS.start}..{AUTO_DOMAINS.stop - 1}: every one is "
                         f"reserved by another evoscen graph on this host (locks in {directory})")
    try:
        yield chosen
    finally:
        os.close(fd)
