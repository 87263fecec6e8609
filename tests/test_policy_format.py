"""The pickle-free policy format: the numpy policy acts as SB3's, malformed files are refused, no pickle runs."""

from __future__ import annotations

import base64
import json
import os
import pickle
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import electroloc_gym  # noqa: F401
from electroloc_gym.policy import PolicyFormatError, load_policy
from electroloc_gym.policy.format import read_export, read_weights, write_export

torch = pytest.importorskip("torch")
pytest.importorskip("stable_baselines3")

from stable_baselines3 import A2C, DQN, PPO, SAC  # noqa: E402
from stable_baselines3.common.vec_env import DummyVecEnv, VecFrameStack, VecNormalize  # noqa: E402

from electroloc_gym.policy.sb3 import export_meta, model_weights  # noqa: E402

#: An SB3 zip pickled under numpy 2 cannot be unpickled by numpy 1.x (no module numpy._core): the test that opens
#: one with SB3 runs on numpy >= 2 (the nox session `tests`), not at the numpy minimum (`lowest`).
needs_numpy2_pickles = pytest.mark.skipif(
    int(np.__version__.split(".")[0]) < 2, reason="SB3 zips are opened here on numpy >= 2 only"
)

ROOT = Path(__file__).resolve().parents[1]
KW = {"n_particles": 200}


def _venv(observation="belief", action_type="continuous", stack=1, n=2):
    venv = DummyVecEnv(
        [lambda: gym.make("ElectroLoc-v0", observation=observation, action_type=action_type, **KW) for _ in range(n)]
    )
    venv.seed(3)
    venv = VecNormalize(venv, norm_reward=False)
    venv.obs_rms.mean[:] = np.random.default_rng(1).normal(0, 0.1, venv.obs_rms.mean.shape)  # not the identity
    venv.obs_rms.var[:] = 0.5
    venv.training = False  # frozen statistics, as the export freezes them
    return VecFrameStack(venv, stack) if stack > 1 else venv


def _export(model, venv, folder, observation="belief", action_type="continuous", stack=1):
    meta = export_meta(
        model,
        env_id="ElectroLoc-v0",
        env_kwargs={"observation": observation, "action_type": action_type},
        frame_stack=stack,
        vecnormalize=model.get_vec_normalize_env(),
        provenance={"test": True},
    )
    write_export(folder, meta, model_weights(model))
    return load_policy(folder)


def _rollout_check(model, venv, agent, steps=40, atol=1e-5):
    """Step the training stack; the agent sees only raw observations and must act as model.predict on the stack."""
    obs = venv.reset()
    vn = model.get_vec_normalize_env()
    raw_obs = vn.get_original_obs()
    agent.reset()
    starts = np.ones(venv.num_envs, dtype=bool)
    state, n_done = None, 0
    for _ in range(steps):
        expected, state = model.predict(obs, state=state, episode_start=starts, deterministic=True)
        got, _ = agent.predict(raw_obs, episode_start=starts)
        if np.issubdtype(np.asarray(expected).dtype, np.integer):
            assert np.array_equal(got, expected)
        else:
            np.testing.assert_allclose(got, expected, atol=atol)
        obs, _, starts, _ = venv.step(expected)
        raw_obs = vn.get_original_obs()
        n_done += int(starts.sum())
    return n_done


@pytest.mark.parametrize(
    "algo, action_type, stack",
    [
        (PPO, "continuous", 1),
        (PPO, "discrete", 1),
        (PPO, "continuous", 3),
        (A2C, "continuous", 1),
        (SAC, "continuous", 1),
        (DQN, "discrete", 1),
    ],
)
def test_the_numpy_policy_acts_as_sb3_predict(tmp_path, algo, action_type, stack):
    observation = "raw" if stack > 1 else "belief"
    venv = _venv(observation, action_type, stack)
    kw = {"policy_kwargs": {"net_arch": [16, 16]}, "seed": 0, "device": "cpu"}
    if algo in (SAC, DQN):
        kw.update(learning_starts=10**6)
    model = algo("MlpPolicy", venv, **kw)
    agent = _export(model, venv, tmp_path / "p", observation, action_type, stack)
    assert agent.normalize_frames == (stack > 1)  # rl-zoo3's order: VecNormalize inside VecFrameStack
    assert _rollout_check(model, venv, agent) >= 1  # episodes ended and restarted inside the check


def test_qrdqn_and_recurrent_ppo_act_as_sb3(tmp_path):
    contrib = pytest.importorskip("sb3_contrib")
    venv = _venv("belief", "discrete")
    model = contrib.QRDQN(
        "MlpPolicy",
        venv,
        policy_kwargs={"net_arch": [16], "n_quantiles": 5},
        seed=0,
        learning_starts=10**6,
        device="cpu",
    )
    _rollout_check(model, venv, _export(model, venv, tmp_path / "q", "belief", "discrete"))
    venv = _venv("raw")
    model = contrib.RecurrentPPO(
        "MlpLstmPolicy", venv, policy_kwargs={"lstm_hidden_size": 8, "net_arch": [8]}, seed=0, device="cpu"
    )
    agent = _export(model, venv, tmp_path / "r", "raw")
    assert agent.recurrent and _rollout_check(model, venv, agent, steps=60) >= 1  # the LSTM state resets per episode


def test_a_recurrent_policy_called_without_episode_start_keeps_its_state_within_an_episode(tmp_path):
    """Called as the benchmark calls it (``predict(obs)``, no ``episode_start``), a recurrent policy starts its
    episode at the first call after ``reset`` and carries its LSTM state after: SB3's actions, step by step."""
    contrib = pytest.importorskip("sb3_contrib")
    venv = _venv("raw")
    model = contrib.RecurrentPPO(
        "MlpLstmPolicy", venv, policy_kwargs={"lstm_hidden_size": 8, "net_arch": [8]}, seed=0, device="cpu"
    )
    agent = _export(model, venv, tmp_path / "r", "raw")
    obs = venv.reset()
    vn = model.get_vec_normalize_env()
    raw = vn.get_original_obs()
    agent.reset()
    state, starts = None, np.ones(venv.num_envs, dtype=bool)
    for _ in range(6):
        expected, state = model.predict(obs, state=state, episode_start=starts, deterministic=True)
        got, _ = agent.predict(raw)
        np.testing.assert_allclose(got, expected, atol=1e-5)
        obs, _, dones, _ = venv.step(expected)
        raw = vn.get_original_obs()
        assert not dones.any()  # one episode throughout
        starts = np.zeros(venv.num_envs, dtype=bool)


def _renormed(model, rng):
    """The CrossQ model with Batch Renorm statistics, scales and biases far from their initial identity (running
    mean/var as after training), so that the numpy forward pass is checked on every term of the layer."""
    import torch

    with torch.no_grad():
        for name, t in model.policy.state_dict().items():
            if name.endswith((".ra_mean", ".bias")) and t.dtype.is_floating_point:
                t.copy_(torch.as_tensor(rng.normal(0, 0.5, t.shape)))
            elif name.endswith((".ra_var", ".scale")):
                t.copy_(torch.as_tensor(rng.uniform(0.3, 2.0, t.shape)))
            elif name.endswith(".steps"):
                t.fill_(12345)
    return model


@pytest.mark.parametrize(
    "policy_kwargs",
    [
        {"net_arch": [16, 16]},
        {"net_arch": {"pi": [8], "qf": [12]}},
        {"net_arch": [16], "batch_norm": False},
        {"net_arch": [16, 8], "batch_norm_eps": 0.05},
    ],
)
def test_the_numpy_crossq_actor_acts_as_sb3_contrib_predict(tmp_path, policy_kwargs):
    """CrossQ's actor has Batch Renorm layers (before each linear layer and after the last hidden one); the numpy
    forward pass uses their running statistics, as sb3-contrib's predict does in evaluation mode."""
    contrib = pytest.importorskip("sb3_contrib")
    venv = _venv()
    model = contrib.CrossQ("MlpPolicy", venv, policy_kwargs=policy_kwargs, seed=0, learning_starts=10**6, device="cpu")
    _renormed(model, np.random.default_rng(5))
    agent = _export(model, venv, tmp_path / "c")
    assert read_export(tmp_path / "c").meta["algo"] == "crossq"
    assert _rollout_check(model, venv, agent) >= 1
    if policy_kwargs.get("batch_norm", True):  # the statistics matter: the identity statistics act differently
        w = read_weights(read_export(tmp_path / "c"))
        w = {k: (np.zeros_like(v) if k.endswith(".ra_mean") else v) for k, v in w.items()}
        from electroloc_gym.policy.networks import build_actor

        x = np.random.default_rng(0).normal(size=(4, agent.obs_dim))
        a0, _ = agent.actor(x)
        a1, _ = build_actor(agent.meta, w)(x)
        assert not np.allclose(a0, a1)


def test_a_crossq_file_rebuilds_sb3_contribs_policy_and_its_counters_must_be_integers(tmp_path):
    """Stochastic actions load the file into sb3-contrib's CrossQPolicy strictly (its 0-d int64 step counters
    included); a counter written as a float, or a weight as an integer, is refused in one line."""
    contrib = pytest.importorskip("sb3_contrib")
    venv = _venv()
    model = contrib.CrossQ("MlpPolicy", venv, policy_kwargs={"net_arch": [8]}, seed=0, device="cpu")
    agent = _export(model, venv, tmp_path / "c")
    venv.reset()
    action, _ = agent.predict(venv.get_original_obs(), deterministic=False)
    assert action.shape == (2, 2) and np.all(np.abs(action) <= 1)
    weights = read_weights(read_export(tmp_path / "c"))
    assert weights["actor.latent_pi.0.steps"].shape == () and weights["actor.latent_pi.0.steps"].dtype == np.int64
    meta = {
        k: v for k, v in read_export(tmp_path / "c").meta.items() if k not in ("format", "format_version", "weights")
    }
    bad = dict(weights, **{"actor.latent_pi.0.steps": np.float32(3.0).reshape(())})
    with pytest.raises(PolicyFormatError, match="'actor.latent_pi.0.steps' is float32, not an integer counter"):
        write_export(tmp_path / "bad", meta, bad)
    bad = dict(weights, **{"actor.mu.bias": np.zeros(2, dtype=np.int64)})
    with pytest.raises(PolicyFormatError, match="'actor.mu.bias' is int64, not floating-point"):
        write_export(tmp_path / "bad", meta, bad)


_BOX = {"type": "Box", "shape": [3], "dtype": "float32", "low": [-1.0] * 3, "high": [1.0] * 3}
_DISCRETE = {"type": "Discrete", "n": 5, "start": 0}
_LSTM = {"lstm_hidden_size": 6, "n_lstm_layers": 1, "shared_lstm": False, "enable_critic_lstm": True}


@pytest.mark.parametrize(
    "algo, policy_class, action, policy_kwargs, recurrent",
    [
        ("ppo", "ActorCriticPolicy", _BOX, {"net_arch": [16, 8]}, None),
        ("ppo", "ActorCriticPolicy", _DISCRETE, {"net_arch": {"pi": [16], "vf": [8, 4]}}, None),
        (
            "a2c",
            "ActorCriticPolicy",
            _BOX,
            {"net_arch": {"pi": [], "vf": [5]}, "share_features_extractor": False},
            None,
        ),
        ("recurrentppo", "RecurrentActorCriticPolicy", _BOX, {"net_arch": [6]}, _LSTM),
        ("recurrentppo", "RecurrentActorCriticPolicy", _DISCRETE, {"net_arch": [6]}, {**_LSTM, "n_lstm_layers": 2}),
        (
            "recurrentppo",
            "RecurrentActorCriticPolicy",
            _BOX,
            {"net_arch": {"pi": [3], "vf": [4]}},
            {**_LSTM, "shared_lstm": True, "enable_critic_lstm": False},
        ),
        ("recurrentppo", "RecurrentActorCriticPolicy", _BOX, {"net_arch": []}, {**_LSTM, "enable_critic_lstm": False}),
        ("sac", "SACPolicy", _BOX, {"net_arch": [16, 8]}, None),
        ("sac", "SACPolicy", _BOX, {"net_arch": {"pi": [9], "qf": [6, 5]}, "n_critics": 3}, None),
        ("dqn", "DQNPolicy", _DISCRETE, {"net_arch": [12]}, None),
        ("dqn", "DQNPolicy", _DISCRETE, {"net_arch": []}, None),
        ("qrdqn", "QRDQNPolicy", _DISCRETE, {"net_arch": [12], "n_quantiles": 7}, None),
        ("crossq", "CrossQPolicy", _BOX, {"net_arch": [16, 8]}, None),
        ("crossq", "CrossQPolicy", _BOX, {"net_arch": {"pi": [9], "qf": [6, 5]}, "n_critics": 3}, None),
        ("crossq", "CrossQPolicy", _BOX, {"net_arch": [7], "batch_norm": False}, None),
        ("crossq", "CrossQPolicy", _BOX, {"net_arch": {"pi": [], "qf": [4]}}, None),
    ],
)
def test_the_format_knows_each_policy_class_tensors(algo, policy_class, action, policy_kwargs, recurrent):
    """expected_tensors (what a file's tensors are checked against at load) is the SB3 / sb3-contrib class's own
    state_dict for each architecture: names and shapes."""
    import importlib

    from electroloc_gym.policy.format import POLICY_CLASSES, expected_tensors, space_from_json

    if policy_class in ("RecurrentActorCriticPolicy", "QRDQNPolicy", "CrossQPolicy"):
        pytest.importorskip("sb3_contrib")
    obs = {"type": "Box", "shape": [7], "dtype": "float32", "low": [-1.0] * 7, "high": [1.0] * 7}
    meta = {
        "algo": algo,
        "architecture": {"policy_class": policy_class, "policy_kwargs": policy_kwargs, "recurrent": recurrent},
        "observation": {"shape": [7], "space": obs},
        "action": {"space": action},
    }
    module, attr = POLICY_CLASSES[policy_class].split(":")
    cls = getattr(importlib.import_module(module), attr)
    policy = cls(space_from_json(obs), space_from_json(action), lambda _: 0.0, **policy_kwargs, **(recurrent or {}))
    assert expected_tensors(meta) == {k: tuple(v.shape) for k, v in policy.state_dict().items()}


@pytest.fixture
def saved(tmp_path) -> Path:
    venv = _venv()
    model = PPO("MlpPolicy", venv, policy_kwargs={"net_arch": [8]}, seed=0, device="cpu")
    _export(model, venv, tmp_path / "saved")
    model.save(tmp_path / "saved" / "model.zip")
    return tmp_path / "saved"


def _edit(folder: Path, fn) -> None:
    meta = json.loads((folder / "policy.json").read_text())
    fn(meta)
    (folder / "policy.json").write_text(json.dumps(meta))


@pytest.mark.parametrize(
    "edit, pattern",
    [
        (lambda m: m.update(format="other"), "not an electroloc-gym-policy"),
        (lambda m: m.update(format_version=99), r"Invalid enum value 99 - at `\$\.format_version`"),
        (
            lambda m: m["architecture"].update(policy_class="os.system"),
            r"architecture\.policy_class must be one of \[.*\], got 'os\.system'",
        ),
        (
            lambda m: m["architecture"]["policy_kwargs"].update(activation_fn="evil"),
            r"architecture\.policy_kwargs\.activation_fn must be one of \[.*\], got 'evil'",
        ),
        (lambda m: m["observation"].update(frame_stack=2), "does not match"),
        (lambda m: m["normalization"].update(obs_mean=None), r"norm_obs is true but \['obs_mean'\] are missing"),
        (
            lambda m: m["normalization"].update(obs_mean=[0.0], obs_var=[1.0]),
            "normalisation statistics have 1 features",
        ),
        (lambda m: m.pop("action"), "Object missing required field `action`"),
    ],
)
def test_malformed_policy_json_is_refused_with_one_clear_error(saved, edit, pattern):
    _edit(saved, edit)
    with pytest.raises(PolicyFormatError, match=pattern):
        load_policy(saved)


def test_broken_files_are_refused(saved):
    blob = (saved / "policy.safetensors").read_bytes()
    (saved / "policy.safetensors").write_bytes(blob[:-4] + b"\0\0\0\0")
    with pytest.raises(PolicyFormatError, match="does not match the sha256"):
        load_policy(saved)
    (saved / "policy.safetensors").unlink()
    with pytest.raises(PolicyFormatError, match="no policy.safetensors"):
        load_policy(saved)
    (saved / "policy.json").write_text("{not json")
    with pytest.raises(PolicyFormatError, match="not valid JSON"):
        load_policy(saved)
    with pytest.raises(ValueError, match="does not exist"):
        load_policy(saved.parent / "nowhere")


def test_weights_round_trip_the_safetensors_library(saved):
    import safetensors.numpy as st  # the dev extra installs the reference library

    ours = read_weights(read_export(saved))
    theirs = st.load_file(str(saved / "policy.safetensors"))
    assert ours.keys() == theirs.keys()
    assert all(np.array_equal(ours[k], theirs[k]) and ours[k].dtype == theirs[k].dtype for k in ours)


class _Payload:
    """Unpickling this runs ``touch MARKER`` (the shape of a real attack)."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


def _poison_zip(zip_path: Path, marker: Path) -> None:
    with zipfile.ZipFile(zip_path) as zf:
        entries = {n: zf.read(n) for n in zf.namelist()}
    data = json.loads(entries["data"])
    data["observation_space"] = {
        ":type:": "<class 'gymnasium.spaces.box.Box'>",
        ":serialized:": base64.b64encode(pickle.dumps(_Payload(marker))).decode(),
    }
    entries["data"] = json.dumps(data).encode()
    with zipfile.ZipFile(zip_path, "w") as zf:
        for n, b in entries.items():
            zf.writestr(n, b)


@pytest.fixture
def poisoned(saved, tmp_path) -> tuple[Path, Path, Path]:
    """A policy folder with a poisoned vecnormalize.pkl and model.zip beside its files; a bare poisoned copy."""
    marker = tmp_path / "pwned"
    (saved / "vecnormalize.pkl").write_bytes(pickle.dumps(_Payload(marker)))
    _poison_zip(saved / "model.zip", marker)
    bare = tmp_path / "bare"
    shutil.copytree(saved, bare)
    (bare / "policy.json").unlink()
    return saved, bare, marker


@needs_numpy2_pickles
def test_an_sb3_zip_runs_under_the_name_its_path_is_shown_by(saved, tmp_path):
    """A trusted SB3 zip is named as the progress line and the log name its path (``runs/x/model.zip``: ``x``), so the
    table's row and the log line agree; another zip by its stem."""
    from electroloc_gym.bench.agents import agent_display_name

    other = tmp_path / "best_model.zip"
    shutil.copy(saved / "model.zip", other)
    for path, name in ((saved / "model.zip", "saved"), (other, "best_model")):
        assert load_policy(path, trust_pickle=True).name == agent_display_name(str(path)) == name


@needs_numpy2_pickles
def test_the_payloads_are_real(poisoned):
    _, bare, marker = poisoned
    with pytest.raises(Exception):  # noqa: B017 - whatever SB3 raises after running the payload
        load_policy(bare / "model.zip", trust_pickle=True)
    assert marker.exists()


def test_no_default_load_path_runs_a_payload(poisoned, caplog):
    d, bare, marker = poisoned
    assert load_policy(d).normalization is not None  # read from policy.json; the pickles are ignored
    load_policy(d / "policy.json")
    for target in (bare, bare / "model.zip"):
        with pytest.raises(ValueError, match="trust_pickle"):
            load_policy(target)
    agents = pytest.importorskip("electroloc_gym.bench.agents")
    assert agents.make_bench_agent(str(d)).env_kwargs["observation"] == "belief"
    with pytest.raises(ValueError, match="trust_pickle"):
        agents.make_bench_agent(str(bare))
    assert not marker.exists()


def test_a_shipped_policy_runs_without_torch_and_sb3():
    """Deterministic actions need numpy only; stochastic ones say that torch and SB3 are needed."""
    code = (
        "import sys; sys.modules['torch'] = None; sys.modules['stable_baselines3'] = None\n"
        "import numpy as np, gymnasium as gym, electroloc_gym\n"
        "from electroloc_gym.bench.agents import make_bench_agent\n"
        "a = make_bench_agent('ppo-belief'); env = gym.make('ElectroLoc-v0', n_particles=200, **a.env_kwargs)\n"
        "o, _ = env.reset(seed=0); a.reset(env); print(a.predict(o)[0].shape)\n"
        "try:\n    a.predict(o, deterministic=False)\nexcept ValueError as e:\n    print('ERR', e)\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    assert "(2,)" in r.stdout and "ERR stochastic actions of a learned policy need torch and SB3" in r.stdout


# ------------------------------------------------------------------ damaged folders: one error naming the file
SHIPPED = ROOT / "electroloc_gym" / "models" / "ppo-belief"


def _copy_shipped(tmp: Path) -> Path:
    dst = tmp / "policy"
    if dst.exists():
        shutil.rmtree(dst)
    shutil.copytree(SHIPPED, dst)
    return dst


def test_a_deeply_nested_policy_json_is_one_error_naming_the_file(tmp_path):
    d = _copy_shipped(tmp_path)
    (d / "policy.json").write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(PolicyFormatError, match="policy.json"):
        load_policy(d)


def test_a_list_for_the_policy_class_is_one_error_naming_the_file(tmp_path):
    d = _copy_shipped(tmp_path)
    _edit(d, lambda m: m["architecture"].update(policy_class=[[], []]))
    with pytest.raises(PolicyFormatError, match="policy.json.*policy_class"):
        load_policy(d)


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_weights_are_refused_even_with_a_matching_sha256(tmp_path, bad):
    import hashlib

    import safetensors.numpy as st

    d = _copy_shipped(tmp_path)
    tensors = st.load_file(str(d / "policy.safetensors"))
    name = sorted(tensors)[0]
    tensors[name] = np.full_like(tensors[name], bad)
    blob = st.save(tensors)
    (d / "policy.safetensors").write_bytes(blob)
    _edit(d, lambda m: m["weights"].update(sha256=hashlib.sha256(blob).hexdigest()))
    with pytest.raises(PolicyFormatError, match="non-finite weights"):
        load_policy(d)


def _leaf_paths(node, prefix=()):
    """Every path to a value of a JSON document (dict keys and list indices)."""
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _leaf_paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node[:4]):  # a few entries of long lists are enough
            yield from _leaf_paths(v, prefix + (i,))


_DAMAGES = [None, True, -1, 0, 10**30, 1e308, "x", "", [], [[], []], {}, {"a": {}}, 3.5, "nan", [None]]


def test_any_single_field_damage_of_a_shipped_policy_is_one_value_error_or_a_working_policy(tmp_path):
    """Hypothesis: replace or delete one field of a shipped policy.json; loading either works (the field
    was not used) and acts finitely, or raises one PolicyFormatError naming the file — never another type.
    """
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as hs

    meta0 = json.loads((SHIPPED / "policy.json").read_text())
    paths = [p for p in _leaf_paths(meta0) if p]
    obs = np.zeros(len(meta0["observation"]["space"]["low"]), dtype=np.float32)

    @settings(max_examples=60, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
    @given(hs.sampled_from(paths), hs.sampled_from(_DAMAGES + ["<delete>"]))
    def check(path, value):
        d = _copy_shipped(tmp_path)
        meta = json.loads(json.dumps(meta0))
        node = meta
        for k in path[:-1]:
            node = node[k]
        if value == "<delete>":
            node.pop(path[-1]) if isinstance(node, dict) else node.pop(path[-1])
        else:
            node[path[-1]] = value
        (d / "policy.json").write_text(json.dumps(meta))
        try:
            agent = load_policy(d)
        except PolicyFormatError as exc:
            assert str(d) in str(exc) and "\n" not in str(exc).strip()
            return
        action, _ = agent.predict(obs)
        assert np.isfinite(np.asarray(action, dtype=np.float64)).all()

    check()


def test_a_zoo_zip_that_is_no_model_is_one_line_naming_it(tmp_path):
    """A trusted rl-zoo3 run whose zip SB3 cannot load (here: not a zip at all) is one ValueError naming the file,
    the algorithm it was read as and SB3's reason."""
    pytest.importorskip("rl_zoo3")
    from electroloc_gym.policy.sb3 import load_zoo_run

    zp = tmp_path / "run" / "ElectroLoc-v0.zip"
    zp.parent.mkdir()
    zp.write_bytes(b"not a zip")
    with pytest.raises(ValueError, match=rf"^cannot load {re.escape(str(zp))} as a ppo model: ") as info:
        load_zoo_run(zp)
    assert "\n" not in str(info.value)
