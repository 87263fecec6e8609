"""The pickle-free policy format: exact actions after reload, refusals, and crafted pickle payloads that never run."""

from __future__ import annotations

import base64
import io
import json
import logging
import os
import pickle
import shutil
import zipfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
pytest.importorskip("safetensors")

import electroloc_gym  # noqa: E402,F401
from electroloc_gym.train.callbacks import save_model_dir  # noqa: E402
from electroloc_gym.train.policy import load_policy  # noqa: E402
from electroloc_gym.train.policy_format import PolicyFormatError, read_export  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
FAST_ENV = {"condition": "random", "n_particles": 100, "sensor_model": "analytic"}


def _observations(n: int = 48, observation: str = "belief", action_type: str = "continuous") -> np.ndarray:
    env = gym.make("ElectroLoc-v0", observation=observation, action_type=action_type, **FAST_ENV)
    env.action_space.seed(0)
    out, (obs, _) = [], env.reset(seed=0)
    while len(out) < n:
        out.append(obs)
        obs, _, term, trunc, _ = env.step(env.action_space.sample())
        if term or trunc:
            obs, _ = env.reset(seed=len(out))
    return np.stack(out).astype(np.float32)


def _trained(algo: str = "ppo", action_type: str = "continuous", observation: str = "belief", frame_stack: int = 1):
    """A briefly trained model on a normalised env (non-trivial weights and statistics)."""
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from electroloc_gym.train.wrappers import FlatFrameStack

    def thunk():
        env = gym.make("ElectroLoc-v0", observation=observation, action_type=action_type, **FAST_ENV)
        return FlatFrameStack(env, frame_stack) if frame_stack > 1 else env

    venv = VecNormalize(DummyVecEnv([thunk, thunk]), norm_reward=False)
    venv.seed(0)
    if algo == "ppo":
        model = PPO("MlpPolicy", venv, n_steps=32, batch_size=32, n_epochs=1, seed=0, device="cpu",
                    policy_kwargs={"net_arch": [32, 16], "log_std_init": -0.3})
    elif algo == "recurrentppo":
        from sb3_contrib import RecurrentPPO

        model = RecurrentPPO("MlpLstmPolicy", venv, n_steps=16, batch_size=16, n_epochs=1, seed=0, device="cpu",
                             policy_kwargs={"lstm_hidden_size": 8, "net_arch": [8]})
    else:
        model = SAC("MlpPolicy", venv, learning_starts=10, buffer_size=200, batch_size=16, seed=0, device="cpu",
                    policy_kwargs={"net_arch": [16]})
    model.learn(64)
    cfg = {"algo": algo, "env_id": "ElectroLoc-v0", "frame_stack": frame_stack, "seed": 0,
           "normalize": {"norm_obs": True, "norm_reward": False},
           "env_kwargs": {"observation": observation, "action_type": action_type, **FAST_ENV}}
    return model, venv, cfg


def _net_input(venv, frames: np.ndarray, frame_stack: int) -> np.ndarray:
    raw = frames.reshape(-1, frame_stack * frames.shape[1]) if frame_stack > 1 else frames
    return venv.normalize_obs(raw).astype(np.float32)


# ----------------------------------------------------------------------------- exact reproduction
@pytest.mark.parametrize("algo, action_type, observation, frame_stack", [
    ("ppo", "continuous", "belief", 1), ("ppo", "discrete", "belief", 1), ("ppo", "continuous", "raw", 4),
    ("sac", "continuous", "belief", 1)])
def test_reloaded_policy_acts_exactly_as_sb3(tmp_path, algo, action_type, observation, frame_stack):
    model, venv, cfg = _trained(algo, action_type, observation, frame_stack)
    save_model_dir(model, tmp_path / "m", cfg)
    agent = load_policy(tmp_path / "m")
    assert agent.env_kwargs == {"observation": observation, "action_type": action_type}
    assert agent.frame_stack == frame_stack
    x = _net_input(venv, _observations(48 * frame_stack, observation, action_type), frame_stack)
    expected, _ = model.predict(x, deterministic=True)
    got, _ = agent.policy.predict(x, deterministic=True)
    np.testing.assert_array_equal(got, expected)  # bit-identical, batch of 48
    # The agent's own preprocessing (stack + frozen statistics) equals VecNormalize's.
    frames = _observations(frame_stack, observation, action_type)
    agent.reset(None)
    for f in frames:
        net_in = agent.preprocess(f)
    np.testing.assert_allclose(net_in[0], _net_input(venv, frames, frame_stack)[0], rtol=1e-6, atol=1e-6)


def test_recurrent_policy_reload_keeps_the_lstm_sequence(tmp_path):
    pytest.importorskip("sb3_contrib")
    model, venv, cfg = _trained("recurrentppo", observation="raw")
    save_model_dir(model, tmp_path, cfg)
    meta = json.loads((tmp_path / "policy.json").read_text())
    assert meta["architecture"]["recurrent"] == {"lstm_hidden_size": 8, "n_lstm_layers": 1, "shared_lstm": False,
                                                 "enable_critic_lstm": True}
    agent = load_policy(tmp_path)
    x = _net_input(venv, _observations(12, "raw"), 1).reshape(12, 1, -1)
    st_a = st_b = None
    for t in range(12):
        start = np.array([t == 0])
        a, st_a = model.predict(x[t], state=st_a, episode_start=start, deterministic=True)
        b, st_b = agent.policy.predict(x[t], state=st_b, episode_start=start, deterministic=True)
        np.testing.assert_array_equal(a, b)


def test_shipped_models_load_without_pickle_and_act_as_their_sb3_zip():
    from stable_baselines3 import PPO

    for name in ("ppo-belief", "ppo-raw-framestack"):
        folder = REPO / "models" / name
        assert not (folder / "vecnormalize.pkl").exists()
        agent = load_policy(folder)
        export = read_export(folder)
        model = PPO.load(folder / "model.zip", device="cpu")  # our own file: trusted here
        frames = _observations(32 * agent.frame_stack, export.meta["observation"]["mode"])
        raw = frames.reshape(32, -1)
        x = export.normalization.apply(raw).astype(np.float32)
        np.testing.assert_array_equal(agent.policy.predict(x, deterministic=True)[0],
                                      model.predict(x, deterministic=True)[0])
        assert export.meta["provenance"]["timesteps"] == model.num_timesteps
        assert export.meta["provenance"]["commands"][0].startswith("python -m electroloc_gym.train --algo ppo")


# -------------------------------------------------------------------------------------- refusals
@pytest.fixture(scope="module")
def saved(tmp_path_factory) -> Path:
    model, _, cfg = _trained()
    return save_model_dir(model, tmp_path_factory.mktemp("saved") / "m", cfg)


def _copy(saved: Path, tmp_path: Path) -> Path:
    d = tmp_path / "m"
    shutil.copytree(saved, d)
    return d


def _edit_json(folder: Path, fn) -> None:
    meta = json.loads((folder / "policy.json").read_text())
    fn(meta)
    (folder / "policy.json").write_text(json.dumps(meta))


def test_normalised_config_without_statistics_is_refused(saved, tmp_path):
    d = _copy(saved, tmp_path)
    _edit_json(d, lambda m: m.update(normalization=None))
    with pytest.raises(ValueError, match="config.yml says observations were normalised.*refusing"):
        load_policy(d)
    d2 = tmp_path / "n2"
    shutil.copytree(saved, d2)
    _edit_json(d2, lambda m: m["normalization"].update(obs_mean=None))
    with pytest.raises(ValueError, match="norm_obs is true but the observation statistics"):
        load_policy(d2)
    # Without config.yml, a vecnormalize.pkl beside it still says "normalised" (it is not read).
    (d / "config.yml").unlink()
    (d / "vecnormalize.pkl").write_bytes(b"not even a pickle")
    with pytest.raises(ValueError, match="vecnormalize.pkl.*refusing"):
        load_policy(d)
    # Also for the pickle path: a config that normalises, a missing vecnormalize.pkl.
    d3 = tmp_path / "n3"
    shutil.copytree(saved, d3)
    (d3 / "policy.json").unlink()
    with pytest.raises(ValueError, match="vecnormalize.pkl is missing"):
        load_policy(d3, trust_pickle=True)


@pytest.mark.parametrize("edit, pattern", [
    (lambda m: m.update(format_version=2), "format_version"),
    (lambda m: m["architecture"].update(policy_class="os:system"), "policy_class must be one of"),
    (lambda m: m["architecture"]["policy_kwargs"].update(activation_fn="os.system"), "activation_fn"),
    (lambda m: m["architecture"]["policy_kwargs"].update(net_arch=[64]), "do not fit the architecture"),
    (lambda m: m["weights"].update(sha256="0" * 64), "sha256"),
    (lambda m: m["observation"].update(frame_stack=2), "does not match"),
    (lambda m: m["normalization"].update(obs_mean=[0.0] * 3, obs_var=[1.0] * 3), "features"),
    (lambda m: m["normalization"].update(obs_var=[-1.0] * 81), "var ≥ 0"),
    (lambda m: m.pop("observation"), "missing key 'observation'"),
])
def test_malformed_policy_json_is_refused_with_a_clear_error(saved, tmp_path, edit, pattern):
    d = _copy(saved, tmp_path)
    _edit_json(d, edit)
    with pytest.raises(PolicyFormatError, match=pattern):
        load_policy(d)


def test_broken_files_are_refused(saved, tmp_path):
    d = _copy(saved, tmp_path)
    (d / "policy.json").write_text("{not json")
    with pytest.raises(PolicyFormatError, match="not valid JSON"):
        load_policy(d)
    d = tmp_path / "w"
    shutil.copytree(saved, d)
    (d / "policy.safetensors").unlink()
    with pytest.raises(PolicyFormatError, match="no policy.safetensors"):
        load_policy(d)


def test_a_bare_sb3_zip_needs_trust_pickle_and_logs_a_warning(saved, tmp_path, caplog):
    bare = tmp_path / "bare"
    bare.mkdir()
    shutil.copy(saved / "model.zip", bare / "model.zip")
    with pytest.raises(ValueError, match="trust_pickle"):
        load_policy(bare / "model.zip")
    with caplog.at_level(logging.WARNING, logger="electroloc_gym.train.policy"):
        agent = load_policy(bare / "model.zip", trust_pickle=True)
    assert "pickle" in caplog.text and agent.normalization is None
    # Our own model.zip stands for its folder: the pickle-free files are read, no warning.
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="electroloc_gym.train.policy"):
        assert load_policy(saved / "model.zip").normalization is not None
    assert caplog.text == ""


# ----------------------------------------------------------------------- crafted pickle payloads
class _Payload:
    """Unpickling this runs ``touch MARKER`` (the shape of a real attack)."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


def _evil_vecnormalize(folder: Path, marker: Path) -> None:
    (folder / "vecnormalize.pkl").write_bytes(pickle.dumps(_Payload(marker)))


def _evil_zip(zip_path: Path, marker: Path, key: str = "observation_space") -> None:
    """Rewrite ``zip_path`` so that its ``data`` entry carries the payload in a pickled (cloudpickle) entry."""
    with zipfile.ZipFile(zip_path) as zf:
        entries = {n: zf.read(n) for n in zf.namelist()}
    data = json.loads(entries["data"])
    data[key] = {":type:": "<class 'gymnasium.spaces.box.Box'>",
                 ":serialized:": base64.b64encode(pickle.dumps(_Payload(marker))).decode()}
    entries["data"] = json.dumps(data).encode()
    with zipfile.ZipFile(zip_path, "w") as zf:
        for n, b in entries.items():
            zf.writestr(n, b)


def test_the_payloads_are_real(saved, tmp_path):
    """With trust_pickle (and only then) each payload runs — so the tests below prove something."""
    for kind in ("pkl", "zip"):
        d = tmp_path / kind
        shutil.copytree(saved, d)
        (d / "policy.json").unlink()
        marker = tmp_path / f"pwned_{kind}"
        if kind == "pkl":
            _evil_vecnormalize(d, marker)
        else:
            _evil_zip(d / "model.zip", marker)
        with pytest.raises(ValueError):
            load_policy(d, trust_pickle=True)
        assert marker.exists(), kind


@pytest.fixture
def poisoned(saved, tmp_path) -> tuple[Path, Path, Path]:
    """A model folder with our files, plus a poisoned vecnormalize.pkl and model.zip; and a bare poisoned one."""
    marker = tmp_path / "pwned"
    d = tmp_path / "poisoned"
    shutil.copytree(saved, d)
    _evil_vecnormalize(d, marker)
    _evil_zip(d / "model.zip", marker)
    bare = tmp_path / "bare"
    shutil.copytree(d, bare)
    (bare / "policy.json").unlink()
    (bare / "policy.safetensors").unlink()
    return d, bare, marker


def test_no_default_load_path_runs_a_payload(poisoned):
    d, bare, marker = poisoned
    assert load_policy(d).normalization is not None  # read from policy.json; the pickles are ignored
    load_policy(d / "model.zip")
    load_policy(d / "policy.json")
    for target in (bare, bare / "model.zip"):
        with pytest.raises(ValueError, match="trust_pickle"):
            load_policy(target)
    assert not marker.exists()


def test_the_benchmark_resolver_runs_no_payload(poisoned, monkeypatch):
    agents = pytest.importorskip("electroloc_gym.bench.agents")
    d, bare, marker = poisoned
    agent = agents.make_bench_agent(str(d))
    assert agent.env_kwargs["observation"] == "belief"
    agents.make_bench_agent(str(d / "model.zip"))
    with pytest.raises(ValueError, match="trust_pickle|pickle"):
        agents.make_bench_agent(str(bare))
    # A downloaded folder with poisoned ./models/*: a default run uses the shipped models only.
    monkeypatch.chdir(d.parent)
    (d.parent / "models").mkdir()
    shutil.copytree(bare, d.parent / "models" / "evil")
    if hasattr(agents, "default_agents"):
        specs = [c.spec for c in agents.default_agents()]
        assert not any("evil" in s for s in specs)
    assert not marker.exists()


def test_resume_reads_no_pickle(poisoned, tmp_path):
    """Continuing training from a poisoned checkpoint: the pickled entries are replaced, never unpickled."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv

    from electroloc_gym.train.config import ConfigError
    from electroloc_gym.train.resume import load_for_resume

    d, _, marker = poisoned
    venv = DummyVecEnv([lambda: gym.make("ElectroLoc-v0", **FAST_ENV)] * 2)
    model = load_for_resume(d / "model.zip", PPO, venv, {"policy": "MlpPolicy",
                                                         "policy_kwargs": {"net_arch": [32, 16], "log_std_init": -0.3},
                                                         "n_steps": 32, "batch_size": 32, "n_epochs": 1},
                            device="cpu", tensorboard_log=None, verbose=0)
    assert model.num_timesteps >= 64
    _evil_zip(d / "model.zip", marker, key="something_new")
    with pytest.raises(ConfigError, match=r"refusing"):
        load_for_resume(d / "model.zip", PPO, venv, {"policy": "MlpPolicy"}, device="cpu", tensorboard_log=None,
                        verbose=0)
    assert not marker.exists()


def test_resume_restores_exactly_what_sb3_would(saved):
    """Pickle-free resume = SB3's own (pickle) load: weights, optimiser state, statistics, counters."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from electroloc_gym.train.resume import load_for_resume, vec_normalize_from_export

    venv = DummyVecEnv([lambda: gym.make("ElectroLoc-v0", **FAST_ENV)] * 2)
    kw = {"policy": "MlpPolicy", "policy_kwargs": {"net_arch": [32, 16], "log_std_init": -0.3}, "n_steps": 32,
          "batch_size": 32, "n_epochs": 1}
    ours = load_for_resume(saved / "model.zip", PPO, venv, kw, device="cpu", tensorboard_log=None, verbose=0)
    ref = PPO.load(saved / "model.zip", env=venv, device="cpu")
    for a, b in zip(ours.policy.state_dict().values(), ref.policy.state_dict().values()):
        torch.testing.assert_close(a, b, rtol=0, atol=0)
    sa, sb = ours.policy.optimizer.state_dict(), ref.policy.optimizer.state_dict()
    assert sa["param_groups"][0]["lr"] == sb["param_groups"][0]["lr"]
    for k in sa["state"]:
        torch.testing.assert_close(sa["state"][k]["exp_avg"], sb["state"][k]["exp_avg"], rtol=0, atol=0)
    assert (ours.num_timesteps, ours.n_steps, ours.batch_size) == (ref.num_timesteps, ref.n_steps, ref.batch_size)
    norm = read_export(saved).meta["normalization"]
    vn = vec_normalize_from_export(venv, norm)
    live = VecNormalize(venv)
    live.obs_rms.mean = np.asarray(norm["obs_mean"])
    live.obs_rms.var = np.asarray(norm["obs_var"])
    x = _observations(8)
    np.testing.assert_array_equal(vn.normalize_obs(x), live.normalize_obs(x))
    assert vn.obs_rms.count == norm["obs_count"]


def test_json_is_strict_and_spaces_round_trip():
    from gymnasium import spaces

    from electroloc_gym.train.policy_format import dump_json, space_from_json, space_to_json
    from electroloc_gym.train.rundir import strict_json

    assert json.loads(strict_json({"a": float("nan"), "b": [float("inf"), 1.5]})) == {"a": None, "b": [None, 1.5]}
    with pytest.raises(ValueError):
        dump_json({"a": float("nan")})
    for sp in (spaces.Box(-1, 1, (3,), np.float32), spaces.Box(-np.inf, np.inf, (2,), np.float32),
               spaces.Discrete(9), spaces.Discrete(4, start=1)):
        back = space_from_json(json.loads(json.dumps(space_to_json(sp))))
        assert back == sp


def test_an_sb3_zip_is_exported_and_verified(saved, tmp_path):
    """``python -m electroloc_gym.train.export`` on a trusted folder: pickle-free files, same actions."""
    from electroloc_gym.train.export import main as export_main
    from electroloc_gym.train.resume import vec_normalize_from_export

    d = tmp_path / "sb3"
    d.mkdir()
    shutil.copy(saved / "model.zip", d / "model.zip")
    shutil.copy(saved / "config.yml", d / "config.yml")
    from stable_baselines3.common.vec_env import DummyVecEnv

    venv = vec_normalize_from_export(DummyVecEnv([lambda: gym.make("ElectroLoc-v0", **FAST_ENV)]),
                                     read_export(saved).meta["normalization"])
    buf = io.BytesIO()
    pickle.dump(venv, buf)
    (d / "vecnormalize.pkl").write_bytes(buf.getvalue())
    assert export_main([str(d), "--remove-pickle"]) == 0
    assert not (d / "vecnormalize.pkl").exists()
    a, b = load_policy(d), load_policy(saved)
    x = _observations(16)
    np.testing.assert_array_equal(a.predict(x)[0], b.predict(x)[0])
    assert export_main([str(tmp_path / "missing")]) == 2
