"""KDE probability distributions on a common grid and their Jensen–Shannon similarity (docs/method.md §5.3).

* **KDE**: a Gaussian kernel density estimate as scipy's ``gaussian_kde`` builds it (kernel
  covariance = factor² × the sample covariance, full in 2-D). The bandwidth factor is
  ``bandwidth``: ``"scott"`` [default] ``n^(−1/(d+4))``, ``"silverman"``
  ``(n(d+2)/4)^(−1/(d+4))``, or a fixed number. **[choice]** In a comparison both KDEs use
  the factor of the SMALLER sample (:func:`shared_factor`): with each sample's own factor,
  a 1 M-row HighD set would be smoothed less than a 20 k-row run, and JS would measure the
  difference in smoothing, not in behaviour (a run against its own 25 Hz export differs
  by ~0.008 that way, by ~0.0002 with one factor). Evaluated on a
  regular grid by *binning*: the samples are spread onto the grid nodes by linear
  (cloud-in-cell) weights and the result is convolved with the kernel sampled on the grid
  (FFT). This equals ``gaussian_kde(...).evaluate(grid)`` up to the binning error (a test
  bounds it) and costs O(grid log grid + N) instead of O(grid · N), so a million HighD
  rows take well under a second. The grid values are normalised to sum 1: a probability
  mass function over the grid cells.
* **Common grid** **[choice]**: ``grid_points`` nodes per axis (128 in 2-D, 512 in 1-D)
  spanning the pooled samples of both sources, extended on each side by ``pad_bandwidths``
  (4) kernel standard deviations (the wider of the two kernels), so the tails are on the
  grid; or fixed ``limits`` per axis. Samples outside fixed limits are left out.
* **JS divergence** with log base 2 **[choice, docs/method.md §5.3]**:
  ``JS(P‖Q) = ½ KL(P‖M) + ½ KL(Q‖M)``, ``M = ½ (P + Q)``, so 0 ≤ JS ≤ 1; similarity
  ``S = (1 − JS) · 100 %``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import fftconvolve
from scipy.stats import gaussian_kde


@dataclass(frozen=True)
class KdeConfig:
    """Bandwidth and grid of the KDEs (module docstring)."""

    bandwidth: str | float = "scott"
    """``"scott"``, ``"silverman"`` (for the smaller sample's size) or a factor (times the data std)."""
    grid_points_1d: int = 512
    grid_points_2d: int = 128
    """Grid nodes per axis in 2-D."""
    pad_bandwidths: float = 4.0
    """Kernel standard deviations the automatic grid extends beyond the pooled samples."""
    limits: tuple[tuple[float, float], ...] | None = None
    """Fixed (lo, hi) per axis instead of the automatic grid."""
    kernel_sigmas: float = 5.0
    """The kernel is truncated at this many standard deviations (per axis)."""


class KdeError(ValueError):
    """Samples from which no KDE can be built (too few, or no spread)."""


def _as_2d(samples: np.ndarray) -> np.ndarray:
    a = np.asarray(samples, dtype=np.float64)
    return a[:, None] if a.ndim == 1 else a


def bandwidth_factor(bandwidth: str | float, n: int, dim: int) -> float:
    """The kernel factor of a rule (scipy's definitions) for ``n`` samples in ``dim``-D, or a given factor."""
    if bandwidth == "scott":
        return float(n ** (-1.0 / (dim + 4)))
    if bandwidth == "silverman":
        return float((n * (dim + 2) / 4.0) ** (-1.0 / (dim + 4)))
    if isinstance(bandwidth, str):
        raise ValueError(f"bandwidth {bandwidth!r}: expected 'scott', 'silverman' or a positive number")
    if not bandwidth > 0:
        raise ValueError(f"bandwidth {bandwidth!r}: expected 'scott', 'silverman' or a positive number")
    return float(bandwidth)


def shared_factor(a: np.ndarray, b: np.ndarray, bandwidth: str | float) -> float:
    """The one bandwidth factor both KDEs of a comparison use: the rule for the smaller sample."""
    xa, xb = _as_2d(a), _as_2d(b)
    n, dim = min(xa.shape[0], xb.shape[0]), xa.shape[1]
    if n <= dim:
        raise KdeError(f"{n} sample{'s' if n != 1 else ''} in {dim}-D: a KDE needs at least {dim + 1}")
    return bandwidth_factor(bandwidth, n, dim)


def kernel_covariance(samples: np.ndarray, bandwidth: str | float = "scott") -> np.ndarray:
    """Covariance [D, D] of the Gaussian kernel scipy's ``gaussian_kde(samples.T, bandwidth)`` uses."""
    x = _as_2d(samples)
    n, dim = x.shape
    if n <= dim:
        raise KdeError(f"{n} sample{'s' if n != 1 else ''} in {dim}-D: a KDE needs at least {dim + 1}")
    try:
        return np.atleast_2d(gaussian_kde(x.T, bw_method=bandwidth_factor(bandwidth, n, dim)).covariance)
    except np.linalg.LinAlgError:
        raise KdeError(f"{n} samples without spread in every dimension: no KDE bandwidth") from None
    except ValueError as exc:
        raise KdeError(str(exc)) from None


def common_grid(a: np.ndarray, b: np.ndarray, config: KdeConfig = KdeConfig()) -> list[np.ndarray]:
    """The grid axes (one 1-D array per dimension) both KDEs are evaluated on."""
    xa, xb = _as_2d(a), _as_2d(b)
    dim = xa.shape[1]
    points = config.grid_points_1d if dim == 1 else config.grid_points_2d
    if config.limits is not None:
        if len(config.limits) != dim:
            raise ValueError(f"KdeConfig.limits: {len(config.limits)} axes given, the samples have {dim}")
        return [np.linspace(lo, hi, points) for lo, hi in config.limits]
    factor = shared_factor(xa, xb, config.bandwidth)
    sigma = np.maximum(np.sqrt(np.diag(kernel_covariance(xa, factor))),
                       np.sqrt(np.diag(kernel_covariance(xb, factor))))
    pooled = np.concatenate([xa, xb])
    lo = pooled.min(axis=0) - config.pad_bandwidths * sigma
    hi = pooled.max(axis=0) + config.pad_bandwidths * sigma
    return [np.linspace(lo[k], hi[k], points) for k in range(dim)]


def _linear_binning(x: np.ndarray, axes: list[np.ndarray]) -> np.ndarray:
    """Sample counts spread onto the grid nodes with linear (cloud-in-cell) weights."""
    shape = tuple(len(ax) for ax in axes)
    dim = len(axes)
    idx0, frac = [], []
    inside = np.ones(x.shape[0], dtype=bool)
    for k, ax in enumerate(axes):
        pos = (x[:, k] - ax[0]) / (ax[1] - ax[0])
        inside &= (pos >= 0) & (pos <= len(ax) - 1)
        i0 = np.clip(np.floor(pos), 0, len(ax) - 2).astype(np.int64)
        idx0.append(i0)
        frac.append(pos - i0)
    idx0 = [i[inside] for i in idx0]
    frac = [f[inside] for f in frac]
    total = np.zeros(int(np.prod(shape)))
    for corner in range(2 ** dim):
        flat = np.zeros(idx0[0].shape, dtype=np.int64)
        w = np.ones(idx0[0].shape)
        for k in range(dim):
            up = (corner >> k) & 1
            flat = flat * shape[k] + idx0[k] + up
            w = w * (frac[k] if up else 1.0 - frac[k])
        total += np.bincount(flat, weights=w, minlength=total.size)
    return total.reshape(shape)


def _kernel_on_grid(cov: np.ndarray, axes: list[np.ndarray], sigmas: float) -> np.ndarray:
    """The Gaussian kernel of covariance ``cov`` sampled at grid offsets (odd size, centred)."""
    steps = [ax[1] - ax[0] for ax in axes]
    std = np.sqrt(np.diag(cov))
    half = [int(min(len(ax) - 1, np.ceil(sigmas * s / h))) for ax, s, h in zip(axes, std, steps)]
    offsets = np.meshgrid(*[np.arange(-m, m + 1) * h for m, h in zip(half, steps)], indexing="ij")
    z = np.stack([o.ravel() for o in offsets])  # [D, M]
    q = np.einsum("im,ij,jm->m", z, np.linalg.inv(cov), z)
    return np.exp(-0.5 * q).reshape(offsets[0].shape)


def kde_pmf(samples: np.ndarray, axes: list[np.ndarray], bandwidth: str | float = "scott",
            kernel_sigmas: float = 5.0) -> np.ndarray:
    """KDE of ``samples`` ([N] or [N, D]) on the grid ``axes``, normalised to sum 1."""
    x = _as_2d(samples)
    if x.shape[1] != len(axes):
        raise ValueError(f"kde_pmf: {x.shape[1]}-D samples on a {len(axes)}-D grid")
    cov = kernel_covariance(x, bandwidth)
    binned = _linear_binning(x, axes)
    if binned.sum() <= 0:
        raise KdeError("no sample lies on the grid")
    density = np.clip(fftconvolve(binned, _kernel_on_grid(cov, axes, kernel_sigmas), mode="same"), 0.0, None)
    return density / density.sum()


def js_divergence(p: np.ndarray, q: np.ndarray) -> float:
    """Jensen–Shannon divergence of two distributions on the same grid, log base 2 (0..1).

    ``p`` and ``q`` are non-negative arrays of the same shape (normalised here); cells
    where a distribution is 0 contribute 0 to its KL term (0·log 0 = 0).
    """
    p = np.asarray(p, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    if p.shape != q.shape:
        raise ValueError(f"js_divergence: shapes {p.shape} and {q.shape} differ")
    p = p / p.sum()
    q = q / q.sum()
    m = 0.5 * (p + q)

    def kl_to_m(a: np.ndarray) -> float:
        nz = a > 0
        return float(np.sum(a[nz] * np.log2(a[nz] / m[nz])))

    js = 0.5 * (kl_to_m(p) + kl_to_m(q))  # JS = ½ KL(P‖M) + ½ KL(Q‖M), docs/method.md §5.3
    return float(min(1.0, max(0.0, js)))


def similarity_percent(js: float) -> float:
    """S = (1 − JS) · 100 % (docs/method.md §5.3)."""
    return (1.0 - js) * 100.0


@dataclass
class Comparison:
    """Two sample sets' KDEs on their common grid and their JS divergence."""

    js: float
    similarity_pct: float
    axes: list[np.ndarray]
    p: np.ndarray
    q: np.ndarray
    n_p: int
    n_q: int


def compare(a: np.ndarray, b: np.ndarray, config: KdeConfig = KdeConfig()) -> Comparison:
    """KDEs of ``a`` and ``b`` on a common grid and JS(P‖Q); KdeError if either cannot have a KDE."""
    axes = common_grid(a, b, config)
    factor = shared_factor(a, b, config.bandwidth)
    p = kde_pmf(a, axes, factor, config.kernel_sigmas)
    q = kde_pmf(b, axes, factor, config.kernel_sigmas)
    js = js_divergence(p, q)
    return Comparison(js=js, similarity_pct=similarity_percent(js), axes=axes, p=p, q=q,
                      n_p=int(_as_2d(a).shape[0]), n_q=int(_as_2d(b).shape[0]))
