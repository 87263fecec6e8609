"""The torch core against the numba core: operation by operation on the same inputs and the same draws,
determinism, independence of N, the compiled capture, the refusals and the make_vec hook.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

torch = pytest.importorskip("torch")

import electroloc_gym  # noqa: E402,F401 - registers the ids
from electroloc_gym.contract.observation import belief_observation, condition_descriptor  # noqa: E402
from electroloc_gym.contract.params import EnvParams  # noqa: E402
from electroloc_gym.engines.torch_core import belief_update as F  # noqa: E402
from electroloc_gym.engines.torch_core import sim  # noqa: E402
from electroloc_gym.engines.torch_core.calibration import tables_from_draws  # noqa: E402
from electroloc_gym.engines.torch_core.consts import TorchConsts  # noqa: E402
from electroloc_gym.engines.torch_core.rng import bits32, mix32  # noqa: E402
from electroloc_gym.envs.torch_vector import TorchElectroLocVectorEnv, numpy_view  # noqa: E402
from electroloc_gym.kernels import loglik_assimilate  # noqa: E402
from electroloc_gym.kernels.streams import normal_table, table_normal_indices  # noqa: E402
from electroloc_gym.sensor_models import AnalyticSensorModel, CalibratedSensorModel  # noqa: E402
from electroloc_gym.sensor_models.calibrated import (  # noqa: E402
    DEFAULT_CALIBRATION,
    PAPER_CALIBRATION,
    calibration_coefficients,
    noise_free_calibration_grid,
)
from electroloc_gym.world.conditions import PRESET_NAMES, get_condition  # noqa: E402

torch.set_num_threads(1)
CPU = torch.device("cpu")
M = 2500


def consts(**kwargs):
    return TorchConsts.build(EnvParams.from_kwargs("localize", kwargs, "ElectroLoc-v0"), CPU)


def to_torch_layout(coef: np.ndarray, n1: int, stride: int) -> np.ndarray:
    """numba rows a·n1 + b → the torch core's rows a·stride + b (the last row: outside)."""
    out = np.zeros((stride * stride + 1, 8), dtype=np.float32)
    rows = (np.arange(n1)[:, None] * stride + np.arange(n1)[None, :]).reshape(-1)
    out[rows] = coef[:-1]
    out[-1] = coef[-1]
    return out


# ---- the generator ---------------------------------------------------------------------------------
def test_mix32_is_lowbias32():
    """The hash equals Wellons' lowbias32 computed with numpy's uint32 arithmetic (wrapping)."""
    x = np.random.default_rng(0).integers(0, 2**32, 10_000, dtype=np.uint64).astype(np.uint32)
    y = x.copy()
    with np.errstate(over="ignore"):
        y ^= y >> np.uint32(16)
        y *= np.uint32(0x7FEB352D)
        y ^= y >> np.uint32(15)
        y *= np.uint32(0x846CA68B)
        y ^= y >> np.uint32(16)
    got = mix32(torch.tensor(x.astype(np.int64)))
    np.testing.assert_array_equal(got.numpy(), y.astype(np.int64))


def test_draws_are_uniform_bits():
    """Each of the 32 bits of the words is a fair coin (within 5 σ over 200 000 words)."""
    w = bits32(torch.tensor([12345, 678], dtype=torch.int64), 100_000).reshape(-1).numpy()
    frac = np.array([((w >> b) & 1).mean() for b in range(32)])
    assert np.all(np.abs(frac - 0.5) < 5 * 0.5 / np.sqrt(w.size))


# ---- operation by operation ------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["fresh-steel-12.7", "salt-delrin-38.1"])
def test_calibrated_likelihood_matches_numba(name):
    c = get_condition(name)
    model = CalibratedSensorModel(c, seed=3)
    coef = calibration_coefficients(c, 3, DEFAULT_CALIBRATION, out=np.empty_like(model._coef, dtype=np.float32))
    n1 = model.grid_mm.size - 1
    rng = np.random.default_rng(1)
    h = c.allowed_half_width_mm
    parts = rng.uniform(-h, h, (4, 2, M)).astype(np.float32)
    carriage = rng.uniform(-h, h, (4, 2)).astype(np.float32)
    reading = rng.normal(0, 0.5, 4).astype(np.float32)
    off = (parts - carriage[:, :, None]).transpose(0, 2, 1)
    want = model.log_likelihood(reading[:, None], off.astype(np.float32)).astype(np.float32)
    mean_std = model.mean_std(off.astype(np.float32))
    want = want - 0.0 * mean_std[0]  # the model's own float32 path
    table = torch.tensor(np.stack([to_torch_layout(coef, n1, n1 + 5)] * 4))
    got = F.calibrated_log_likelihood(
        torch.tensor(parts),
        torch.tensor(carriage),
        torch.full((4,), np.float32(model.grid_mm[0])),
        torch.full((4,), np.float32(1.0 / 4.0)),
        torch.full((4,), n1),
        n1 + 5,
        table,
        torch.tensor(reading),
    ).numpy()
    np.testing.assert_allclose(got, want, rtol=2e-5, atol=2e-4)


def test_analytic_likelihood_matches_numba():
    c = get_condition("salt-steel-12.7")
    model = AnalyticSensorModel(c)
    rng = np.random.default_rng(2)
    parts = rng.uniform(-50, 50, (3, 2, M)).astype(np.float32)
    carriage = rng.uniform(-50, 50, (3, 2)).astype(np.float32)
    reading = rng.normal(0, 1, 3)
    off = (parts - carriage[:, :, None]).transpose(0, 2, 1)
    want = model.log_likelihood(reading[:, None], off)
    k = consts(condition="salt-steel-12.7", sensor_model="analytic")
    dip = tuple(d.repeat(3).to(torch.float32) for d in (k.dip_h, k.dip_z2, k.dip_k, k.dip_strength))
    got = F.analytic_log_likelihood(
        torch.tensor(parts),
        torch.tensor(carriage),
        dip,
        k.dip_scale.repeat(3).float(),
        k.saturation_V.repeat(3).float(),
        k.noise_V.repeat(3).float(),
        torch.tensor(reading, dtype=torch.float32),
    ).numpy()
    assert want.dtype == np.float32
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-3)


def test_true_reading_matches_physics():
    from electroloc_gym.world.sensor import expected_reading

    k = consts(condition="random")
    s = sim.empty_state(k, 8)
    rng = np.random.default_rng(3)
    s["cond"] = torch.arange(8)
    s["target_mm"] = torch.tensor(rng.uniform(-40, 40, (8, 2)))
    s["position_mm"] = torch.tensor(rng.uniform(-40, 40, (8, 2)))
    got = sim.true_reading_V(k, s).numpy()
    pool = EnvParams.from_kwargs("localize", {"condition": "random"}, "ElectroLoc-v0").options.conditions()
    off = s["target_mm"].numpy() - s["position_mm"].numpy()
    want = np.array([expected_reading(pool[i], off[i], saturate=False) for i in range(8)])
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_resampling_and_statistics_match_numba(seed):
    """Same log-likelihoods, offsets and jitter draws: the same resampled clouds (indices equal away from
    ties), means, covariances and histogram counts.
    """
    rng = np.random.default_rng(seed)
    k, h = 6, 50.0
    src = rng.uniform(-h, h, (k, 2, M)).astype(np.float32)
    origin = rng.uniform(-h, h, (k, 2)).astype(np.float32)
    centre = rng.normal(0, 20, (k, 2, 1))
    ll = (-0.5 * ((src - centre) / rng.uniform(3, 30, (k, 1, 1))) ** 2).sum(axis=1).astype(np.float32)
    u0 = rng.random(k)
    jit = np.stack([table_normal_indices(rng, 2 * M) for _ in range(k)])
    half = np.full(k, h, dtype=np.float32)
    out = np.empty_like(src)
    mean, cov, counts = np.empty((k, 2)), np.empty((k, 2, 2)), np.empty((k, 64))
    assert (
        loglik_assimilate(ll, src.copy(), origin, u0, jit, normal_table(), half, out, mean, cov, 2 * half, 8, counts)
        == -1
    )
    table = torch.tensor(normal_table())
    j = torch.tensor(jit.astype(np.int64))
    got, idx = F.resample(
        torch.tensor(ll), torch.tensor(src), torch.tensor(u0), j[:, 0::2], j[:, 1::2], table, torch.tensor(half)
    )
    same = (got.numpy() == out).all(axis=1)
    assert same.mean() > 0.999  # a pointer within float rounding of a cumulative weight may pick its neighbour
    gmean, gcov, gcounts = F.statistics(got, torch.tensor(origin), torch.tensor(2 * half))
    np.testing.assert_allclose(gmean.numpy(), mean, rtol=0, atol=1e-3)
    np.testing.assert_allclose(gcov.numpy(), cov, rtol=1e-3, atol=1e-3)
    assert np.abs(gcounts.numpy() - counts).sum(axis=1).max() <= 2 * (~same).sum(axis=1).max()
    # on the same cloud the statistics agree to float64 rounding and the counts exactly
    mean2, cov2 = np.empty((k, 2)), np.empty((k, 2, 2))
    from electroloc_gym.kernels import egocentric_counts, mean_cov_rows

    mean_cov_rows(out[:, 0], out[:, 1], mean2, cov2)
    counts2 = np.empty((k, 64))
    egocentric_counts(out[:, 0], out[:, 1], origin, 2 * half, 8, counts2)
    m3, c3, n3 = F.statistics(torch.tensor(out), torch.tensor(origin), torch.tensor(2 * half))
    np.testing.assert_allclose(m3.numpy(), mean2, rtol=1e-12)
    np.testing.assert_allclose(c3.numpy(), cov2, rtol=1e-9)
    np.testing.assert_array_equal(n3.numpy(), counts2)


def test_systematic_indices_are_the_search_bit_for_bit():
    gen = torch.Generator().manual_seed(4)
    m = 257
    w = torch.rand((40, m), generator=gen, dtype=torch.float64)
    w[:8] = 0.0  # flat runs of the cumulative weights: repeated entries
    w[:8, ::7] = 1.0
    w[8:12] = torch.rand((4, m), generator=gen, dtype=torch.float64) ** 40  # a few heavy particles
    cum = torch.cumsum(w / w.sum(1, keepdim=True), 1)
    cum = cum / cum[:, -1:]
    u0 = torch.rand(40, generator=gen, dtype=torch.float64)
    u0[:4] = 0.0
    ptr = (u0[:, None] + torch.arange(m, dtype=torch.float64)[None, :]) / m
    cum[12:20, 5:20] = ptr[12:20, 10:25]  # ties: entries that are pointers exactly
    cum[12:20] = torch.cummax(cum[12:20], 1).values
    want = torch.searchsorted(cum, ptr, right=True)
    assert torch.equal(F.systematic_indices(cum, u0), want)


def test_blocked_hash_is_the_one_pass_hash(monkeypatch):
    from electroloc_gym.engines.torch_core import rng

    key = torch.randint(0, 2**32, (37,), dtype=torch.int64, generator=torch.Generator().manual_seed(0))
    whole = bits32(key, 300, start=5)  # 11,100 words: one pass at the default block size
    monkeypatch.setattr(rng, "CPU_BLOCK_WORDS", 1000)  # 3 envs per block
    assert torch.equal(bits32(key, 300, start=5), whole)
    monkeypatch.setattr(rng, "CPU_BLOCK_WORDS", 10)  # fewer words than one env's: one env per block
    assert torch.equal(bits32(key, 300, start=5), whole)


def test_resample_degenerate_weights_are_uniform():
    """All log-likelihoods −inf (no finite maximum): every weight 1, as the numba kernel."""
    ll = torch.full((1, 8), -float("inf"))
    parts = torch.arange(16, dtype=torch.float32).reshape(1, 2, 8)
    zero = torch.full((1, 8), 32768)  # the table's entry nearest 0
    _, idx = F.resample(
        ll,
        parts,
        torch.tensor([0.5], dtype=torch.float64),
        zero,
        zero,
        torch.tensor(normal_table()),
        torch.tensor([100.0]),
    )
    np.testing.assert_array_equal(idx.numpy(), [list(range(8))])


@pytest.mark.parametrize("protocol", [DEFAULT_CALIBRATION, PAPER_CALIBRATION])
@pytest.mark.parametrize("name", ["fresh-steel-12.7", "salt-delrin-38.1"])
def test_calibration_matches_numba_on_the_same_draws(name, protocol):
    cond = get_condition(name)
    seed = 11
    nf = noise_free_calibration_grid(cond, protocol)
    s, n = nf.shape[0], nf.shape[1]
    idx = table_normal_indices(np.random.default_rng(seed), nf.size).reshape(s, n, n).astype(np.int64)
    want = calibration_coefficients(cond, seed, protocol, out=np.empty(((n - 1) ** 2 + 1, 8), dtype=np.float32))
    k = consts(condition=name, calibration=protocol)
    got = tables_from_draws(k, torch.zeros(1, dtype=torch.int64), lambda t: torch.tensor(idx[t])[None])[0].numpy()
    np.testing.assert_allclose(got, to_torch_layout(want, n - 1, k.grid_n - 1), rtol=1e-5, atol=1e-7)


def test_belief_observation_matches_numba():
    rng = np.random.default_rng(4)
    k = 5
    carriage = rng.uniform(-50, 50, (k, 2))
    reading = rng.normal(0, 2, k)
    mean = rng.uniform(-50, 50, (k, 2))
    a = rng.normal(0, 10, (k, 2, 2))
    cov = a @ a.transpose(0, 2, 1)
    hist = rng.dirichlet(np.ones(64), k)
    n_obs = rng.integers(1, 35, k)
    half, noise, sat = np.full(k, 50.0), np.full(k, 0.02), np.full(k, 10.0)
    desc = np.stack([condition_descriptor(get_condition(p)) for p in PRESET_NAMES[:k]])
    want = belief_observation(carriage, reading, mean, cov, hist, n_obs, 35, half, noise, sat, 10.0, desc)
    t = torch.tensor
    got = F.belief_observation(
        t(carriage), t(reading), t(mean), t(cov), t(hist), t(n_obs), 35, t(half), t(noise), t(sat), 10.0, t(desc)
    ).numpy()
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-7)


# ---- the env ---------------------------------------------------------------------------------------
def rollout(env, steps, seed, n):
    obs, _ = env.reset(seed=seed)
    out = [obs.clone()]
    rng = np.random.default_rng(7)
    acts = rng.uniform(-1, 1, (steps, 64, 2)).astype(np.float32)
    for t in range(steps):
        obs, r, te, tr, _ = env.step(torch.tensor(acts[t, :n]))
        out.append(torch.cat([obs, r[:, None].float(), te[:, None].float(), tr[:, None].float()], 1))
    return out


def test_same_seed_same_trajectory_and_independent_of_n():
    kw = dict(condition="random", randomize_target=True, n_particles=400)
    a = rollout(TorchElectroLocVectorEnv(num_envs=4, **kw), 12, [5, 6, 7, 8], 4)
    b = rollout(TorchElectroLocVectorEnv(num_envs=4, **kw), 12, [5, 6, 7, 8], 4)
    c = rollout(TorchElectroLocVectorEnv(num_envs=2, **kw), 12, [5, 6], 2)
    for x, y, z in zip(a, b, c, strict=True):
        assert torch.equal(x, y)
        assert torch.equal(x[:2, : z.shape[1]] if x.shape[1] == z.shape[1] else x[:2], z)


def test_episodes_end_and_autoreset():
    env = TorchElectroLocVectorEnv(num_envs=8, n_particles=500, max_observations=5)
    env.reset(seed=0)
    done_before = torch.zeros(8, dtype=torch.bool)
    for _ in range(7):
        obs, r, te, tr, info = env.step(torch.zeros(8, 2))
        assert torch.all(r[done_before] == 0) and not torch.any((te | tr)[done_before])
        assert torch.all(r[~done_before] == -1)
        assert torch.all(info["n_observations"] <= 5)
        done_before = te | tr
        assert obs.shape == (8, 81) and obs.dtype == torch.float32 and torch.all(obs.abs() <= 1)


@pytest.mark.parametrize(
    "kw",
    [
        dict(observation="raw"),
        dict(action_type="discrete"),
        dict(sensor_model="analytic"),
        dict(calibration_seed=3, condition="random"),
    ],
)
def test_options_run_and_fit_their_spaces(kw):
    env = TorchElectroLocVectorEnv(num_envs=3, n_particles=300, **kw)
    obs, _ = env.reset(seed=1)
    for _ in range(3):
        act = torch.as_tensor(env.action_space.sample())
        obs, *_ = env.step(act)
    assert env.single_observation_space.contains(obs[0].numpy())


def test_fixed_calibration_seed_is_the_numba_table():
    k = consts(calibration_seed=5)
    want = calibration_coefficients(
        get_condition("fresh-steel-12.7"), 5, DEFAULT_CALIBRATION, out=np.empty((50 * 50 + 1, 8), dtype=np.float32)
    )
    np.testing.assert_array_equal(k.fixed_table[0].numpy(), to_torch_layout(want, 50, k.grid_n - 1))


def test_make_vec_backend_torch():
    env = gym.make_vec(
        "ElectroLoc-v0",
        num_envs=3,
        vectorization_mode="vector_entry_point",
        backend="torch",
        device="cpu",
        n_particles=200,
    )
    assert isinstance(env, TorchElectroLocVectorEnv)
    obs, info = env.reset(seed=0)
    assert isinstance(obs, torch.Tensor) and obs.device.type == "cpu"
    if not hasattr(gym.wrappers.vector, "ArrayConversion"):  # gymnasium 1.1: the view is refused in one line
        with pytest.raises(RuntimeError, match="needs gymnasium >= 1.2"):
            numpy_view(env)
        return
    view = numpy_view(env)
    obs, _ = view.reset(seed=0)
    obs, r, te, tr, _ = view.step(np.zeros((3, 2), dtype=np.float32))
    assert isinstance(obs, np.ndarray) and isinstance(r, np.ndarray) and obs.shape == (3, 81)
    numba_env = gym.make_vec("ElectroLoc-v0", num_envs=2, vectorization_mode="vector_entry_point", n_particles=100)
    assert not isinstance(numba_env, TorchElectroLocVectorEnv)


@pytest.mark.parametrize(
    ("env_id", "kw", "match"),
    [
        ("ElectroLocGlobal-v0", {}, "implements"),
        ("ElectroLocUnknownTarget-v0", {}, "implements"),
        ("ElectroLoc-v0", {"backend": "jax"}, "backend must be one of"),
        ("ElectroLoc-v0", {"gain_levels": (0.5, 1.0)}, "gain_levels"),
        ("ElectroLoc-v0", {"distractors": 2}, "distractors"),
        ("ElectroLoc-v0", {"sensor_layout": "line-4"}, "sensor_layout: backend='torch' takes only"),
        ("ElectroLoc-v0", {"device": "nonsense"}, "device must be"),
        ("ElectroLoc-v0", {"autoreset_mode": "same_step"}, "autoreset_mode"),
    ],
)
def test_refusals_are_one_clear_error(env_id, kw, match):
    kw = {"backend": "torch", **kw}
    with pytest.raises(ValueError, match=match):
        gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **kw)


def test_bad_actions_are_refused():
    env = TorchElectroLocVectorEnv(num_envs=2, n_particles=50)
    with pytest.raises(RuntimeError, match="reset"):
        env.step(torch.zeros(2, 2))
    env.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        env.step(torch.zeros(3, 2))
