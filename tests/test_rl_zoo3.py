"""rl-zoo3 trains ElectroLoc-v0 from the shipped hyper-parameter file, read unchanged (``--conf-file``)."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]
ZOO_FILE = REPO / "train" / "hyperparams" / "rl_zoo3" / "ppo.yml"


def test_the_zoo_file_mirrors_the_shipped_ppo_belief():
    section = yaml.safe_load(ZOO_FILE.read_text())["ElectroLoc-v0"]
    shipped = yaml.safe_load((REPO / "models" / "ppo-belief" / "config.yml").read_text())
    assert "default" not in yaml.safe_load(ZOO_FILE.read_text())  # rl-zoo3 has no inheritance
    assert section["env_kwargs"] == shipped["env_kwargs"]
    assert section["n_envs"] == shipped["n_envs"] and section["n_timesteps"] == shipped["n_timesteps"]
    for key, value in shipped["hyperparams"].items():
        if key != "policy_kwargs":
            assert section[key] == value, key
    assert ast.literal_eval(section["normalize"]) == shipped["normalize"]
    kwargs = section["policy_kwargs"]
    assert isinstance(kwargs, str)  # rl-zoo3 evaluates it as Python
    for part in ("net_arch=[128, 128]", "activation_fn=nn.Tanh", "log_std_init=-0.5"):
        assert part in kwargs
    (wrapper,) = section["env_wrapper"]
    assert wrapper == {"electroloc_gym.train.wrappers.PotentialShaping": {"coef": shipped["shaping_coef"],
                                                                          "gamma": shipped["hyperparams"]["gamma"]}}


def test_rl_zoo3_trains_with_the_file_and_the_result_exports(tmp_path):
    pytest.importorskip("rl_zoo3")
    pytest.importorskip("stable_baselines3")
    env = dict(os.environ, OMP_NUM_THREADS="1", MKL_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), env.get("PYTHONPATH", "")])
    cmd = [sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", "ElectroLoc-v0",
           "--gym-packages", "electroloc_gym", "--conf-file", str(ZOO_FILE), "-n", "256", "--seed", "0",
           "--log-folder", str(tmp_path / "logs"), "--eval-freq", "-1", "--device", "cpu",
           # A small filter and one short rollout keep the test fast; the file itself is read unchanged.
           "--env-kwargs", "condition:'random'", "observation:'belief'", "randomize_target:True", "n_particles:100",
           "sensor_model:'analytic'", "--hyperparams", "n_envs:2", "n_steps:64", "batch_size:64", "n_epochs:2"]
    proc = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-3000:]
    run = tmp_path / "logs" / "ppo" / "ElectroLoc-v0_1"
    zip_path, vn = run / "ElectroLoc-v0.zip", run / "ElectroLoc-v0" / "vecnormalize.pkl"
    assert zip_path.is_file() and vn.is_file()
    monitor = (run / "0.monitor.csv").read_text().splitlines()
    assert monitor[1] == "r,l,t,success,n_observations"

    # The rl-zoo3 model (trusted: we just trained it) converts to the pickle-free format and plays.
    import gymnasium as gym

    from electroloc_gym.train.export import export_model_dir
    from electroloc_gym.train.policy import load_policy

    out = export_model_dir(zip_path, out=tmp_path / "policy", vecnormalize=vn,
                           overrides={"env_kwargs": {"observation": "belief", "n_particles": 100,
                                                     "sensor_model": "analytic"}})
    agent = load_policy(out)
    assert agent.normalization is not None and agent.env_kwargs["observation"] == "belief"
    e = gym.make("ElectroLoc-v0", n_particles=100, sensor_model="analytic", **agent.env_kwargs)
    obs, _ = e.reset(seed=1)
    agent.reset(e)
    action, _ = agent.predict(obs)
    assert e.action_space.contains(action)
