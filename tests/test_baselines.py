"""The paper's controllers: move limits, Algorithm 1 against a literal implementation, registry errors."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import electroloc_gym  # noqa: F401  (registers the ids)
from electroloc_gym.baselines.agent import (
    MAX_STEP_MM,
    BaselineAgent,
    make_agent,
    move_bounds_mm,
    parse_agent_spec,
    sample_options_mm,
)
from electroloc_gym.baselines.min_variance import (
    MinVarianceAgent,
    choose_voters,
    count_votes,
    option_means_stds,
    predicted_variances,
    resampled_variances,
    weighted_moments,
)
from electroloc_gym.baselines.min_variance_reference import (
    literal_predicted_variances,
    multinomial_resampled_variances,
)
from electroloc_gym.baselines.random_walk import RandomWalkAgent
from electroloc_gym.baselines.zero_crossing import ZeroCrossingAgent, _line_zero
from electroloc_gym.utils.agentspec import AgentSpec
from electroloc_gym.world.conditions import get_condition
from electroloc_gym.world.sensor import expected_reading


def _run(agent, condition="fresh-steel-12.7", seed=0, n_particles=300, max_steps=None, **env_kwargs):
    """Run one trial; return (positions before each step, moves requested in mm, final info)."""
    cond = get_condition(condition)
    if hasattr(agent, "adapt_condition"):
        cond = agent.adapt_condition(cond)
    kwargs = {"condition": cond, "n_particles": n_particles, **env_kwargs, **agent.env_kwargs}
    env = gym.make("ElectroLoc-v0", **kwargs)
    obs, info = env.reset(seed=seed)
    agent.reset(env)
    positions, moves, boxes = [], [], []
    steps = 0
    while True:
        action, _ = agent.predict(obs)
        if getattr(agent, "done", False):
            break
        a = np.asarray(action, dtype=np.float64)
        assert a.shape == (2,) and np.all(np.abs(a) <= 1.0 + 1e-7)
        positions.append(env.unwrapped.position_mm)
        moves.append(a * MAX_STEP_MM)
        boxes.append(env.unwrapped.allowed_box_mm)
        obs, _, term, trunc, info = env.step(action)
        # the carriage went exactly where the agent asked (no move was clipped by a wall)
        np.testing.assert_allclose(env.unwrapped.position_mm, positions[-1] + moves[-1], atol=1e-4)
        steps += 1
        if term or trunc or (max_steps is not None and steps >= max_steps):
            break
    return np.array(positions), np.array(moves), info, env


# ---- options and registry ------------------------------------------------------------------------
def test_sample_options_stay_first_and_inside_bounds() -> None:
    rng = np.random.default_rng(0)
    lo, hi = np.array([-10.0, -3.0]), np.array([4.0, 10.0])
    opts = sample_options_mm(rng, lo, hi, 16)
    assert opts.shape == (16, 2)
    np.testing.assert_array_equal(opts[0], [0.0, 0.0])
    assert np.all(opts >= lo) and np.all(opts <= hi)
    with pytest.raises(ValueError, match="n_options"):
        sample_options_mm(rng, lo, hi, 0)


def test_move_bounds_clip_to_box() -> None:
    env = gym.make("ElectroLoc-v0", n_particles=50, sensor_model="analytic")
    env.reset(seed=1)
    env.unwrapped._state.position_mm[0] = [47.0, -50.0]  # test setup only: put the carriage near two walls
    lo, hi = move_bounds_mm(env)
    np.testing.assert_allclose(lo, [-10.0, 0.0])
    np.testing.assert_allclose(hi, [3.0, 10.0])


@pytest.mark.parametrize(
    "name,cls", [("rnd-wlk", RandomWalkAgent), ("min-var", MinVarianceAgent), ("zero-crossing", ZeroCrossingAgent)]
)
def test_make_agent_builds_registry_agents(name: str, cls: type) -> None:
    agent = make_agent(name, seed=3)
    assert isinstance(agent, cls) and isinstance(agent, BaselineAgent)
    assert isinstance(agent.env_kwargs, dict)


def test_make_agent_options() -> None:
    agent = make_agent("min-var[n_voters=64, n_options=8]")
    assert agent.n_voters == 64 and agent.n_options == 8
    assert make_agent("min-var[n_voters=None]").n_voters is None
    spec = parse_agent_spec("rnd-wlk[n_options=4]")  # the package's one parser and its one type
    assert isinstance(spec, AgentSpec) and (spec.name, spec.options) == ("rnd-wlk", {"n_options": 4})


def test_one_registry_declares_every_built_in_agent() -> None:
    from electroloc_gym.baselines.agent import AGENT_NAMES, PAPER_AGENTS, _registry
    from electroloc_gym.bench.config import DEFAULT_AGENTS

    assert tuple(_registry()) == AGENT_NAMES and DEFAULT_AGENTS == PAPER_AGENTS == AGENT_NAMES[:3]


@pytest.mark.parametrize(
    "spec,match",
    [
        ("nope", "unknown agent 'nope'"),
        ("min-var[n_voters=0]", "n_voters"),
        ("min-var[bogus=1]", "bad options for agent 'min-var'"),
        ("min-var[n_voters]", "key=value"),
        ("", "non-empty"),
        ("rnd wlk!", "malformed"),
    ],
)
def test_make_agent_bad_names(spec: str, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        make_agent(spec)


def test_make_agent_builds_controllers_and_shipped_policies_by_name_only() -> None:
    # a shipped policy by its name (electroloc_gym.policy.load_policy); paths and files go through load_policy or
    # the benchmark's registry (electroloc_gym.bench.agents), never through make_agent
    from electroloc_gym.policy import LearnedAgent

    assert isinstance(make_agent("ppo-belief"), LearnedAgent)
    for spec in ("electroloc_gym/models/ppo-belief", "run/model.zip", "ppo-nope"):
        with pytest.raises(ValueError, match="unknown agent|malformed"):
            make_agent(spec)


# ---- every agent's moves: ≤ 10 mm per axis, never out of the box -----------------------------------
@pytest.mark.parametrize("spec", ["rnd-wlk", "min-var[n_voters=32]"])
@pytest.mark.parametrize("condition", ["fresh-steel-12.7", "salt-delrin-38.1"])
def test_belief_agents_moves_within_limits(spec: str, condition: str) -> None:
    agent = make_agent(spec, seed=5)
    positions, moves, info, env = _run(agent, condition, seed=2, n_particles=300)
    assert len(moves) >= 1
    assert np.all(np.abs(moves) <= MAX_STEP_MM + 1e-6)
    low, high = env.unwrapped.allowed_box_mm
    path = env.unwrapped.path_mm
    assert np.all(path >= low - 1e-9) and np.all(path <= high + 1e-9)


def test_belief_agents_hug_the_wall_without_leaving() -> None:
    # Start the carriage in a corner: options must stay inside (moves are never clipped, checked in _run).
    agent = make_agent("rnd-wlk", seed=1)
    env = gym.make("ElectroLoc-v0", n_particles=100, sensor_model="analytic", signal="paper")
    env.reset(seed=0)
    env.unwrapped._state.position_mm[0] = [50.0, -50.0]  # test setup only: the carriage in a corner
    agent.reset(env)
    for _ in range(30):
        a, _ = agent.predict(None)
        before = env.unwrapped.position_mm
        *_, term, trunc, _ = env.step(a)
        np.testing.assert_allclose(env.unwrapped.position_mm, before + np.asarray(a, float) * MAX_STEP_MM, atol=1e-4)
        if term or trunc:
            break


def test_zero_crossing_moves_within_limits_and_workspace() -> None:
    agent = make_agent("zero-crossing")
    positions, moves, info, env = _run(agent, "fresh-steel-12.7", seed=4, n_particles=16)
    assert agent.done and agent.estimate_mm is not None
    assert np.all(np.abs(moves) <= MAX_STEP_MM + 1e-6)
    lo, hi = agent.workspace_mm
    path = env.unwrapped.path_mm
    assert np.all(path >= lo - 1e-6) and np.all(path <= hi + 1e-6)
    assert np.all(hi - lo <= 160.0 + 1e-9)


def test_rnd_wlk_seeded_determinism() -> None:
    a1 = _run(make_agent("rnd-wlk", seed=7), seed=1, max_steps=10)[1]
    a2 = _run(make_agent("rnd-wlk", seed=7), seed=1, max_steps=10)[1]
    a3 = _run(make_agent("rnd-wlk", seed=8), seed=1, max_steps=10)[1]
    np.testing.assert_array_equal(a1, a2)
    assert not np.array_equal(a1, a3)


# ---- min-var: Algorithm 1 ----------------------------------------------------------------------------
def _small_belief(condition: str, sensor_model: str, m: int, steps: int = 2, seed: int = 0, signal: str = "fitted"):
    """A belief after ``steps`` fixed moves; the weak fitted signal keeps it wide (many distinct options)."""
    env = gym.make("ElectroLoc-v0", condition=condition, sensor_model=sensor_model, n_particles=m, signal=signal)
    env.reset(seed=seed)
    for _ in range(steps):
        *_, term, trunc, _ = env.step(np.array([0.7, -0.4], dtype=np.float32))
        if term or trunc:
            break
    return env.unwrapped


@pytest.mark.parametrize(
    "condition,sensor_model", [("fresh-steel-12.7", "calibrated"), ("salt-delrin-38.1", "analytic")]
)
@pytest.mark.parametrize("weighted", [False, True])
def test_vectorised_vote_equals_literal(condition: str, sensor_model: str, weighted: bool) -> None:
    core = _small_belief(condition, sensor_model, m=40)
    rng = np.random.default_rng(11)
    options = sample_options_mm(rng, *move_bounds_mm(core), 16)
    particles = core.belief.particles
    weights = rng.dirichlet(np.ones(particles.shape[0])) if weighted else None
    voters = choose_voters(rng, particles.shape[0], 10)
    positions = core.position_mm + options
    ref = literal_predicted_variances(core.sensor_model, particles, weights, positions, voters)
    mean, std = option_means_stds(core.sensor_model, particles, positions)
    for kernel in ("difference", "expanded"):
        fast = predicted_variances(particles, weights, mean, std, voters, kernel=kernel, chunk_rows=3)
        # float32 sums of |x|² (x ≈ ±50 mm) leave ≈ 1e-4 mm² of cancellation in E|x|² − |E x|²
        np.testing.assert_allclose(fast, ref, rtol=1e-3, atol=1e-3)
        # Same ballots wherever the literal vote is not a float-rounding tie, and the same winner.
        srt = np.sort(ref, axis=1)
        clear = (srt[:, 1] - srt[:, 0]) > 1e-3 * srt[:, 0]
        np.testing.assert_array_equal(fast.argmin(axis=1)[clear], ref.argmin(axis=1)[clear])
        assert count_votes(fast)[0] == count_votes(ref)[0]


def test_env_prediction_api_matches_direct_offsets() -> None:
    core = _small_belief("fresh-delrin-12.7", "calibrated", m=64)
    options = sample_options_mm(np.random.default_rng(0), *move_bounds_mm(core), 16)
    a = core.predicted_reading_model(core.belief.particles, options)
    b = option_means_stds(core.sensor_model, core.belief.particles, core.position_mm + options)
    np.testing.assert_allclose(a[0], b[0], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(a[1], b[1], rtol=1e-5, atol=1e-6)


def test_weighted_variance_is_the_expected_resampled_variance() -> None:
    # Algorithm 1 step 4–5 resample; E[population variance of M multinomial draws] = (M−1)/M · weighted var.
    rng = np.random.default_rng(0)
    m = 40
    x = rng.normal(size=(m, 2)) * [3.0, 1.0]
    w = rng.dirichlet(np.ones(m))
    mean = w @ x
    wvar = float(np.sum(w * np.sum((x - mean) ** 2, axis=1)))
    draws = rng.choice(m, size=(20000, m), p=w)
    xs = x[draws]
    pop = np.mean(np.sum((xs - xs.mean(axis=1, keepdims=True)) ** 2, axis=2), axis=1)
    assert abs(pop.mean() - (m - 1) / m * wvar) < 4 * pop.std() / np.sqrt(pop.size)


def _moments_float64(x: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Reference: the nine normalised moments of :func:`weighted_moments` in float64, per weight row."""
    xc = x - np.average(x, axis=0, weights=np.full(x.shape[0], 1.0 / x.shape[0]))
    cx, cy = xc[:, 0], xc[:, 1]
    r2 = cx * cx + cy * cy
    f = np.stack([np.ones_like(cx), cx, cy, cx * cx, cy * cy, cx * cy, r2 * cx, r2 * cy, r2 * r2], axis=1)
    return (w @ f) / w.sum(axis=1, keepdims=True)


def test_weighted_moments_match_float64() -> None:
    core = _small_belief("fresh-steel-12.7", "calibrated", m=300)
    rng = np.random.default_rng(4)
    options = sample_options_mm(rng, *move_bounds_mm(core), 16)
    p = core.belief.particles.astype(np.float64)
    mean, std = core.predicted_reading_model(core.belief.particles, options)
    voters = choose_voters(rng, p.shape[0], 20)
    mom = weighted_moments(core.belief.particles, None, mean, std, voters)
    for c in (0, 5, 15):
        z = (mean[c, voters][:, None] - mean[c][None, :]) / std[c][None, :]
        w = np.exp(-0.5 * z * z) / std[c][None, :]
        ref = _moments_float64(p, w)
        np.testing.assert_allclose(mom[:, c, 1:], ref[:, 1:], rtol=2e-3, atol=2e-2)


def test_resampled_variance_has_the_distribution_of_a_literal_resample() -> None:
    """Algorithm 1 step 4: the central-limit draw against real roulette-wheel resampling (many draws)."""
    core = _small_belief("fresh-steel-12.7", "calibrated", m=400, steps=2)
    rng = np.random.default_rng(8)
    options = sample_options_mm(rng, *move_bounds_mm(core), 4)
    p = core.belief.particles
    mean, std = core.predicted_reading_model(p, options)
    voters = choose_voters(rng, p.shape[0], 6)
    mom = weighted_moments(p, None, mean, std, voters)
    clt = np.stack([resampled_variances(mom, p.shape[0], rng) for _ in range(2000)])
    lit = np.stack([multinomial_resampled_variances(p, None, mean, std, voters, rng) for _ in range(400)])
    se_mean = lit.std(axis=0) / np.sqrt(lit.shape[0])
    assert np.all(np.abs(clt.mean(axis=0) - lit.mean(axis=0)) < 5 * se_mean + 1e-3 * lit.mean(axis=0))
    ratio = clt.std(axis=0) / lit.std(axis=0)
    assert np.all((ratio > 0.8) & (ratio < 1.25)), ratio  # 400 literal draws: sd known to ≈ ±4 %
    # and the expectation is (M − 1)/M times the weighted variance
    expected = predicted_variances(p, None, mean, std, voters) * (p.shape[0] - 1) / p.shape[0]
    np.testing.assert_allclose(clt.mean(axis=0), expected, rtol=0.02)


def test_blind_voters_scatter_with_the_resample_and_agree_with_the_expectation() -> None:
    """The mechanism that separates Algorithm 1 from the argmin of the expected variance."""
    cond = get_condition("fresh-steel-12.7", "fitted")  # a small detection region: most voters are blind
    env = gym.make("ElectroLoc-v0", condition=cond, n_particles=2500, sensor_model="calibrated")
    env.reset(seed=2)
    core = env.unwrapped
    rng = np.random.default_rng(0)
    options = sample_options_mm(rng, *move_bounds_mm(core), 16)
    p = core.belief.particles
    mean, std = core.predicted_reading_model(p, options)
    # blind: hypotheses whose true (noise-free) reading is below half the noise at every option
    offsets = p[None, :, :].astype(np.float64) - (core.position_mm + options)[:, None, :]
    blind = np.flatnonzero(np.all(np.abs(expected_reading(cond, offsets)) < 0.5 * cond.noise_std_V, axis=0))
    assert blind.size > 200
    voters = blind[:200]
    exp_ballots = np.argmin(predicted_variances(p, None, mean, std, voters), axis=1)
    res_ballots = np.argmin(resampled_variances(weighted_moments(p, None, mean, std, voters), p.shape[0], rng), axis=1)
    top_exp = np.bincount(exp_ballots, minlength=16).max() / voters.size
    top_res = np.bincount(res_ballots, minlength=16).max() / voters.size
    assert top_exp > 0.95 and top_res < 0.8, (top_exp, top_res)  # measured: 1.0 and 0.64


def test_min_var_vote_options() -> None:
    for vote in ("resample", "expected", "multinomial"):
        agent = make_agent(f"min-var[vote={vote!r},n_voters=8]", seed=1)
        _, moves, info, _ = _run(agent, seed=2, n_particles=120, max_steps=3)
        assert 1 <= len(moves) <= 3 and np.all(np.abs(moves) <= MAX_STEP_MM)
    with pytest.raises(ValueError, match="vote"):
        MinVarianceAgent(vote="mean")


def test_particles_per_option_equal_shared_when_static() -> None:
    core = _small_belief("fresh-steel-12.7", "analytic", m=80)
    options = sample_options_mm(np.random.default_rng(2), *move_bounds_mm(core), 16)
    p = core.belief.particles
    mean, std = option_means_stds(core.sensor_model, p, core.position_mm + options)
    voters = np.arange(80)
    a = predicted_variances(p, None, mean, std, voters)
    b = predicted_variances(np.broadcast_to(p, (16, *p.shape)), None, mean, std, voters)
    np.testing.assert_allclose(a, b, rtol=1e-6)


def test_count_votes_ties_go_to_lowest_option() -> None:
    var = np.array([[1.0, 0.5, 0.5], [2.0, 1.0, 0.1], [0.2, 0.3, 0.4], [0.9, 0.1, 0.3]])
    best, votes = count_votes(var)
    np.testing.assert_array_equal(votes, [1, 2, 1])
    assert best == 1
    assert count_votes(np.array([[0.0, 1.0], [1.0, 0.0]]))[0] == 0


def test_min_var_prefers_informative_move() -> None:
    # A belief split in two clusters along x: moving toward one cluster separates them; staying does not.
    class _Belief:
        particles = np.concatenate([np.full((50, 2), [-20.0, 0.0]), np.full((50, 2), [20.0, 0.0])]).astype(np.float32)
        particles += np.random.default_rng(0).normal(0, 1.0, particles.shape).astype(np.float32)
        weights = np.full(100, 0.01)

    cond = get_condition("fresh-steel-12.7")
    from electroloc_gym.sensor_models import make_sensor_model

    model = make_sensor_model("analytic", cond)
    options = np.array([[0.0, 0.0], [10.0, 10.0], [-10.0, 10.0]])
    pos = np.array([0.0, 40.0])  # far above both clusters: weak, nearly symmetric readings
    mean, std = option_means_stds(model, _Belief.particles, pos + options)
    var = predicted_variances(_Belief.particles, None, mean, std, np.arange(100))
    assert var[:, 0].mean() > var[:, 1:].mean(axis=1).mean()


def test_min_var_bad_arguments() -> None:
    with pytest.raises(ValueError, match="n_voters"):
        MinVarianceAgent(n_voters=0)
    with pytest.raises(ValueError, match="n_options"):
        MinVarianceAgent(n_options=0)
    with pytest.raises(ValueError, match="exp_floor"):
        MinVarianceAgent(exp_floor=-200.0)
    with pytest.raises(ValueError, match="kernel"):
        predicted_variances(np.zeros((2, 2)), None, np.zeros((1, 2)), np.ones((1, 2)), np.arange(2), kernel="x")
    with pytest.raises(RuntimeError, match="reset"):
        MinVarianceAgent().predict(None)


def test_min_var_seeded_determinism_and_voter_subset() -> None:
    a1 = _run(make_agent("min-var[n_voters=16]", seed=3), seed=5, n_particles=200, max_steps=4)[1]
    a2 = _run(make_agent("min-var[n_voters=16]", seed=3), seed=5, n_particles=200, max_steps=4)[1]
    np.testing.assert_array_equal(a1, a2)
    v = choose_voters(np.random.default_rng(0), 100, 10)
    assert v.size == 10 and np.unique(v).size == 10
    np.testing.assert_array_equal(choose_voters(np.random.default_rng(0), 100, None), np.arange(100))


# ---- zero-crossing ----------------------------------------------------------------------------------
@pytest.mark.parametrize("condition", ["fresh-delrin-12.7", "fresh-steel-38.1"])
def test_zero_crossing_localises_without_belief(condition: str) -> None:
    agent = make_agent("zero-crossing")
    _, _, info, env = _run(agent, condition, seed=1, n_particles=16)
    assert agent.done and agent.estimate_mm is not None
    err = np.abs(np.asarray(agent.estimate_mm) - np.asarray(env.unwrapped.condition.target_xy_mm))
    assert np.all(err < 1.5), err
    assert agent.env_kwargs["n_particles"] == 16  # the belief is not used


def test_zero_crossing_gives_up_on_a_tiny_budget() -> None:
    agent = ZeroCrossingAgent(max_observations=10)
    _run(agent, "fresh-steel-12.7", seed=0, n_particles=16)
    assert agent.estimate_mm is None


def test_zero_crossing_bad_arguments() -> None:
    with pytest.raises(ValueError, match="n_average"):
        ZeroCrossingAgent(n_average=0)
    with pytest.raises(ValueError, match="k_sigma"):
        ZeroCrossingAgent(k_sigma=-1.0)
    with pytest.raises(ValueError, match="refine_offsets_mm"):
        ZeroCrossingAgent(refine_offsets_mm=())


def test_zero_crossing_line_zero_is_the_least_squares_zero() -> None:
    rng = np.random.default_rng(7)
    for _ in range(200):
        n = int(rng.integers(2, 10))
        ts = list(rng.uniform(-60.0, 60.0) + np.sort(rng.uniform(-3.0, 3.0, n)))
        vs = list(rng.normal(0.0, 1e-3) + rng.uniform(-1e-3, 1e-3) * (np.asarray(ts) - ts[0]) + rng.normal(0, 1e-5, n))
        tq, vq = [Fraction(t) for t in ts], [Fraction(v) for v in vs]  # the exact least-squares zero
        tm, vm = sum(tq) / n, sum(vq) / n
        slope = sum((t - tm) * (v - vm) for t, v in zip(tq, vq)) / sum((t - tm) ** 2 for t in tq)
        exact = float(tm - vm / slope)
        assert _line_zero(ts, vs) == pytest.approx(exact, rel=1e-12, abs=1e-9)
        fit = np.polyfit(ts, vs, 1)  # the textbook fit it stands for, up to rounding
        assert _line_zero(ts, vs) == pytest.approx(-fit[1] / fit[0], rel=1e-7, abs=1e-6)
    assert _line_zero([1.0], [0.5]) is None  # one point
    assert _line_zero([2.0, 2.0, 2.0], [0.1, -0.1, 0.3]) is None  # no spread in position: no slope
    assert _line_zero([1.0, 2.0, 3.0], [0.2, 0.2, 0.2]) is None  # flat: no crossing


def test_benchmark_records_do_not_depend_on_the_blas_kernel(tmp_path: Path) -> None:
    """A trial's record is the same whichever kernels OpenBLAS picks for the CPU (its generic x86-64 ones here):
    zero-crossing's line fit, the networks' and the planners' matrix products.
    """
    from electroloc_gym.bench.schema import TIMING_KEYS

    agents = "zero-crossing,ppo-belief,ppo-raw-framestack,pursuit,infotaxis,eedi"
    records = []
    for kernel in (None, "Prescott"):
        env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
        env.update({} if kernel is None else {"OPENBLAS_CORETYPE": kernel})
        out = tmp_path / str(kernel)
        args = ["--agents", agents, "--conditions", "fresh-steel-12.7", "--trials", "6", "--workers", "1"]
        cli = [sys.executable, "-m", "electroloc_gym.cli", "bench", *args, "--out", str(out), "--no-progress"]
        subprocess.run(cli, env=env, check=True, capture_output=True, timeout=300)
        lines = (out / "trials.jsonl").read_text(encoding="utf-8").splitlines()
        records.append(
            {
                (r["agent"], r["trial"]): {k: v for k, v in r.items() if k not in TIMING_KEYS}
                for r in map(json.loads, lines)
            }
        )
    zero_crossing = [r["estimate"] for (agent, _), r in records[0].items() if agent == "zero-crossing"]
    assert len(records[0]) == 36 and sum(e is not None for e in zero_crossing) >= 4
    assert records[0] == records[1]  # bit for bit (JSON keeps every digit of a float)


def test_zero_crossing_table1_layout() -> None:
    cond = ZeroCrossingAgent.adapt_condition(get_condition("salt-steel-38.1"))
    assert cond.start_half_width_mm == 75.0 and cond.allowed_half_width_mm == 155.0
    assert cond.target_xy_mm == (0.0, 0.0)
