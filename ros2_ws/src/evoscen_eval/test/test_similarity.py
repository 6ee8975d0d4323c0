"""JS divergence and KDE similarity (evoscen_eval.naturalistic.similarity) against known answers."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate, stats

from evoscen_eval.naturalistic.similarity import (
    KdeConfig,
    KdeError,
    bandwidth_factor,
    common_grid,
    compare,
    js_divergence,
    kde_pmf,
    similarity_percent,
)


def js_integral(pdf_p, pdf_q, lo: float, hi: float) -> float:
    """JS(P‖Q) of two continuous densities by numerical integration (scipy.integrate.quad), log2."""

    def integrand(x: float) -> float:
        p, q = pdf_p(x), pdf_q(x)
        m = 0.5 * (p + q)
        out = 0.0
        if p > 0:
            out += 0.5 * p * np.log2(p / m)
        if q > 0:
            out += 0.5 * q * np.log2(q / m)
        return out

    value, _ = integrate.quad(integrand, lo, hi, limit=400, epsabs=1e-12)
    return value


def test_js_of_hand_computed_distributions() -> None:
    # P = [1, 0], Q = [0.5, 0.5]: M = [0.75, 0.25];
    # KL(P‖M) = log2(1/0.75) = 0.415037; KL(Q‖M) = 0.5·log2(0.5/0.75) + 0.5·log2(0.5/0.25) = 0.207519
    assert js_divergence(np.array([1.0, 0.0]), np.array([0.5, 0.5])) == pytest.approx(0.311278, abs=1e-6)
    assert js_divergence(np.array([1.0, 0.0]), np.array([0.0, 1.0])) == pytest.approx(1.0, abs=1e-12)
    # unnormalised inputs are normalised first
    assert js_divergence(np.array([2.0, 0.0]), np.array([3.0, 3.0])) == pytest.approx(0.311278, abs=1e-6)
    assert similarity_percent(0.25) == 75.0


def test_identical_samples_give_zero() -> None:
    rng = np.random.default_rng(1)
    x = rng.normal(size=(2000, 2))
    c = compare(x, x.copy())
    assert c.js == pytest.approx(0.0, abs=1e-12)
    assert c.similarity_pct == pytest.approx(100.0)


def test_disjoint_supports_give_one() -> None:
    rng = np.random.default_rng(2)
    a = rng.uniform(0.0, 1.0, 500)
    b = rng.uniform(100.0, 101.0, 500)
    assert compare(a, b).js == pytest.approx(1.0, abs=1e-9)
    a2 = np.column_stack([a, rng.uniform(0.0, 1.0, 500)])
    b2 = np.column_stack([b, rng.uniform(0.0, 1.0, 500)])
    assert compare(a2, b2).js == pytest.approx(1.0, abs=1e-9)


def test_symmetric() -> None:
    rng = np.random.default_rng(3)
    a = rng.normal(0.0, 1.0, (800, 2))
    b = rng.normal(0.5, 2.0, (1500, 2))
    assert compare(a, b).js == compare(b, a).js
    p, q = rng.random(50), rng.random(50)
    assert js_divergence(p, q) == js_divergence(q, p)


def test_js_of_two_gaussians_matches_the_integral() -> None:
    """Densities on a fine grid: JS within 1e-5 of the quad integral (N(0,1) vs N(1,1.5²))."""
    p, q = stats.norm(0.0, 1.0), stats.norm(1.0, 1.5)
    exact = js_integral(p.pdf, q.pdf, -15.0, 15.0)
    grid = np.linspace(-15.0, 15.0, 6001)
    assert js_divergence(p.pdf(grid), q.pdf(grid)) == pytest.approx(exact, abs=1e-5)
    assert 0.1 < exact < 0.2  # a clearly non-trivial value (≈ 0.13)


def test_kde_of_gaussian_samples_matches_the_integral() -> None:
    """From 20,000 seeded draws each: within 0.005 of the integral.

    A Gaussian KDE of N(μ, σ²) samples estimates N(μ, σ²(1 + f²)) (f = the bandwidth factor,
    Scott: n^(-1/5)); the reference integral uses those widened densities.
    """
    rng = np.random.default_rng(4)
    n = 20_000
    a = rng.normal(0.0, 1.0, n)
    b = rng.normal(1.0, 1.5, n)
    f = bandwidth_factor("scott", n, 1)
    exact = js_integral(stats.norm(0.0, np.sqrt(1 + f * f)).pdf, stats.norm(1.0, 1.5 * np.sqrt(1 + f * f)).pdf,
                        -20.0, 20.0)
    assert compare(a, b).js == pytest.approx(exact, abs=0.005)


@pytest.mark.parametrize("dim", [1, 2])
def test_binned_kde_equals_scipy_gaussian_kde(dim: int) -> None:
    """The binned evaluation is scipy's gaussian_kde up to a total-variation distance of 0.005."""
    rng = np.random.default_rng(5)
    x = rng.normal(size=(600, dim)) @ (np.array([[1.0, 0.6], [0.0, 0.8]])[:dim, :dim])
    axes = common_grid(x, x)
    pmf = kde_pmf(x, axes)
    nodes = np.stack([g.ravel() for g in np.meshgrid(*axes, indexing="ij")])
    ref = stats.gaussian_kde(x.T, bw_method="scott").evaluate(nodes).reshape(pmf.shape)
    ref /= ref.sum()
    assert pmf.sum() == pytest.approx(1.0)
    assert 0.5 * np.abs(pmf - ref).sum() < 0.005


def test_fixed_limits_and_grid_size() -> None:
    cfg = KdeConfig(grid_points_1d=101, limits=((0.0, 10.0),))
    axes = common_grid(np.array([1.0, 2.0, 3.0]), np.array([4.0, 5.0, 7.0]), cfg)
    assert len(axes) == 1 and axes[0][0] == 0.0 and axes[0][-1] == 10.0 and len(axes[0]) == 101


def test_too_few_or_degenerate_samples() -> None:
    with pytest.raises(KdeError, match="needs at least 2"):
        compare(np.array([1.0]), np.array([1.0, 2.0, 3.0]))
    with pytest.raises(KdeError, match="needs at least 3"):
        compare(np.zeros((2, 2)), np.ones((5, 2)))
    with pytest.raises(KdeError, match="spread"):
        compare(np.full(10, 3.0), np.arange(10.0))
    with pytest.raises(ValueError, match="bandwidth 'wide'"):
        bandwidth_factor("wide", 10, 1)
