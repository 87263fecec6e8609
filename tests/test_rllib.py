"""Training on RLlib: the creator's two entry points, seeds across runners, episode boundaries, one thread per
runner, a tiny PPO iteration in Ray worker processes, and the export that `electroloc bench` runs.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

pytestmark = pytest.mark.rllib  # the rllib extra; the nox session rllib runs these

import electroloc_gym.train.rllib as erl  # noqa: E402
from electroloc_gym.envs import ElectroLocVectorEnv  # noqa: E402
from electroloc_gym.envs.vector import sub_env_seeds  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SMALL = {"n_particles": 60, "max_observations": 6}


def _example():
    spec = importlib.util.spec_from_file_location("example_rllib_ppo", ROOT / "examples" / "rllib_ppo.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _runner_config(seed: int, num_envs: int, **env_kwargs):
    from ray.rllib.algorithms.ppo import PPOConfig

    return (
        PPOConfig()
        .environment(erl.register(), env_config={**SMALL, **env_kwargs})
        .env_runners(num_env_runners=0, num_envs_per_env_runner=num_envs, gym_env_vectorize_mode="vector_entry_point")
        .debugging(seed=seed)
    )


def _runner(seed: int, num_envs: int, worker_index: int = 0, mode: str = "vector_entry_point", **env_kwargs):
    from ray.rllib.env.single_agent_env_runner import SingleAgentEnvRunner

    config = _runner_config(seed, num_envs, **env_kwargs).env_runners(gym_env_vectorize_mode=mode)
    return SingleAgentEnvRunner(config=config, worker_index=worker_index)


@pytest.mark.parametrize(
    ("mode", "vector_class"), [("vector_entry_point", "ElectroLocVectorEnv"), ("sync", "SyncVectorEnv")]
)
def test_rllib_runner_builds_the_registered_creator_in_both_modes(mode: str, vector_class: str) -> None:
    runner = _runner(seed=1, num_envs=2, mode=mode)
    assert type(runner.env.unwrapped).__name__ == vector_class and runner.env.num_envs == 2
    assert sum(len(ep) for ep in runner.sample(num_timesteps=4, random_actions=True)) >= 4


def test_rllib_creator_serves_both_entry_points_and_refuses_same_step() -> None:
    from ray.rllib.env.env_context import EnvContext

    single = erl.make_env(EnvContext({"n_particles": 50}, worker_index=1))
    assert single.observation_space.shape == (81,)
    vec = erl.make_env(EnvContext({"n_particles": 50}, worker_index=1) | {"num_envs": 3})
    assert isinstance(vec.unwrapped, ElectroLocVectorEnv) and vec.num_envs == 3
    assert vec.metadata["autoreset_mode"] is gym.vector.AutoresetMode.NEXT_STEP
    glob = erl.make_env({"env_id": "ElectroLocGlobal-v0", "n_particles": 50, "num_envs": 2})
    assert type(glob.unwrapped).__name__ == "GlobalVectorEnv"
    with pytest.raises(ValueError, match=r"env_config\['autoreset_mode'\]"):
        erl.make_env({"num_envs": 2, "autoreset_mode": "same_step"})
    with pytest.raises(ValueError, match=r"env_config\['env_id'\]"):
        erl.make_env({"env_id": "CartPole-v1"})
    with pytest.raises(ValueError, match="n_particles"):
        erl.make_env({"n_particles": 0, "num_envs": 2})


def test_rllib_sub_env_seeds_come_from_seed_sequence() -> None:
    seeds = sub_env_seeds(5, 4)
    assert seeds[:2] == sub_env_seeds(5, 2)  # sub-env i depends on (seed, i) only
    expected = [
        int.from_bytes(c.generate_state(4, np.uint32).tobytes(), "little") for c in np.random.SeedSequence(5).spawn(4)
    ]
    assert seeds == expected
    runners = [set(sub_env_seeds(100 + k, 8)) for k in range(4)]  # RLlib: runner k reset with seed + k
    assert len(set().union(*runners)) == 32
    for bad in (-1, 1.5, True):
        with pytest.raises(ValueError, match="seed"):
            sub_env_seeds(bad, 2)


def _first_obs(runner) -> np.ndarray:
    episodes = runner.sample(num_timesteps=2, random_actions=True)
    return np.stack([ep.get_observations(0) for ep in episodes])


def test_rllib_two_runners_never_produce_the_same_episodes() -> None:
    n = 3
    first = [_first_obs(_runner(seed=40, num_envs=n, worker_index=k)) for k in (1, 2)]
    rows = np.concatenate(first)
    assert len({r.tobytes() for r in rows}) == 2 * n, "two sub-envs (in one or two runners) started alike"
    # The check can fail: with the seeds s + i the second runner's sub-env i repeats the first's sub-env i + 1.
    offset = [[gym.make("ElectroLoc-v0", **SMALL).reset(seed=40 + k + i)[0] for i in range(n)] for k in (1, 2)]
    assert np.array_equal(offset[1][0], offset[0][1])
    # ... and each runner's sub-envs are the single env reset with the SeedSequence seeds of (seed + k, i)
    # (compared as a set: RLlib does not promise to return a runner's episodes in sub-env order).
    for k, obs in zip((1, 2), first):
        want = {gym.make("ElectroLoc-v0", **SMALL).reset(seed=seed)[0].tobytes() for seed in sub_env_seeds(40 + k, n)}
        assert {o.tobytes() for o in obs} == want


def test_rllib_episode_returns_and_lengths_equal_the_envs() -> None:
    n, seed = 2, 7
    runner = _runner(seed=seed, num_envs=n)
    episodes = [ep for ep in runner.sample(num_timesteps=60, random_actions=True) if ep.is_done]
    metrics = runner.get_metrics()
    assert len(episodes) >= 6
    # Replay every sub-env with a single env: its episodes in order, reset by the env itself (next-step autoreset).
    by_start = {ep.get_observations(0).tobytes(): ep for ep in episodes}
    replayed = []
    for i, s in enumerate(sub_env_seeds(seed, n)):
        env = gym.make("ElectroLoc-v0", **SMALL)
        obs, _ = env.reset(seed=s)
        while obs.tobytes() in by_start:
            ep = by_start.pop(obs.tobytes())
            rewards, done, t = [], False, 0
            while not done:
                obs, r, term, trunc, _ = env.step(ep.get_actions(t))
                rewards.append(r)
                done, t = term or trunc, t + 1
                assert np.array_equal(obs, ep.get_observations(t)), (i, t)
            assert len(ep) == t and ep.get_return() == pytest.approx(sum(rewards), abs=0)
            assert ep.is_terminated == term and ep.is_truncated == trunc
            replayed.append((sum(rewards), t))
            obs, _ = env.reset()
    assert not by_start, "an RLlib episode matched no episode of the envs"
    returns, lengths = np.array(replayed).T
    assert float(metrics["episode_return_mean"]) == pytest.approx(returns.mean())
    assert float(metrics["episode_len_mean"]) == pytest.approx(lengths.mean())
    assert float(metrics["num_episodes"]) == len(replayed)


@pytest.fixture(scope="module")
def ray_local():
    ray = pytest.importorskip("ray")
    started = not ray.is_initialized()
    if started:
        ray.init(
            num_cpus=2, include_dashboard=False, log_to_driver=False, runtime_env={"env_vars": erl.runner_env_vars()}
        )
    yield ray
    if started:
        ray.shutdown()


def test_rllib_ppo_iteration_in_a_worker_exports_a_policy_bench_runs(ray_local, tmp_path: Path) -> None:
    import torch
    from ray.rllib.core import COMPONENT_ENV_TO_MODULE_CONNECTOR, Columns

    from electroloc_gym.policy.load import load_policy

    ex = _example()
    args = ex.parse_args(
        [
            "--num-env-runners",
            "1",
            "--num-envs-per-env-runner",
            "2",
            "--train-batch",
            "64",
            "--n-particles",
            "60",
            "--timesteps",
            "64",
            "--seed",
            "3",
        ]
    )
    erl.warm_kernels(ex.env_config(args))
    algo = ex.build_config(args).build_algo()
    try:
        # The remote runner resolved the registered creator and pinned its threads.
        remote = algo.env_runner_group.foreach_env_runner(
            lambda r: (
                type(r.env.unwrapped).__name__,
                r.env.num_envs,
                os.environ.get("OMP_NUM_THREADS"),
                os.environ.get("NUMBA_NUM_THREADS"),
                __import__("torch").get_num_threads(),
                os.getpid(),
            ),
            local_env_runner=False,
        )
        assert len(remote) == 1 and remote[0][:5] == ("ElectroLocVectorEnv", 2, "1", "1", 1)
        assert remote[0][5] != os.getpid()
        result = algo.train()
        assert result["num_env_steps_sampled_lifetime"] >= 64
        assert result["env_runners"]["num_episodes"] >= 1
        assert 0.0 <= result["env_runners"][erl.SUCCESS_METRIC] <= 1.0
        out = erl.export_ppo(
            algo,
            tmp_path / "model",
            env_id=ex.ENV_ID,
            env_kwargs=ex.ENV_KWARGS,
            hidden=ex.HIDDEN,
            provenance={"seed": 3},
        )
        # The exported policy acts as RLlib's module on the filtered observation.
        agent = load_policy(out)
        env = gym.make("ElectroLoc-v0", n_particles=60)
        obs = np.stack([env.reset(seed=s)[0] for s in range(5)])
        state = algo.env_runner.get_state(components=COMPONENT_ENV_TO_MODULE_CONNECTOR)
        stat = state[COMPONENT_ENV_TO_MODULE_CONNECTOR]["MeanStdFilter"][None]["running_stats"][0]
        from ray.rllib.utils.filter import RunningStat

        rs = RunningStat.from_state(stat)
        x = np.clip((obs - rs.mean) / (rs.std + 1e-6), -10, 10).astype(np.float32)
        module = algo.get_module()
        with torch.no_grad():
            out_rl = module.forward_inference({Columns.OBS: torch.as_tensor(x)})[Columns.ACTION_DIST_INPUTS]
        mean = np.clip(out_rl.numpy()[:, :2], -1, 1)
        ours = np.stack([agent.predict(o, deterministic=True)[0] for o in obs])
        np.testing.assert_allclose(ours, mean, atol=1e-5)
    finally:
        algo.stop()


def test_rllib_progress_plot_skips_iterations_without_episodes(tmp_path: Path) -> None:
    head = "iteration,env_steps,wall_s,episodes,return_mean,length_mean,success_mean\n"
    good = tmp_path / "progress.csv"
    good.write_text(head + "1,100,1.0,5,-9.0,9.0,0.4\n2,200,2.0,5,nan,nan,nan\n3,300,3.0,12,-6.0,6.0,0.9\n")
    png = erl.plot_progress(good, tmp_path / "curve.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    empty = tmp_path / "empty.csv"
    empty.write_text(head + "1,0,1.0,0,nan,nan,nan\n")
    with pytest.raises(ValueError, match="no iteration with finished episodes"):
        erl.plot_progress(empty, tmp_path / "x.png")


@pytest.mark.parametrize(
    "body, pattern",
    [
        (
            "iteration,env_steps,wall_s,episodes,return_mean,success_mean\n1,100,1.0,5,-9.0,0.4\n",
            r"lacks the column\(s\) \['length_mean'\]",
        ),
        (
            "iteration,env_steps,wall_s,episodes,return_mean,length_mean,success_mean\n1,100,1.0,5,-9.0,9.0,0.4\n2,200\n",
            "line 3 is short",
        ),
        (
            "iteration,env_steps,wall_s,episodes,return_mean,length_mean,success_mean\n1,x,1.0,5,-9.0,9.0,0.4\n",
            "line 2: .* must be numbers",
        ),
        ("", r"lacks the column\(s\)"),
    ],
)
def test_rllib_progress_plot_refuses_a_damaged_csv_in_one_line(tmp_path: Path, body: str, pattern: str) -> None:
    bad = tmp_path / "progress.csv"
    bad.write_text(body)
    with pytest.raises(ValueError, match=pattern) as info:
        erl.plot_progress(bad, tmp_path / "x.png")
    assert "\n" not in str(info.value) and not (tmp_path / "x.png").exists()
    bad.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(ValueError, match="cannot read"):
        erl.plot_progress(bad, tmp_path / "x.png")
