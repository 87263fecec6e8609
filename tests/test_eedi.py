"""eedi: the cosine basis, the expected information density (closed forms), SMC on a fixed density, the agent."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import electroloc_gym  # noqa: F401  (registers the ids)
from electroloc_gym.baselines.agent import MAX_STEP_MM, make_agent, move_bounds_mm
from electroloc_gym.baselines.eedi import EEDIAgent
from electroloc_gym.baselines.ergodic import (
    CosineBasis,
    belief_fisher_information,
    information_density,
    workspace_grid,
)

BOX = ((-50.0, -50.0), (50.0, 50.0))


def _bump(amplitude_V: float, width_mm: float, hypotheses_mm: np.ndarray, noise_V: float):
    """A closed-form sensor: μ = A exp(−|θ − q|²/2s²), σ constant; the reading function of the EID."""

    def readings(carriages):
        d = hypotheses_mm[None, :, :] - carriages[:, None, :]
        mean = amplitude_V * np.exp(-0.5 * np.sum(d * d, axis=-1) / width_mm**2)
        return mean, np.full_like(mean, noise_V)

    return readings


def test_cosine_basis_is_orthonormal_and_its_gradients_are_right() -> None:
    basis = CosineBasis(*BOX, n_per_axis=5)
    grid, area = workspace_grid(*BOX, 0.5)
    f = basis.values(grid)
    np.testing.assert_allclose(f.T @ f * area, np.eye(25), atol=1e-4)  # ∫ F_j F_k = δ_jk (midpoint rule)
    x = np.array([[12.3, -7.7], [-40.0, 33.0]])
    h = 1e-5
    fd = np.stack(
        [
            (basis.values(x + [h, 0]) - basis.values(x - [h, 0])) / (2 * h),
            (basis.values(x + [0, h]) - basis.values(x - [0, h])) / (2 * h),
        ],
        axis=-1,
    )
    np.testing.assert_allclose(basis.gradients(x), fd, atol=1e-8)
    np.testing.assert_allclose(basis.gradients(np.array([[-50.0, 10.0]]))[..., 0], 0.0, atol=1e-12)  # no flux


def test_workspace_grid_covers_the_box_with_equal_cells() -> None:
    grid, area = workspace_grid((-60.0, -60.0), (60.0, 60.0), 5.0)
    assert grid.shape == (576, 2) and area == 25.0
    np.testing.assert_allclose(grid.min(axis=0), -57.5)
    grid, area = workspace_grid((0.0, 0.0), (10.0, 7.0), 3.0)  # ⌈10/3⌉ = 4, ⌈7/3⌉ = 3 cells
    assert grid.shape == (12, 2) and area == pytest.approx(2.5 * 7 / 3)


@pytest.mark.parametrize("criterion", ["det", "trace"])
def test_the_density_integrates_to_one(criterion: str) -> None:
    rng = np.random.default_rng(0)
    hyp = rng.uniform(-30, 30, size=(40, 2))
    grid, area = workspace_grid(*BOX, 4.0)
    eid = information_density(belief_fisher_information(_bump(2.0, 12.0, hyp, 0.05), grid), area, criterion)
    assert eid.sum() * area == pytest.approx(1.0, rel=1e-12)
    assert np.all(eid >= 0)


def test_the_density_peaks_where_the_reading_is_most_sensitive() -> None:
    """Closed form: one hypothesis θ₀ and μ = A exp(−r²/2s²): |∇μ|² = A² r²/s⁴ exp(−r²/s²), largest on r = s."""
    theta, s, a, noise = np.array([[3.5, -4.5]]), 12.0, 2.0, 0.05  # θ₀ on a cell centre
    grid, area = workspace_grid(*BOX, 1.0)
    fisher = belief_fisher_information(_bump(a, s, theta, noise), grid, step_mm=1e-3)
    eid = information_density(fisher, area, "trace")
    r2 = np.sum((grid - theta) ** 2, axis=1)
    closed = a**2 * r2 / s**4 * np.exp(-r2 / s**2) / noise**2
    np.testing.assert_allclose(fisher[:, 0, 0] + fisher[:, 1, 1], closed, rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose(eid, closed / (closed.sum() * area), rtol=1e-5, atol=1e-12)
    peak = np.sqrt(r2[np.argmax(eid)])
    assert abs(peak - s) < 1.0  # on the ring of steepest reading, within a cell
    assert eid[np.argmin(r2)] < 1e-9 * eid.max()  # flat top: no information right above it


def test_the_determinant_is_of_the_belief_averaged_fisher_matrix() -> None:
    theta, s, a, noise = np.array([[0.0, 0.0], [10.0, 5.0]]), 10.0, 1.5, 0.1
    q = np.array([[4.0, -6.0], [20.0, 20.0], [-15.0, 3.0]])
    fisher = belief_fisher_information(_bump(a, s, theta, noise), q, step_mm=1e-3)
    expect = np.zeros((3, 2, 2))
    for t in theta:  # ∇_θ μ = −A/s² (θ − q) exp(−|θ − q|²/2s²)
        d = t - q
        g = -a / s**2 * d * np.exp(-0.5 * np.sum(d * d, axis=1) / s**2)[:, None]
        expect += g[:, :, None] * g[:, None, :] / noise**2 / len(theta)
    np.testing.assert_allclose(fisher, expect, rtol=1e-5, atol=1e-10)
    raw = np.linalg.det(expect)
    np.testing.assert_allclose(information_density(fisher, 1.0, "det"), raw / raw.sum(), rtol=1e-4)
    one = belief_fisher_information(_bump(a, s, theta[:1], noise), q, step_mm=1e-3)
    assert np.all(np.abs(np.linalg.det(one)) < 1e-9 * np.max(one) ** 2)  # one hypothesis: rank one


def test_smc_drives_the_ergodic_metric_down_on_a_fixed_density() -> None:
    basis = CosineBasis((0.0, 0.0), (100.0, 100.0), n_per_axis=10)
    grid, area = workspace_grid((0.0, 0.0), (100.0, 100.0), 1.0)
    density = np.exp(-np.sum((grid - [30.0, 35.0]) ** 2, axis=1) / (2 * 8.0**2)) + 0.6 * np.exp(
        -np.sum((grid - [70.0, 65.0]) ** 2, axis=1) / (2 * 12.0**2)
    )
    density /= density.sum() * area
    phi_k = basis.density_coefficients(density, grid, area)
    path = [np.array([90.0, 10.0])]
    metrics = {}
    for t in range(1, 401):
        b = basis.smc_direction(np.array(path), phi_k)
        path.append(np.clip(path[-1] - 2.0 * b / np.linalg.norm(b), 0.0, 100.0))  # |u| = 2 mm per step
        if t in (25, 50, 100, 200, 400):
            metrics[t] = basis.metric(np.array(path), phi_k)
    values = [metrics[t] for t in sorted(metrics)]
    assert all(b < a for a, b in zip(values, values[1:])), metrics
    assert values[-1] < 0.05 * values[0]
    uniform_start = basis.metric(np.array(path[:1]), phi_k)
    assert values[-1] < 0.01 * uniform_start


def test_bad_options_name_the_option() -> None:
    for spec, option in [
        ("eedi[n_coefficients=1]", "n_coefficients"),
        ("eedi[grid_mm=0]", "grid_mm"),
        ("eedi[n_particles=0]", "n_particles"),
        ("eedi[update_period=0]", "update_period"),
        ("eedi[criterion='max']", "criterion"),
        ("eedi[step_mm=-1]", "step_mm"),
    ]:
        with pytest.raises(ValueError, match=option):
            make_agent(spec)
    with pytest.raises(ValueError, match="n_per_axis"):
        CosineBasis(*BOX, n_per_axis=0)
    with pytest.raises(ValueError, match="criterion"):
        information_density(np.zeros((1, 2, 2)), 1.0, "max")
    with pytest.raises(ValueError, match="path_mm"):
        CosineBasis(*BOX, n_per_axis=3).metric(np.zeros((0, 2)), np.zeros(9))


def _moves(agent, env, seed=4, steps=4):
    obs, _ = env.reset(seed=seed)
    agent.reset(env)
    moves = []
    for _ in range(steps):
        lo, hi = move_bounds_mm(env)
        action, _ = agent.predict(obs)
        u = np.asarray(action, dtype=np.float64) * MAX_STEP_MM
        assert np.all(u >= lo - 1e-5) and np.all(u <= hi + 1e-5)
        assert np.max(np.abs(u)) <= MAX_STEP_MM + 1e-5
        moves.append(u)
        obs, _, term, trunc, _ = env.step(action)
        if term or trunc:
            break
    return np.array(moves)


def test_decisions_are_seeded_within_the_limits_and_the_density_is_normalised() -> None:
    env = gym.make("ElectroLoc-v0", n_particles=500, sensor_model="analytic")
    agent = make_agent("eedi[n_particles=100]", seed=3)
    a = _moves(agent, env)
    b = _moves(make_agent("eedi[n_particles=100]", seed=3), env)
    np.testing.assert_array_equal(a, b)
    assert isinstance(agent, EEDIAgent) and agent.last_density is not None
    h = float(np.unique(np.diff(np.unique(agent.last_grid_mm[:, 0])))[0])
    assert agent.last_density.sum() * h * h == pytest.approx(1.0)


def test_registry_and_bench_name() -> None:
    from electroloc_gym.bench.agents import agent_kind

    assert agent_kind("eedi[n_coefficients=6]") == "baseline"
    assert make_agent("eedi[n_coefficients=6]").n_coefficients == 6
