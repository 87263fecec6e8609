"""The belief accessor of the envs, the core's update edge cases, and the numpy reference filter the kernels are
tested against (tests/reference_filter.py)."""

from __future__ import annotations

import numpy as np
import pytest
from reference_filter import ParticleBelief, spread_from_cov, systematic_resample, weighted_mean_cov

from electroloc_gym.sensor_models import AnalyticSensorModel
from electroloc_gym.world.conditions import get_condition
from electroloc_gym.world.sensor import noisy_reading


def test_uniform_start_statistics() -> None:
    b = ParticleBelief(20000, [-50, -50], [50, 50])
    b.reset(np.random.default_rng(0))
    assert np.all(np.abs(b.particles) <= 50)
    np.testing.assert_allclose(b.mean(), 0.0, atol=1.0)
    # Uniform on ±50: variance 100²/12 per axis, spread √(2·833.3) ≈ 40.8 mm.
    assert b.spread() == pytest.approx(np.sqrt(2 * 100**2 / 12), rel=0.02)


def test_update_is_bayes_rule() -> None:
    b = ParticleBelief(4, [-10, -10], [10, 10])
    b.set_state(np.array([[0, 0], [1, 0], [2, 0], [3, 0]], float))
    ll = np.log(np.array([1.0, 2.0, 3.0, 4.0]))
    w = b.update(ll)
    np.testing.assert_allclose(w, [0.1, 0.2, 0.3, 0.4])
    w = b.update(ll)  # second update multiplies again
    np.testing.assert_allclose(w, np.array([1, 4, 9, 16]) / 30)
    np.testing.assert_allclose(b.mean(), [np.dot(w, [0, 1, 2, 3]), 0.0])


def test_all_weights_underflowing_is_handled_in_log_domain() -> None:
    b = ParticleBelief(3, [-10, -10], [10, 10])
    b.set_state(np.array([[0, 0], [1, 0], [2, 0]], float))
    w = b.update(np.array([-2000.0, -2001.0, -5000.0]))  # exp() of each underflows to 0
    np.testing.assert_allclose(w, [1 / (1 + np.exp(-1)), np.exp(-1) / (1 + np.exp(-1)), 0.0], atol=1e-12)
    assert not b.last_update_degenerate


def test_all_minus_inf_keeps_weights_and_flags() -> None:
    b = ParticleBelief(3, [-10, -10], [10, 10])
    b.set_state(np.zeros((3, 2)))
    w = b.update(np.full(3, -np.inf))
    np.testing.assert_allclose(w, 1 / 3)
    assert b.last_update_degenerate


def test_nan_likelihood_is_an_error() -> None:
    b = ParticleBelief(3, [-10, -10], [10, 10])
    b.set_state(np.zeros((3, 2)))
    with pytest.raises(ValueError, match="NaN"):
        b.update(np.array([0.0, np.nan, 0.0]))


def test_systematic_resampling_counts() -> None:
    w = np.array([0.5, 0.25, 0.125, 0.125])
    idx = systematic_resample(np.tile(w, 1), np.random.default_rng(0))
    counts = np.bincount(idx, minlength=4)
    # Systematic resampling: each count is floor or ceil of M·w.
    assert np.all(np.abs(counts - 4 * w) < 1)
    big = np.random.default_rng(1).dirichlet(np.ones(1000))
    idx = systematic_resample(big, np.random.default_rng(2))
    assert np.all(np.abs(np.bincount(idx, minlength=1000) - 1000 * big) < 1)


def test_batched_resampling_equals_rowwise() -> None:
    rng = np.random.default_rng(3)
    w = rng.dirichlet(np.ones(50), size=(3, 4))
    idx = systematic_resample(w, np.random.default_rng(9))
    u = np.random.default_rng(9).random((3, 4, 1))
    for i in range(3):
        for j in range(4):
            cum = np.cumsum(w[i, j]) / w[i, j].sum()
            ref = np.minimum(np.searchsorted(cum, (u[i, j] + np.arange(50)) / 50, side="right"), 49)
            np.testing.assert_array_equal(idx[i, j], ref)


def test_weighted_stats_and_spread_for_far_apart_clusters() -> None:
    # Two clusters 80 mm apart: spread must reflect the bimodality (≈40 mm), not the cluster widths.
    rng = np.random.default_rng(0)
    p = np.concatenate([rng.normal([-40, 0], 1.0, (500, 2)), rng.normal([40, 0], 1.0, (500, 2))])
    mean, cov = weighted_mean_cov(p)
    assert spread_from_cov(cov) == pytest.approx(40.0, rel=0.02)
    w = np.r_[np.full(500, 0.9 / 500), np.full(500, 0.1 / 500)]
    mean, cov = weighted_mean_cov(p, w)
    assert mean[0] == pytest.approx(-32.0, abs=0.3)
    np.testing.assert_allclose(cov, np.cov(p.T, aweights=w, bias=True), rtol=1e-10)
    batched_mean, batched_cov = weighted_mean_cov(np.stack([p, p]), np.stack([w, w]))
    np.testing.assert_allclose(batched_cov[1], cov)


def test_jitter_and_box() -> None:
    b = ParticleBelief(5000, [-5, -5], [5, 5], jitter_std_mm=1.0)
    b.set_state(np.zeros((5000, 2)))
    b.jitter(np.random.default_rng(0))
    assert b.particles.std() == pytest.approx(1.0, rel=0.05)
    b.predict([100.0, 0.0])
    assert np.all(b.particles[:, 0] == 5.0)


@pytest.mark.parametrize("n", [0, -1, 2.5, True])
def test_bad_particle_count(n) -> None:
    with pytest.raises(ValueError, match="n_particles"):
        ParticleBelief(n, [-1, -1], [1, 1])


def test_bad_box() -> None:
    with pytest.raises(ValueError, match="low_mm"):
        ParticleBelief(10, [1, 1], [-1, 1])


def test_filter_converges_on_true_target() -> None:
    """Static carriage grid around a known target: the filter's estimate converges and spread shrinks."""
    c = get_condition("fresh-steel-12.7")
    model = AnalyticSensorModel(c)
    rng = np.random.default_rng(0)
    target = np.array([7.0, -12.0])
    b = ParticleBelief(2500, [-50, -50], [50, 50])
    b.reset(rng)
    for pos in [np.array([x, y]) for x in (-20, 0, 20) for y in (-25, -5, 15)] * 2:
        z = float(noisy_reading(c, target - pos, rng))
        b.assimilate(model.log_likelihood(z, b.particles - pos), rng)
    assert np.linalg.norm(b.mean() - target) < 3.0
    assert b.spread() < 5.0


def test_belief_view_is_a_read_only_view_of_the_core_cloud() -> None:
    import gymnasium as gym

    import electroloc_gym  # noqa: F401

    env = gym.make("ElectroLoc-v0", n_particles=300)
    env.reset(seed=1)
    b = env.unwrapped.belief
    p = b.particles
    assert p.shape == (300, 2) and p.dtype == np.float32
    with pytest.raises(ValueError):
        p[0, 0] = 1.0
    np.testing.assert_allclose(b.mean(), p.astype(np.float64).mean(axis=0), rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(b.covariance(), np.cov(p.T.astype(np.float64), bias=True), rtol=1e-9, atol=1e-9)
    assert b.spread() == pytest.approx(float(np.sqrt(np.trace(b.covariance()))))
    assert b.uniform_weights and np.all(b.weights == 1 / 300)
    env.step(np.zeros(2, np.float32))  # a live view: it shows the updated cloud
    np.testing.assert_allclose(b.mean(), b.particles.astype(np.float64).mean(axis=0), rtol=1e-12, atol=1e-9)


def _update(ll: np.ndarray) -> tuple[np.ndarray, int]:
    """The core's update kernel on one cloud of 3 particles at 0, 1, 2 mm (u0 = 0.5, no jitter)."""
    from electroloc_gym.kernels import loglik_assimilate
    from electroloc_gym.kernels.streams import normal_table

    src = np.array([[[0.0, 1.0, 2.0], [0.0, 0.0, 0.0]]], dtype=np.float32)
    table = normal_table()
    zero = np.full((1, 6), np.searchsorted(table, 0.0), dtype=np.uint16)  # the quantiles nearest 0
    mean, cov, counts = np.empty((1, 2)), np.empty((1, 2, 2)), np.empty((1, 64))
    bad = loglik_assimilate(
        ll[None].astype(np.float32),
        src,
        np.zeros((1, 2), np.float32),
        np.full(1, 0.5),
        zero,
        table,
        np.full(1, 10.0, np.float32),
        src,
        mean,
        cov,
        np.full(1, 20.0, np.float32),
        8,
        counts,
    )
    return np.round(src[0, 0]).astype(int), bad


def test_core_update_edge_cases() -> None:
    # Every likelihood underflowing in linear space: the log-domain weights still pick the best particle.
    x, bad = _update(np.array([-2000.0, -1990.0, -5000.0]))
    assert bad == -1 and np.all(x == 1)
    # All −inf: the weights stay uniform (each particle kept once).
    x, bad = _update(np.full(3, -np.inf))
    assert bad == -1 and sorted(x.tolist()) == [0, 1, 2]
    # A NaN log-likelihood is reported (the env raises).
    _, bad = _update(np.array([0.0, np.nan, 0.0]))
    assert bad == 0
