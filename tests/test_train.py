"""Tests of train/: strict YAML config, wrappers, a tiny real training run, save/load of policies."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from train_fixtures import TINY_YAML  # noqa: E402

import electroloc_gym  # noqa: E402,F401
from electroloc_gym.train.callbacks import evaluate_agent, save_model_dir  # noqa: E402
from electroloc_gym.train.config import ConfigError, algo_kwargs, load_hyperparams, resolve_hyperparams  # noqa: E402
from electroloc_gym.train.policy import SB3Agent, load_policy  # noqa: E402
from electroloc_gym.train.wrappers import FlatFrameStack, FrameStacker, PotentialShaping, spread_potential  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
FAST_ENV = {"condition": "random", "n_particles": 100, "sensor_model": "analytic"}


def _subprocess_env() -> dict[str, str]:
    env = dict(os.environ, OMP_NUM_THREADS="1", MKL_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), env.get("PYTHONPATH", "")])
    return env


# ---------------------------------------------------------------------------------------- config
def _write(tmp_path: Path, text: str, name: str = "hp.yml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_config_default_is_inherited_and_env_section_wins(tmp_path):
    p = _write(tmp_path, "default: {n_steps: 32, gamma: 0.9}\nElectroLoc-v0: {gamma: 0.95}\n")
    hp = resolve_hyperparams(p, "ppo", "ElectroLoc-v0")
    assert hp == {"n_steps": 32, "gamma": 0.95}
    assert resolve_hyperparams(p, "ppo", "Other-v0") == {"n_steps": 32, "gamma": 0.9}


def test_config_rejects_unknown_keys_with_a_clear_message(tmp_path):
    p = _write(tmp_path, "ElectroLoc-v0: {n_step: 32}\n")
    with pytest.raises(ConfigError, match=r"unknown key\(s\) \['n_step'\].*allowed"):
        load_hyperparams(p, "ppo")
    # A SAC-only keyword is unknown to PPO.
    with pytest.raises(ConfigError, match="buffer_size"):
        load_hyperparams(_write(tmp_path, "default: {buffer_size: 10}\n"), "ppo")
    with pytest.raises(ConfigError, match="normalize has unknown"):
        load_hyperparams(_write(tmp_path, "default: {normalize: {norm_ob: true}}\n"), "ppo")


@pytest.mark.parametrize("body, pattern", [
    ("default: {frame_stack: 0}", "frame_stack"),
    ("default: {shaping_coef: -1}", "shaping_coef"),
    ("default: {learning_rate: fast}", "learning_rate"),
    ("default: {policy_kwargs: {activation_fn: sigmoidish}}", "activation_fn"),
    ("default: [1, 2]", "section 'default' must be a mapping"),
    ("- a\n- b", "top level"),
    ("default: {n_steps: [1, 2", "not valid YAML"),
])
def test_config_rejects_bad_values(tmp_path, body, pattern):
    with pytest.raises(ConfigError, match=pattern):
        load_hyperparams(_write(tmp_path, body + "\n"), "ppo")


def test_config_missing_file_and_section_and_algo(tmp_path):
    with pytest.raises(ConfigError, match="no such file"):
        load_hyperparams(tmp_path / "nope.yml", "ppo")
    with pytest.raises(ConfigError, match="no section"):
        resolve_hyperparams(_write(tmp_path, "Other-v0: {n_steps: 8}\n"), "ppo", "ElectroLoc-v0")
    with pytest.raises(ConfigError, match="--algo must be one of"):
        load_hyperparams(_write(tmp_path, "default: {}\n"), "ppo2")


def test_shipped_hyperparams_are_valid():
    hp_dir = REPO / "train" / "hyperparams"
    for name, algo in (("ppo.yml", "ppo"), ("sac.yml", "sac"), ("ppo_framestack.yml", "ppo"),
                       ("recurrentppo.yml", "recurrentppo")):
        hp = resolve_hyperparams(hp_dir / name, algo, "ElectroLoc-v0")
        assert hp["env_kwargs"]["condition"] == "random"
        algo_kwargs(hp)  # builds (schedules, activations) without error


def test_algo_kwargs_builds_schedule_and_activation():
    import torch.nn as nn

    kw = algo_kwargs({"learning_rate": "lin_1e-3", "policy_kwargs": {"activation_fn": "relu"}, "frame_stack": 4})
    assert "frame_stack" not in kw
    assert kw["learning_rate"](1.0) == pytest.approx(1e-3) and kw["learning_rate"](0.5) == pytest.approx(5e-4)
    assert kw["policy_kwargs"]["activation_fn"] is nn.ReLU


def test_cli_rejects_malformed_env_kwargs(capsys):
    from electroloc_gym.train.__main__ import main

    assert main(["--env-kwargs", "condition"]) == 2
    assert "key=value" in capsys.readouterr().err
    assert main(["--timesteps", "0"]) == 2


# -------------------------------------------------------------------------------------- wrappers
def test_frame_stack_wrapper_matches_the_agent_stacker():
    env = FlatFrameStack(gym.make("ElectroLoc-v0", observation="raw", **FAST_ENV), 4)
    plain = gym.make("ElectroLoc-v0", observation="raw", **FAST_ENV)  # same seed, same actions: same frames
    assert env.observation_space.shape == (12,)
    stacker = FrameStacker(4, 3)
    obs, _ = env.reset(seed=3)
    raw, _ = plain.reset(seed=3)
    stacker.reset()
    np.testing.assert_array_equal(obs, stacker.push(raw))
    np.testing.assert_array_equal(obs[:9], 0.0)
    for _ in range(5):
        action = np.array([0.5, -0.5], dtype=np.float32)
        obs, _, term, trunc, _ = env.step(action)
        raw, *_ = plain.step(action)
        np.testing.assert_array_equal(obs, stacker.push(raw))
        assert env.observation_space.contains(obs)
        if term or trunc:
            break
    obs, _ = env.reset(seed=4)
    np.testing.assert_array_equal(obs[:9], 0.0)


def test_potential_shaping_telescopes():
    """With γ = 1 the shaped return = the true return − Φ(s₀) (Φ(terminal) = 0 on success)."""
    env = PotentialShaping(gym.make("ElectroLoc-v0", **FAST_ENV), coef=2.0, gamma=1.0)
    for seed in range(3):
        _, info = env.reset(seed=seed)
        phi0 = spread_potential(info["spread_mm"], 10.0, 2.0)
        shaped, true, done = 0.0, 0.0, False
        rng = np.random.default_rng(seed)
        while not done:
            _, r, term, trunc, info = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
            shaped += r
            true += -1.0
            done = term or trunc
        phi_end = 0.0 if term else spread_potential(info["spread_mm"], 10.0, 2.0)
        assert shaped == pytest.approx(true + phi_end - phi0, abs=1e-9)
    with pytest.raises(ValueError, match="shaping_coef"):
        PotentialShaping(gym.make("ElectroLoc-v0", **FAST_ENV), coef=-1.0, gamma=0.99)


# ------------------------------------------------------------------------ save / load / reproduce
def _in_process_model(frame_stack: int = 1, observation: str = "belief"):
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    def thunk():
        env = gym.make("ElectroLoc-v0", observation=observation, **FAST_ENV)
        return FlatFrameStack(env, frame_stack) if frame_stack > 1 else env

    venv = VecNormalize(DummyVecEnv([thunk]), norm_reward=False)
    venv.seed(0)
    venv.reset()
    for _ in range(20):  # non-trivial running statistics
        venv.step(np.random.default_rng(0).uniform(-1, 1, (1, 2)).astype(np.float32))
    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=32, seed=0, device="cpu",
                policy_kwargs={"net_arch": [16]})
    return model, venv


def _rollout_actions(agent, seed: int, n: int = 8, observation: str = "belief") -> np.ndarray:
    env = gym.make("ElectroLoc-v0", observation=observation, **FAST_ENV)
    obs, _ = env.reset(seed=seed)
    agent.reset(env)
    out = []
    for _ in range(n):
        a, _ = agent.predict(obs, deterministic=True)
        out.append(np.asarray(a))
        obs, _, term, trunc, _ = env.step(a)
        if term or trunc:
            break
    return np.array(out)


@pytest.mark.parametrize("frame_stack, observation", [(1, "belief"), (3, "raw")])
def test_saved_model_reproduces_actions_after_reload(tmp_path, frame_stack, observation):
    model, venv = _in_process_model(frame_stack, observation)
    cfg = {"algo": "ppo", "frame_stack": frame_stack, "env_kwargs": {"observation": observation, "n_particles": 100}}
    save_model_dir(model, tmp_path / "m", cfg)
    assert {p.name for p in (tmp_path / "m").iterdir()} == {"model.zip", "config.yml", "policy.json",
                                                            "policy.safetensors"}
    live = SB3Agent(model, obs_rms=venv.obs_rms, clip_obs=venv.clip_obs, epsilon=venv.epsilon,
                    frame_stack=frame_stack)
    loaded = load_policy(tmp_path / "m")
    assert loaded.env_kwargs == {"observation": observation, "action_type": "continuous"}
    assert loaded.frame_stack == frame_stack
    for seed in (1, 2):
        a_live = _rollout_actions(live, seed, observation=observation)
        np.testing.assert_array_equal(a_live, _rollout_actions(loaded, seed, observation=observation))
        np.testing.assert_array_equal(a_live, _rollout_actions(load_policy(tmp_path / "m" / "model.zip"), seed,
                                                               observation=observation))
    # The agent normalises with the frozen statistics exactly as VecNormalize does.
    obs = gym.make("ElectroLoc-v0", observation=observation, **FAST_ENV).reset(seed=5)[0]
    loaded.reset(None)
    x = loaded.preprocess(obs)
    stacked = FrameStacker(frame_stack, obs.shape[0])
    np.testing.assert_allclose(x[0], venv.normalize_obs(stacked.push(obs)), rtol=1e-6, atol=1e-6)


def test_batch_predict_equals_single_predict(tmp_path):
    model, venv = _in_process_model()
    save_model_dir(model, tmp_path, {"algo": "ppo"})
    agent = load_policy(tmp_path)
    env = gym.make("ElectroLoc-v0", **FAST_ENV)
    obs = np.stack([env.reset(seed=s)[0] for s in range(4)])
    batch, _ = agent.predict(obs)
    singles = []
    for o in obs:
        agent.reset(None)
        singles.append(agent.predict(o)[0])
    np.testing.assert_allclose(batch, np.array(singles), atol=1e-6)


def test_missing_and_corrupt_model_paths_give_clear_errors(tmp_path):
    with pytest.raises(ValueError, match="does not exist"):
        load_policy(tmp_path / "nothing.zip")
    with pytest.raises(ValueError, match="no policy.json"):
        load_policy(tmp_path)
    with pytest.raises(ValueError, match="without model.zip"):
        load_policy(tmp_path, trust_pickle=True)
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "model.zip").write_bytes(b"this is not a zip file")
    with pytest.raises(ValueError, match="trust_pickle"):
        load_policy(bad)
    with pytest.raises(ValueError, match="corrupt"):
        load_policy(bad, trust_pickle=True)
    # A zip that is not an SB3 model (only read with trust_pickle).
    import zipfile

    with zipfile.ZipFile(tmp_path / "other.zip", "w") as zf:
        zf.writestr("hello.txt", "hi")
    with pytest.raises(ValueError, match="not a saved SB3 model|cannot load"):
        load_policy(tmp_path / "other.zip", trust_pickle=True)


# -------------------------------------------------------------------------- a real tiny run
@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("run")
    hp = tmp / "tiny.yml"
    hp.write_text(TINY_YAML)
    out = tmp / "tiny"
    cmd = [sys.executable, "-m", "electroloc_gym.train", "--algo", "ppo", "--env", "ElectroLoc-v0",
           "--env-kwargs", "condition=random", "observation=belief", "randomize_target=true", "n_particles=100",
           "sensor_model=analytic", "--timesteps", "256", "--n-envs", "2", "--seed", "1000",
           "--hyperparams", str(hp), "--out", str(out), "--eval-freq", "128", "--eval-episodes", "3",
           "--checkpoint-freq", "128", "--no-progress", "--no-tensorboard", "--verbose", "0"]
    proc = subprocess.run(cmd, cwd=tmp, env=_subprocess_env(), capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return out


def test_tiny_training_run_writes_a_complete_run_dir(tiny_run):
    for name in ("model.zip", "policy.json", "policy.safetensors", "config.yml", "args.json", "command.txt",
                 "eval.csv", "summary.json", "best/policy.json", "best/model.zip", "checkpoints/step_128/policy.json"):
        assert (tiny_run / name).is_file(), name
    assert not list(tiny_run.rglob("*.pkl"))  # nothing pickled beside SB3's own zip
    assert "python -m electroloc_gym.train --algo ppo" in (tiny_run / "command.txt").read_text()
    assert "training wall time (s): " in (tiny_run / "command.txt").read_text()
    (segment,) = json.loads((tiny_run / "args.json").read_text())["segments"]
    assert segment["args"]["seed"] == 1000 and segment["args"]["env_kwargs"]["n_particles"] == 100
    assert segment["status"] == "finished" and segment["timesteps_end"] >= 256
    rows = (tiny_run / "eval.csv").read_text().strip().splitlines()
    assert rows[0].startswith("timesteps,wall_time_s,episodes,success_rate,median_steps")
    assert len(rows) >= 3  # t = 0, 128, 256
    summary = json.loads((tiny_run / "summary.json").read_text())
    assert summary["timesteps"] >= 256
    norm = json.loads((tiny_run / "policy.json").read_text())["normalization"]
    assert norm["norm_obs"] and len(norm["obs_mean"]) == 81


def test_tiny_model_loads_and_plays_an_episode(tiny_run):
    agent = load_policy(tiny_run)
    assert agent.env_kwargs == {"observation": "belief", "action_type": "continuous"}
    res = evaluate_agent(agent, "ElectroLoc-v0", {**FAST_ENV, "condition": "fresh-steel-12.7"}, [7, 8])
    assert res.episodes == 2 and 1 <= res.median_steps <= 35
    a1 = _rollout_actions(load_policy(tiny_run / "best"), 11)
    a2 = _rollout_actions(load_policy(tiny_run / "best" / "model.zip"), 11)
    np.testing.assert_array_equal(a1, a2)


def test_benchmark_accepts_the_tiny_model(tiny_run):
    from electroloc_gym.baselines.agent import Agent
    from electroloc_gym.bench.agents import make_bench_agent

    agent = make_bench_agent(str(tiny_run))
    assert isinstance(agent, Agent)
    assert agent.env_kwargs["observation"] == "belief"


def test_resume_continues_from_a_checkpoint(tiny_run, tmp_path):
    from electroloc_gym.train.__main__ import main

    out = tmp_path / "resumed"
    rc = main(["--env-kwargs", "n_particles=100", "sensor_model=analytic", "--timesteps", "128", "--n-envs", "2",
               "--hyperparams", str(tiny_run.parent / "tiny.yml"), "--out", str(out),
               "--resume", str(tiny_run / "checkpoints" / "step_128"), "--eval-freq", "1000",
               "--eval-episodes", "2", "--no-progress", "--no-tensorboard", "--verbose", "0"])
    assert rc == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["timesteps"] >= 256  # 128 from the checkpoint + 128 more
    load_policy(out)
    assert main(["--resume", str(tmp_path / "missing"), "--out", str(tmp_path / "x"), "--verbose", "0",
                 "--no-tensorboard"]) == 2


def test_electroloc_train_forwards_to_the_training_script(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "electroloc_gym.cli", "train", "--help"], cwd=tmp_path,
                          env=_subprocess_env(), capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "--hyperparams" in proc.stdout and "--vec-env" in proc.stdout
    assert "``" not in proc.stdout  # plain text, not reST
    for shown in ("(default: dummy)", "(default: 20000)", "(default: ppo)", "(default: 1000)"):
        assert shown in " ".join(proc.stdout.split()), shown


# ------------------------------------------------------------------------ plots and evaluation
def test_learning_curve_plot_from_a_run(tiny_run, tmp_path):
    from electroloc_gym.train.plots import main as plots_main
    from electroloc_gym.train.plots import read_eval_csv

    cols = read_eval_csv(tiny_run)
    assert cols["timesteps"][0] == 0 and len(cols["success_rate"]) == len(cols["median_steps"])
    out = tmp_path / "lc.png"
    assert plots_main([str(tiny_run), "--out", str(out), "--reference", "min-var=0.9,7"]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert plots_main([str(tmp_path / "none"), "--out", str(out)]) == 2


def test_recurrent_policy_carries_and_resets_its_state(tmp_path):
    sb3_contrib = pytest.importorskip("sb3_contrib")
    from stable_baselines3.common.vec_env import DummyVecEnv

    venv = DummyVecEnv([lambda: gym.make("ElectroLoc-v0", observation="raw", **FAST_ENV)])
    model = sb3_contrib.RecurrentPPO("MlpLstmPolicy", venv, n_steps=16, batch_size=16, seed=0, device="cpu",
                                     policy_kwargs={"lstm_hidden_size": 8, "net_arch": [8]})
    save_model_dir(model, tmp_path, {"algo": "recurrentppo", "env_kwargs": {"observation": "raw"}})
    agent = load_policy(tmp_path)
    assert agent.recurrent and agent.env_kwargs["observation"] == "raw"
    first = _rollout_actions(agent, 3, observation="raw")
    assert agent._state is not None  # the LSTM state is kept between calls
    np.testing.assert_array_equal(first, _rollout_actions(agent, 3, observation="raw"))  # reset() clears it
    np.testing.assert_array_equal(first, _rollout_actions(load_policy(tmp_path), 3, observation="raw"))


@pytest.mark.parametrize("action_type", ["continuous", "discrete"])
def test_numpy_fast_path_equals_sb3_predict(action_type):
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv

    venv = DummyVecEnv([lambda: gym.make("ElectroLoc-v0", action_type=action_type, **FAST_ENV)])
    model = PPO("MlpPolicy", venv, n_steps=16, batch_size=16, seed=1, device="cpu",
                policy_kwargs={"net_arch": [32, 16], "log_std_init": 0.0})
    with torch_no_grad():  # push the means outside [-1, 1] so the clip is exercised
        model.policy.action_net.bias.add_(1.5 if action_type == "continuous" else 0.0)
    agent = SB3Agent(model)
    assert agent._numpy_actor is not None
    obs = np.stack([gym.make("ElectroLoc-v0", **FAST_ENV).reset(seed=s)[0] for s in range(16)])
    fast, _ = agent.predict(obs)
    slow, _ = model.predict(obs, deterministic=True)
    if action_type == "continuous":
        np.testing.assert_allclose(fast, slow, atol=1e-5)
        assert fast.max() == 1.0
    else:
        np.testing.assert_array_equal(fast, slow)


def torch_no_grad():
    import torch

    return torch.no_grad()


def test_native_frame_stack_matches_the_flat_frame_stack():
    """--vec-env native stacks with VecFlatFrameStack; it must equal FlatFrameStack (what the agent rebuilds)."""
    native_vec = pytest.importorskip("electroloc_gym.train.native_vec")
    from stable_baselines3.common.vec_env import DummyVecEnv

    from electroloc_gym.train.__main__ import make_env_fn

    kw = {"observation": "raw", **FAST_ENV}
    a = native_vec.make_native_vec_env("ElectroLoc-v0", 2, 5, kw, frame_stack=4)
    b = DummyVecEnv([make_env_fn("ElectroLoc-v0", kw, 4, 0.0, 0.99) for _ in range(2)])
    b.seed(5)
    assert a.observation_space == b.observation_space
    oa, ob = a.reset(), b.reset()
    np.testing.assert_allclose(oa, ob, atol=1e-6)
    rng = np.random.default_rng(0)
    dones = 0
    for _ in range(60):
        act = rng.uniform(-1, 1, (2, 2)).astype(np.float32)
        oa, _, da, ia = a.step(act)
        ob, _, db, ib = b.step(act)
        np.testing.assert_array_equal(da, db)
        np.testing.assert_allclose(oa, ob, atol=1e-5)
        for i in np.flatnonzero(da):  # the final observation is stacked like the others
            np.testing.assert_allclose(ia[i]["terminal_observation"], ib[i]["terminal_observation"], atol=1e-5)
            assert np.any(ia[i]["terminal_observation"][:-3] != 0.0)
        dones += int(da.sum())
    assert dones > 0  # the comparison crossed episode boundaries


def test_frame_stacker_rows_reset_independently():
    s = FrameStacker(2, 1, n_envs=2)
    s.push(np.array([[1.0], [2.0]]))
    s.reset(np.array([False, True]))
    np.testing.assert_array_equal(s.peek(np.array([[5.0], [6.0]])), [[1.0, 5.0], [0.0, 6.0]])
    np.testing.assert_array_equal(s.push(np.array([[3.0], [4.0]])), [[1.0, 3.0], [0.0, 4.0]])
    with pytest.raises(ValueError, match="frame_stack"):
        FrameStacker(0, 3)


def test_evaluation_metrics_are_those_of_the_plain_episode_loop():
    """evaluate_agent (the benchmark's rollout) gives what a plain reset/predict/step loop gives."""
    model, _ = _in_process_model(3, "raw")
    agent = SB3Agent(model, frame_stack=3, env_kwargs={"observation": "raw"})
    kw = {**FAST_ENV, "max_observations": 12}
    seeds = [11, 12, 13]
    env = gym.make("ElectroLoc-v0", **kw, observation="raw")
    steps, errors, success = [], [], []
    for s in seeds:
        obs, info = env.reset(seed=s)
        agent.reset(env)
        done = False
        while not done:
            action, _ = agent.predict(obs, deterministic=True)
            obs, _, term, trunc, info = env.step(action)
            done = term or trunc
        steps.append(info["n_observations"])
        errors.append(info["error_mm"])
        success.append(info["success"])
    res = evaluate_agent(agent, "ElectroLoc-v0", kw, seeds)
    assert res.episodes == 3
    assert res.median_steps == np.median(steps) and res.mean_steps == np.mean(steps)
    assert res.success_rate == np.mean(success)
    assert res.median_error_mm == np.median(errors) and res.mean_error_mm == np.mean(errors)
