"""The copy-pasteable examples in examples/ run as documented, at a tiny budget."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"


def _load(name: str):
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


def test_ppo_minimal_trains_and_evaluates(tmp_path, capsys) -> None:
    torch = pytest.importorskip("torch")
    ppo = _load("ppo_minimal")
    out = tmp_path / "policy.pt"
    result = ppo.main(
        [
            "--total-timesteps",
            "512",
            "--num-steps",
            "32",
            "--num-envs",
            "8",
            "--update-epochs",
            "2",
            "--eval-episodes",
            "4",
            "--save",
            str(out),
        ]
    )
    assert 0.0 <= result["success_rate"] <= 1.0
    assert 1 <= result["median_observations"] <= 35
    text = capsys.readouterr().out
    assert "update 2/2" in text and "evaluation (4 episodes" in text
    state = torch.load(out, weights_only=True)  # plain tensors, no pickled code
    agent = ppo.Agent(81, 2)
    agent.load_state_dict(state)


def test_ppo_minimal_masks_the_reset_steps_of_next_step_autoreset() -> None:
    pytest.importorskip("torch")
    import gymnasium as gym
    import numpy as np

    import electroloc_gym  # noqa: F401

    # The property the example relies on: after a sub-env ends, the next step only resets it.
    envs = gym.make_vec(
        "ElectroLoc-v0",
        num_envs=2,
        vectorization_mode="vector_entry_point",
        max_observations=2,
        n_particles=200,
        sensor_model="analytic",
    )
    envs.reset(seed=0)
    a = np.zeros((2, 2), np.float32)
    _, _, term, trunc, _ = envs.step(a)
    assert np.all(term | trunc)  # the cap of 2 observations is reached on the first step
    obs, reward, term, trunc, info = envs.step(a)
    assert np.all(reward == 0) and not np.any(term | trunc)
    assert np.all(info["n_observations"] == 1)
    envs.close()


def test_ppo_torch_trains_with_the_rollouts_on_the_env_device(tmp_path, capsys) -> None:
    torch = pytest.importorskip("torch")
    ppo = _load("ppo_torch")
    out = tmp_path / "policy.pt"
    result = ppo.main(
        [
            "--device",
            "cpu",
            "--num-envs",
            "16",
            "--num-steps",
            "16",
            "--total-timesteps",
            "512",
            "--update-epochs",
            "2",
            "--eval-episodes",
            "8",
            "--save",
            str(out),
        ]
    )
    assert 0.0 <= result["success_rate"] <= 1.0 and 1.0 <= result["mean_readings"] <= 35.0
    text = capsys.readouterr().out
    assert "update 2/2" in text and "evaluation (8 episodes" in text
    minimal = _load("ppo_minimal")
    agent = minimal.Agent(81, 2)  # the same network as the CPU example's
    saved = torch.load(out, weights_only=True)
    agent.load_state_dict(saved["agent"])
    norm = ppo.RunningNorm(81, torch.device("cpu"))
    norm.load_state_dict(saved["norm"])
    assert float(norm.count) > 512 and bool((norm.var > 0).all())  # every rollout observation merged
    envs = ppo.make_envs(ppo.parse_args(["--device", "cpu"]), 2, randomize_target=False)
    obs, _ = envs.reset(seed=0)
    assert isinstance(obs, torch.Tensor)  # the loop's inputs are tensors on the env's device, no numpy
    envs.close()


def test_ppo_torch_normaliser_and_shaping_follow_sb3_and_the_training_wrapper() -> None:
    torch = pytest.importorskip("torch")
    from electroloc_gym.train.wrappers import spread_potential

    ppo = _load("ppo_torch")
    gen = torch.Generator().manual_seed(0)
    x = torch.randn((300, 5), generator=gen, dtype=torch.float64) * 3.0 + 7.0
    norm = ppo.RunningNorm(5, torch.device("cpu"))
    for part in x.split([1, 99, 200]):  # batches merged one by one give the whole set's moments
        norm.update(part)
    assert torch.allclose(norm.mean, x.mean(0), atol=1e-6)
    assert torch.allclose(norm.var, x.var(0, unbiased=False), rtol=1e-4)
    z = norm(x)
    assert z.dtype == torch.float32
    assert torch.allclose(z.double().mean(0), torch.zeros(5, dtype=torch.float64), atol=1e-4)
    assert float(norm(torch.full((1, 5), 1e6, dtype=torch.float64)).max()) == 10.0  # clipped as VecNormalize
    spread = torch.tensor([40.0, 10.0, 2.5], dtype=torch.float64)
    expect = spread_potential(spread.numpy(), 10.0, 0.7)
    assert torch.allclose(ppo.potential(spread, 0.7, 10.0), torch.as_tensor(expect))


def test_ppo_minimal_rejects_a_budget_below_one_rollout(capsys) -> None:
    pytest.importorskip("torch")
    ppo = _load("ppo_minimal")
    with pytest.raises(SystemExit):
        ppo.parse_args(["--total-timesteps", "10"])
    assert "total_timesteps" in capsys.readouterr().err


def test_training_page_shows_the_example_verbatim() -> None:
    page = (ROOT / "docs" / "training.md").read_text(encoding="utf-8")
    code = (EXAMPLES / "ppo_minimal.py").read_text(encoding="utf-8")
    assert f"```python\n{code}```" in page, "docs/training.md's copy of examples/ppo_minimal.py is out of date"


def test_episode_pictures_example(tmp_path, capsys) -> None:
    pictures = _load("episode_pictures")
    png, gif = tmp_path / "e.png", tmp_path / "e.gif"
    info = pictures.main(["--agent", "rnd-wlk", "--seed", "2", "--out", str(png), "--gif", str(gif)])
    assert png.stat().st_size > 10_000 and gif.stat().st_size > 10_000
    assert f"{info['n_observations']} observations" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        pictures.main(["--agent", "no-such-agent"])
