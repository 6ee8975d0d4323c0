"""The JIT compiler used for the simulation's per-step kernels.

The hot path of a step (neighbourhood search, collision test, controller and vehicle
integration, car-following law) runs as a handful of numba-compiled kernels over numpy
arrays instead of dozens of small numpy calls: for the ~21 vehicles of a scenario numpy's
per-call overhead, not arithmetic, dominates. Kernels are compiled on first use and
cached on disk (next to the module, or in numba's user cache when that is read-only);
``fastmath`` stays off, so results are IEEE-exact and runs are reproducible to the bit.
"""

from __future__ import annotations

import numba

kernel = numba.njit(cache=True, nogil=True, fastmath=False)
"""Decorator for a compiled per-step kernel."""

elementwise = numba.vectorize(cache=True, nopython=True)
"""Decorator turning a scalar function into a compiled numpy ufunc (broadcasts like numpy)."""


_PLAIN: dict[int, tuple[tuple, tuple]] = {}
_PLAIN_MAX = 256


def plain(named: tuple) -> tuple:
    """``named`` (a named tuple a kernel reads: the road's tables, a model's parameters) as a plain tuple,
    remembered by the identity of ``named`` (the last 256; each entry holds it, so an id is not reused
    while its entry lives). A compiled call takes a plain tuple of arrays and numbers in about 0.1 µs a
    field but works out a named tuple's type in Python, about 2 µs a call; so the per-step kernels take
    plain tuples and rebuild the named tuple inside (the same type, the same compiled code:
    docs/performance.md "Per-step work of the world and of the BV drivers"). For named tuples that are
    never changed after they are made (a named tuple cannot be; nor are the arrays these hold)."""
    hit = _PLAIN.get(id(named))
    if hit is not None and hit[0] is named:
        return hit[1]
    out = tuple(named)
    if len(_PLAIN) >= _PLAIN_MAX:
        _PLAIN.clear()
    _PLAIN[id(named)] = (named, out)
    return out
