"""The JIT compiler used for the simulation's per-step kernels.

The hot path of a step (neighbourhood search, collision test, controller and vehicle
integration, car-following law) runs as a handful of numba-compiled kernels over numpy
arrays instead of dozens of small numpy calls: for the ~21 vehicles of a scenario numpy's
per-call overhead, not arithmetic, dominates. Kernels are compiled on first use and
cached on disk (next to the module, or in numba's user cache when that is read-only);
``fastmath`` stays off, so results are IEEE-exact and runs are reproducible to the bit.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numba

kernel = numba.njit(cache=True, nogil=True, fastmath=False)
"""Decorator for a compiled per-step kernel."""

elementwise = numba.vectorize(cache=True, nopython=True)
"""Decorator turning a scalar function into a compiled numpy ufunc (broadcasts like numpy)."""


IDENTITY_MEMO_SIZE = 256
""":func:`by_identity`'s memory: the last this many arguments."""


def by_identity(fn: Callable[[Any], Any]) -> Callable[[Any], Any]:
    """``fn`` of one immutable argument (a frozen parameter set, a named tuple), remembered by the identity of the
    argument (the last :data:`IDENTITY_MEMO_SIZE`; each entry holds it, so an id is not reused while its entry
    lives): a lookup without hashing the argument's fields, for what a model derives from its parameters every
    decision (docs/performance.md "Per-step work of the SUT drivers"). ``fn`` is called once per argument object."""
    memo: dict[int, tuple[Any, Any]] = {}

    def cached(arg: Any) -> Any:
        hit = memo.get(id(arg))
        if hit is not None and hit[0] is arg:
            return hit[1]
        out = fn(arg)
        if len(memo) >= IDENTITY_MEMO_SIZE:
            memo.clear()
        memo[id(arg)] = (arg, out)
        return out

    cached.__doc__, cached.__name__, cached.__qualname__ = fn.__doc__, fn.__name__, fn.__qualname__
    cached.__module__, cached.__wrapped__ = fn.__module__, fn  # type: ignore[attr-defined]
    return cached


@by_identity
def plain(named: tuple) -> tuple:
    """``named`` (a named tuple a kernel reads: the road's tables, a model's parameters) as a plain tuple, remembered
    by its identity (:func:`by_identity`). A compiled call takes a plain tuple of arrays and numbers in about 0.1 µs a
    field but works out a named tuple's type in Python, about 2 µs a call; so the per-step kernels take plain tuples
    and rebuild the named tuple inside (the same type, the same compiled code: docs/performance.md "Per-step work of
    the world and of the BV drivers"). For named tuples whose arrays are never changed after they are made."""
    return tuple(named)
