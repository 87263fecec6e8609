"""Training on RLlib: the env runners' env creator and process set-up, and the policy export.

The export turns RLlib's PPO module into the project's pickle-free policy format.

The one creator, :func:`make_env`, serves both of RLlib's entry points. Registered with
``ray.tune.registry.register_env`` (:func:`register`), RLlib's ``SingleAgentEnvRunner`` calls it with the
``env_config`` for a single env, and with ``env_config | {"num_envs": n}`` for its vector entry point
(``gym_env_vectorize_mode="vector_entry_point"``), where it returns the native vector env — one batched
core of ``n`` tanks per runner. The creator is a module-level function: Ray pickles it by reference, so
every runner process imports this module, which imports ``electroloc_gym`` and registers the env ids
there too (the string form ``"electroloc_gym:ElectroLoc-v0"`` does the same through Gymnasium).

Seeds: RLlib resets runner ``k``'s vector env with ``seed + k``; the vector env spreads an int seed over
its sub-envs with :class:`numpy.random.SeedSequence` (:func:`electroloc_gym.envs.vector.sub_env_seeds`),
so no two runners share a sub-env. Autoreset: RLlib's runner handles Gymnasium's next-step autoreset
(the step after an episode's last returns the next episode's first observation, and its action is
ignored), the native vector env's default; the creator refuses ``autoreset_mode="same_step"``.

Processes: :func:`runner_env_vars` pins numba, BLAS and torch in every runner to the driver's thread count
(one unless chosen; set in Ray's ``runtime_env``; the creator also calls
:func:`~electroloc_gym.utils.runtime.pin_threads`), and
:func:`warm_kernels` compiles the env's numba kernels once into their on-disk cache before the runners
start, so that they load them instead of each compiling (and writing) them.

Export (:func:`export_ppo`): RLlib's default PPO module with separate actor and critic MLPs
(``vf_share_layers=False``) and a state-independent log-std (``free_log_std=True``) is the same
network as Stable-Baselines3's ``ActorCriticPolicy`` with ``net_arch=hidden`` — the weights are copied
layer by layer, and the ``MeanStdFilter`` connector's statistics become the format's observation
normalisation. The format is unchanged; ``electroloc bench --agents <folder>`` runs the result.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from electroloc_gym.registry import ENV_IDS
from electroloc_gym.utils.runtime import pin_threads, thread_env

__all__ = [
    "ENV_IDS",
    "RLLIB_ENV_NAME",
    "SUCCESS_METRIC",
    "make_env",
    "register",
    "runner_env_vars",
    "warm_kernels",
    "success_callback",
    "plot_progress",
    "sb3_state_dict",
    "normalization_from_filter",
    "export_ppo",
]

#: The name :func:`register` registers the creator under (``PPOConfig().environment(RLLIB_ENV_NAME)``).
RLLIB_ENV_NAME = "electroloc"
#: The key under ``result["env_runners"]`` of the success rate over the last 100 episodes (:func:`success_callback`).
SUCCESS_METRIC = "episode_success_mean"
#: RLlib's ``MeanStdFilter`` divides by ``std + SMALL_NUMBER`` (ray.rllib.utils.numpy.SMALL_NUMBER).
_FILTER_EPS = 1e-6
#: The epsilon of the exported normalisation: the exported variance absorbs RLlib's divisor exactly.
_EXPORT_EPS = 1e-30


def _split_config(config: Mapping[str, Any]) -> tuple[str, int | None, dict[str, Any]]:
    """``(env_id, num_envs, env kwargs)`` of a creator config (a dict or RLlib's ``EnvContext``)."""
    if not isinstance(config, Mapping):
        raise ValueError(f"env_config must be a mapping of env kwargs, got {type(config).__name__}")
    kwargs = dict(config)
    env_id = kwargs.pop("env_id", ENV_IDS[0])
    if env_id not in ENV_IDS:
        raise ValueError(f"env_config['env_id'] must be one of {list(ENV_IDS)}, got {env_id!r}")
    num_envs = kwargs.pop("num_envs", None)
    mode = kwargs.pop("autoreset_mode", "next_step")
    if mode not in ("next_step", gym.vector.AutoresetMode.NEXT_STEP):
        raise ValueError(
            f"env_config['autoreset_mode'] must be 'next_step' (RLlib's env runners expect "
            f"Gymnasium's next-step autoreset), got {mode!r}"
        )
    return env_id, num_envs, kwargs


def make_env(config: Mapping[str, Any]) -> gym.Env | gym.vector.VectorEnv:
    """The creator for ``register_env``: a single env, or the native vector env when RLlib passes ``num_envs``.

    It runs in the env runner's process and first pins that process's numeric libraries to the chosen thread
    count, one unless chosen (:func:`~electroloc_gym.utils.runtime.pin_threads`; called in a driver, it pins the
    driver too).

    Args:
        config: the env kwargs (:class:`~electroloc_gym.contract.params.EnvParams`), plus ``env_id`` (one of
            :data:`electroloc_gym.registry.ENV_IDS`, the env table's ids; default its first) and, from
            RLlib's vector entry point, ``num_envs``.

    Raises:
        ValueError: an unknown ``env_id``, ``autoreset_mode`` other than next-step, or a bad env kwarg
            (the env's own message).
    """
    pin_threads()
    env_id, num_envs, kwargs = _split_config(config)
    if num_envs is None:
        return gym.make(env_id, **kwargs)
    return gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)


def register(name: str = RLLIB_ENV_NAME) -> str:
    """Register :func:`make_env` with Ray Tune's registry under ``name`` (the driver only; Ray ships it)."""
    from ray.tune.registry import register_env

    register_env(name, make_env)
    return name


def runner_env_vars() -> dict[str, str]:
    """Environment variables of every Ray worker: the driver's chosen numba, OpenMP and BLAS threads (one
    unless chosen, :func:`~electroloc_gym.utils.runtime.thread_env`; Ray ``runtime_env``).
    """
    return thread_env()


def warm_kernels(env_config: Mapping[str, Any]) -> float:
    """Compile (or load) the numba kernels of ``env_config``'s env in this process; returns the seconds taken.

    Run in the driver before the runners start: the kernels are compiled with ``cache=True``, so the
    runners load them from numba's on-disk cache instead of each compiling them, and no two processes
    write the same cache file at once.
    """
    t0 = time.perf_counter()
    env = make_env({**dict(env_config), "num_envs": 1})
    env.reset(seed=0)
    env.step(env.action_space.sample())
    env.close()
    return time.perf_counter() - t0


def success_callback(*, episode: Any, metrics_logger: Any, **_: Any) -> None:
    """``callbacks_on_episode_end``: log whether the episode ended in success (the env's ``info["success"]``)
    as :data:`SUCCESS_METRIC`, a mean over the last 100 episodes, beside RLlib's returns and lengths.
    """
    success = bool(episode.get_infos(-1).get("success", False))
    metrics_logger.log_value(SUCCESS_METRIC, float(success), reduce="mean", window=100)


def plot_progress(csv_path: str | Path, png_path: str | Path, title: str = "RLlib PPO on ElectroLoc-v0") -> Path:
    """The learning curve of a ``progress.csv`` (examples/rllib_ppo.py): success rate and mean episode length
    of the training episodes (last 100, stochastic policy) against env steps.

    Raises:
        ValueError: an unreadable file, a missing column, a short row or a value that is not a number
            (one line naming the file and the line).
    """
    import csv

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    columns = ("env_steps", "success_mean", "length_mean")
    try:
        with open(csv_path, newline="", encoding="utf-8") as f:
            reader = csv.DictReader(f)
            missing = [c for c in columns if c not in (reader.fieldnames or ())]
            if missing:
                raise ValueError(f"{csv_path} lacks the column(s) {missing} (a progress.csv has {list(columns)})")
            rows = []
            for line, r in enumerate(reader, start=2):
                if any(r.get(c) is None for c in columns):
                    raise ValueError(f"{csv_path} line {line} is short: it has no value for every column")
                if r["success_mean"] in ("", "nan", "NaN"):
                    continue
                try:
                    rows.append((int(r["env_steps"]), float(r["success_mean"]), float(r["length_mean"])))
                except ValueError:
                    raise ValueError(f"{csv_path} line {line}: {list(columns)} must be numbers") from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise ValueError(f"cannot read {csv_path}: {exc}") from exc
    if not rows:
        raise ValueError(f"{csv_path} has no iteration with finished episodes")
    steps = [r[0] for r in rows]
    fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.4), constrained_layout=True)
    a.plot(steps, [r[1] for r in rows], color="tab:green")
    a.set(xlabel="env steps", ylabel="success rate (last 100 episodes)", ylim=(0, 1.02))
    b.plot(steps, [r[2] for r in rows], color="tab:blue")
    b.set(xlabel="env steps", ylabel="mean episode length (readings)")
    for ax in (a, b):
        ax.xaxis.set_major_formatter(lambda x, _: f"{x / 1000:.0f}k")
    fig.suptitle(title)
    fig.savefig(png_path, dpi=110)
    plt.close(fig)
    return Path(png_path)


# ------------------------------------------------------------------------------------------- export
_LAYER_PAIRS = (
    ("mlp_extractor.policy_net", "encoder.actor_encoder.net.mlp"),
    ("mlp_extractor.value_net", "encoder.critic_encoder.net.mlp"),
)


def sb3_state_dict(rllib_state: Mapping[str, Any], n_hidden: int) -> dict[str, Any]:
    """Stable-Baselines3 ``ActorCriticPolicy`` tensors from the state of RLlib's default PPO torch module.

    The module must have been built with ``vf_share_layers=False`` and ``free_log_std=True`` (and
    ``head_fcnet_hiddens=[]``, the default); both MLPs use Linear layers at even indices.

    Args:
        rllib_state: the learner's module state (``algo.learner_group.get_weights()[module_id]``).
        n_hidden: the number of hidden layers (``len(fcnet_hiddens)``).

    Raises:
        ValueError: a module whose tensors do not have this layout (names the missing tensor).
    """
    import torch

    def get(name: str) -> Any:
        if name not in rllib_state:
            raise ValueError(
                f"the RLlib module has no tensor {name!r}: build it with DefaultModelConfig("
                f"vf_share_layers=False, free_log_std=True) and no head_fcnet_hiddens"
            )
        return torch.as_tensor(np.asarray(rllib_state[name]))

    out: dict[str, Any] = {}
    for sb3, rl in _LAYER_PAIRS:
        for layer in range(n_hidden):
            for part in ("weight", "bias"):
                out[f"{sb3}.{2 * layer}.{part}"] = get(f"{rl}.{2 * layer}.{part}")
    for part in ("weight", "bias"):
        out[f"action_net.{part}"] = get(f"pi.net.mlp.0.{part}")
        out[f"value_net.{part}"] = get(f"vf.net.mlp.0.{part}")
    out["log_std"] = get("pi.log_std")
    return out


def normalization_from_filter(running_stat_state: Mapping[str, Any], clip: float) -> dict[str, Any]:
    """The format's ``normalization`` section from the state of RLlib's ``MeanStdFilter`` running stat.

    RLlib normalises ``clip((x − mean) / (std + 1e-6), ±clip)``; the format computes
    ``clip((x − mean) / sqrt(var' + ε), ±clip)``, so the export writes ``var' = (std + 1e-6)² − ε``
    with ``ε = 1e-30``: the same divisor, to float64 rounding.
    """
    from ray.rllib.utils.filter import RunningStat

    rs = RunningStat.from_state(dict(running_stat_state))
    std = np.asarray(rs.std, dtype=np.float64)
    var = (std + _FILTER_EPS) ** 2 - _EXPORT_EPS
    return {
        "norm_obs": True,
        "norm_reward": False,
        "clip_obs": float(clip),
        "epsilon": _EXPORT_EPS,
        "obs_mean": [float(v) for v in np.asarray(rs.mean, dtype=np.float64)],
        "obs_var": [float(v) for v in var],
        "obs_count": float(rs.num_pushes),
        "source": "rllib MeanStdFilter",
    }


def export_ppo(
    algo: Any,
    folder: str | Path,
    *,
    env_id: str,
    env_kwargs: Mapping[str, Any],
    hidden: Sequence[int],
    provenance: Mapping[str, Any],
) -> Path:
    """Write ``policy.json`` and ``policy.safetensors`` for a trained RLlib PPO ``algo`` into ``folder``.

    Args:
        algo: a built RLlib ``PPO`` (default module as in :func:`sb3_state_dict`, a ``MeanStdFilter``
            env-to-module connector or none, tanh activations).
        folder: the model directory (created).
        env_id: the env trained on.
        env_kwargs: its kwargs (the observation mode and action type are read from them; "belief" and
            continuous actions by default).
        hidden: the hidden layer sizes (``fcnet_hiddens``).
        provenance: plain-data provenance (command, seed, timesteps, versions).
    """
    import torch
    from ray.rllib.core import COMPONENT_ENV_TO_MODULE_CONNECTOR, DEFAULT_MODULE_ID
    from stable_baselines3.common.policies import ActorCriticPolicy

    from electroloc_gym.policy.format import write_export
    from electroloc_gym.policy.sb3 import export_meta, model_weights

    state = algo.learner_group.get_weights()[DEFAULT_MODULE_ID]
    env = make_env({"env_id": env_id, **dict(env_kwargs)})  # the raw spaces (the module sees filtered ones)
    obs_space, act_space = env.observation_space, env.action_space
    env.close()
    policy = ActorCriticPolicy(
        obs_space, act_space, lambda _: 0.0, net_arch=list(hidden), activation_fn=torch.nn.Tanh, ortho_init=False
    )
    policy.load_state_dict(sb3_state_dict(state, len(hidden)), strict=True)
    connectors = algo.env_runner.get_state(components=COMPONENT_ENV_TO_MODULE_CONNECTOR)
    filt = connectors.get(COMPONENT_ENV_TO_MODULE_CONNECTOR, {}).get("MeanStdFilter")
    normalization = None
    if filt:
        (agent_state,) = filt.values()
        (stat,) = agent_state["running_stats"]
        normalization = normalization_from_filter(stat, agent_state["clip_by_value"])
    shim = _PolicyHolder(policy, {"net_arch": list(hidden), "activation_fn": torch.nn.Tanh, "ortho_init": False})
    meta = export_meta(
        shim,
        env_id=env_id,
        env_kwargs=dict(env_kwargs),
        frame_stack=1,
        vecnormalize=None,
        provenance={"trainer": "rllib", **dict(provenance)},
    )
    meta["algo"], meta["normalization"] = "ppo", normalization
    return write_export(folder, meta, model_weights(shim))


class _PolicyHolder:
    """What :func:`~electroloc_gym.policy.sb3.export_meta` reads of an SB3 model: the policy and its
    constructor keywords.
    """

    def __init__(self, policy: Any, policy_kwargs: dict[str, Any]) -> None:
        self.policy, self.policy_kwargs = policy, policy_kwargs
