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
