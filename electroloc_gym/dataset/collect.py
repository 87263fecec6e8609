"""Minari datasets of any benchmark agent: ``electroloc dataset`` and :func:`build_dataset`.

A dataset is the episodes of one agent on one env, written with Minari's own storage
(``minari.create_dataset_from_buffers``, then ``storage.update_episodes``; the arrow format) under
``MINARI_DATASETS_PATH`` (Minari's default folder when unset), with the id
``electroloc/<env-id>/<agent>-v<N>``. Nothing goes to a hub. What it holds:

* the env spec of the episodes' env (``minari.load_dataset(id).recover_environment()`` rebuilds it:
  the benchmark's env kwargs for the agent — its sensor model, particles, cap, observation mode — with
  ``condition="random"``, one of the paper's eight presets drawn per episode from the reset seed);
* per episode the reset seed (:func:`~electroloc_gym.dataset.protocol.episode_seeds`: training seeds,
  disjoint from the benchmark's evaluation seeds), the observations, actions, rewards, flags;
* per step (reset included) the infos of :func:`step_infos`: the belief summary (estimate, covariance,
  spread, readings fused), the reading, the condition's index and the truth (the hidden position; for the
  unknown target its radius and contrast) — for analysis and privileged critics, never an agent's input;
* in the metadata: ``ref_min_score`` / ``ref_max_score`` (rnd-wlk and the best planner,
  :func:`~electroloc_gym.dataset.protocol.reference_scores`), the agent spec (its options included) as
  ``algorithm_name``, and an ``electroloc`` block: agent, env kwargs, root seed, the planned episode count,
  the reference's provenance, and ``complete``.

The episodes are the benchmark's rollout loop (:func:`electroloc_gym.rollout.run_episode`) with the
agent built by the benchmark's own constructor (:func:`electroloc_gym.bench.agents.make_bench_agent`):
every spec ``electroloc bench --agents`` takes works here. Writing is resumable: each episode is written
as it ends, ``complete`` is set after the last, and ``resume=True`` continues an unfinished dataset from
its next episode (the same seeds, so the same episodes); an existing id is refused unless ``force``.
"""

from __future__ import annotations

import os
import re
import shutil
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from electroloc_gym.dataset.protocol import (
    DEFAULT_DATASET_SEED,
    EVALUATION_SEED,
    episode_seeds,
    evaluation_overlap,
    reference_scores,
)

__all__ = [
    "DatasetRequest",
    "build_dataset",
    "dataset_id",
    "step_infos",
    "dataset_env_kwargs",
    "MAX_EPISODES",
    "MINARI_HINT",
]

MINARI_HINT = "pip install 'electroloc-gym[minari]'"
#: Most episodes one dataset may plan.
MAX_EPISODES = 1_000_000
_NAME_RE = re.compile(r"[^A-Za-z0-9_.-]+")


def dataset_id(env_id: str, agent: str, version: int = 0) -> str:
    """Minari's ``electroloc/<env-id>/<agent>-v<version>``; the agent's display name with anything but
    letters, digits, ``_ . -`` replaced by ``_`` (``min-var[n_voters=500]`` → ``min-var_n_voters_500_``).
    """
    from electroloc_gym.bench.agents import agent_display_name

    name = _NAME_RE.sub("_", agent_display_name(agent.strip())).strip("_.-") or "agent"
    return f"electroloc/{env_id}/{name}-v{int(version)}"


@dataclass(frozen=True)
class DatasetRequest:
    """What one dataset is (validated on construction; every error one line naming the argument).

    Attributes:
        env_id: a registered env id (``electroloc_gym.registry.ENV_IDS``).
        agent: an agent spec ``electroloc bench --agents`` takes.
        episodes: episodes to collect (1 … :data:`MAX_EPISODES`).
        seed: root seed of the episodes' seeds (≥ 1; 0 is the benchmark's evaluation seed).
        reference: a benchmark folder or trials.jsonl with rnd-wlk and a planner on ``env_id`` (the
            reference scores), or None: no reference scores.
        version: the id's version N.
        dataset_id: the id, or None: :func:`dataset_id`.
        condition: localize and unknown-target envs: ``"random"`` (a preset per episode) or a preset name.
        trust_pickle: let a learned policy whose files need unpickling load (SB3's bare zip).
    """

    env_id: str
    agent: str
    episodes: int
    seed: int = DEFAULT_DATASET_SEED
    reference: str | os.PathLike[str] | None = None
    version: int = 0
    dataset_id: str | None = None
    condition: str = "random"
    trust_pickle: bool = False

    def __post_init__(self) -> None:
        from electroloc_gym.conditions import PRESET_NAMES
        from electroloc_gym.registry import ENV_IDS

        if self.env_id not in ENV_IDS:
            raise ValueError(f"env must be one of {list(ENV_IDS)}, got {self.env_id!r}")
        for name, val, low, high in (
            ("episodes", self.episodes, 1, MAX_EPISODES),
            ("seed", self.seed, 1, 2**63 - 1),
            ("version", self.version, 0, 10**6),
        ):
            if isinstance(val, bool) or not isinstance(val, int) or not low <= val <= high:
                extra = " (0 is the benchmark's evaluation seed)" if name == "seed" else ""
                raise ValueError(f"{name} must be an integer in [{low}, {high}]{extra}, got {val!r}")
        if self.condition != "random" and self.condition not in PRESET_NAMES:
            raise ValueError(f"condition must be 'random' or one of {list(PRESET_NAMES)}, got {self.condition!r}")
        if not isinstance(self.agent, str) or not self.agent.strip():
            raise ValueError(f"agent must be a non-empty agent spec, got {self.agent!r}")
        if self.dataset_id is not None:
            from minari.dataset.minari_dataset import DATASET_ID_RE

            if not DATASET_ID_RE.fullmatch(self.dataset_id) or "/" not in self.dataset_id:
                raise ValueError(f"dataset id must be NAMESPACE/NAME-vN (Minari's form), got {self.dataset_id!r}")

    @property
    def id(self) -> str:
        return self.dataset_id or dataset_id(self.env_id, self.agent, self.version)


def dataset_env_kwargs(env_id: str, agent: Any, condition: str = "random") -> dict[str, Any]:
    """The ``gym.make`` kwargs of a dataset's env: the benchmark's for ``agent`` (plain JSON values, so the
    env spec serialises), with ``condition`` as a name (the global env takes none).
    """
    from electroloc_gym.bench.agents import bench_env_kwargs
    from electroloc_gym.registry import env_entry

    kwargs = bench_env_kwargs(env_id, agent, None)
    if env_entry(env_id).takes("condition"):
        kwargs["condition"] = condition
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in kwargs.items()}


def step_infos(env: Any, info: dict[str, Any]) -> dict[str, Any]:
    """The numeric per-step infos a dataset stores (same keys every step of every episode of an env).

    ``estimate_mm`` (2,), ``covariance_mm2`` (xx, xy, yy), ``spread_mm``, ``n_observations``, ``reading_V``,
    ``success``: the belief and what the agent saw; ``condition_index``: the preset's index in
    ``PRESET_NAMES`` (−1: the global map); ``truth_mm`` (2,) the hidden position (the target, or the robot's
    own in the mapped tank) and ``error_mm``; for the unknown target ``truth_radius_mm``, ``truth_chi``,
    ``radius_estimate_mm``, ``p_conductor``. Read from the env's documented evaluation accessors.
    """
    from electroloc_gym.conditions import PRESET_NAMES

    core = env.unwrapped
    cov = np.asarray(core.belief.covariance(), dtype=np.float64)
    truth = core.truth_mm
    name = str(info.get("condition", ""))
    out: dict[str, Any] = {
        "estimate_mm": np.asarray(info["estimate_mm"], dtype=np.float64),
        "covariance_mm2": np.array([cov[0, 0], cov[0, 1], cov[1, 1]]),
        "spread_mm": np.float64(info["spread_mm"]),
        "n_observations": np.int64(info["n_observations"]),
        "reading_V": np.float64(np.ravel(info["reading_V"])[0]),
        "success": np.bool_(info["success"]),
        "condition_index": np.int64(PRESET_NAMES.index(name) if name in PRESET_NAMES else -1),
        "truth_mm": np.asarray(truth, dtype=np.float64).reshape(2),
        "error_mm": np.float64(info["error_mm"]),
    }
    hidden = core.hidden_state()
    for key, value in zip(core.hidden_keys[2:], hidden[2:]):  # the hidden shape beyond the position
        out["truth_" + key.removeprefix("target_")] = np.float64(value)
    if core.entry().record_keys:  # its estimates
        out.update(
            radius_estimate_mm=np.float64(info["radius_estimate_mm"]), p_conductor=np.float64(info["p_conductor"])
        )
    return out


def _episode_buffer(env: Any, agent: Any, k: int, root_seed: int) -> Any:
    """Episode ``k``: the benchmark's rollout, recorded step by step into a Minari ``EpisodeBuffer``."""
    from minari.data_collector.episode_buffer import EpisodeBuffer

    from electroloc_gym.rollout import run_episode

    env_seed, agent_seed = episode_seeds(root_seed, k)
    obs, acts, rews, terms, truncs, infos = [], [], [], [], [], []

    class _Recorder:  # the env seen through its step, so the rollout loop stays the benchmark's
        def __init__(self, inner: Any) -> None:
            self._inner = inner

        def __getattr__(self, name: str) -> Any:
            return getattr(self._inner, name)

        def reset(self, **kwargs: Any) -> Any:
            o, info = self._inner.reset(**kwargs)
            obs.append(np.asarray(o))
            infos.append(step_infos(self._inner, info))
            return o, info

        def step(self, action: Any) -> Any:
            o, r, te, tr, info = self._inner.step(action)
            space = self._inner.action_space
            acts.append(np.asarray(action, dtype=space.dtype).reshape(space.shape))
            obs.append(np.asarray(o))
            rews.append(float(r))
            terms.append(bool(te))
            truncs.append(bool(tr))
            infos.append(step_infos(self._inner, info))
            return o, r, te, tr, info

    episode = run_episode(_Recorder(env), agent, env_seed, agent_seed=agent_seed)
    if episode.ended_by == "agent" or not acts:
        raise ValueError(
            f"agent {getattr(agent, 'name', agent)!r} ends episodes itself (zero-crossing's Table 1 "
            f"layout); a dataset needs episodes the env ends"
        )
    stacked = {key: [i[key] for i in infos] for key in infos[0]}
    return EpisodeBuffer(
        id=k,
        seed=env_seed,
        observations=obs,
        actions=acts,
        rewards=rews,
        terminations=terms,
        truncations=truncs,
        infos=stacked,
    )


def _fast(storage: Any) -> Any:
    """``storage`` with its size left uncounted while episodes are appended.

    Minari's storage recounts the size of every file of the dataset after each episode it writes (a walk of
    the whole folder), which makes writing N episodes one by one O(N²); the size is counted once at the end.
    """
    storage.get_size = lambda: 0.0
    return storage


def _existing(ds_id: str) -> Any:
    """The local dataset ``ds_id`` (None: none)."""
    import minari
    from minari.storage.datasets_root_dir import get_dataset_path

    path = Path(get_dataset_path(ds_id))
    if not (path / "data" / "metadata.json").is_file():
        return None if not path.exists() else path
    return minari.load_dataset(ds_id)


def build_dataset(request: DatasetRequest, *, resume: bool = False, force: bool = False, progress: bool = True) -> Any:
    """Collect ``request`` into a local Minari dataset; returns the loaded ``MinariDataset``.

    Raises:
        ValueError: bad input, an existing id without ``resume``/``force``, a resumed dataset of other
            settings, an agent the env refuses, Minari not installed — one line each.
    """
    try:
        import minari
        from minari.storage.datasets_root_dir import get_dataset_path
    except ImportError as exc:
        raise ValueError(f"datasets need Minari ({MINARI_HINT}): {exc}") from None
    import gymnasium as gym
    from tqdm import tqdm

    from electroloc_gym.bench.agents import make_bench_agent, policy_env_problem

    ds_id = request.id
    agent = make_bench_agent(request.agent, trust_pickle=request.trust_pickle)
    why = policy_env_problem(request.agent, agent, request.env_id, None)
    if why is not None:
        raise ValueError(f"agent {request.agent!r} cannot run on {request.env_id}: {why}")
    if getattr(agent, "table_layout", None) == "table1":  # the agent reports its own estimate and stops (Table 1)
        raise ValueError(
            f"agent {request.agent!r} ends episodes itself (zero-crossing's Table 1 layout); a dataset "
            f"needs episodes the env ends"
        )
    kwargs = dataset_env_kwargs(request.env_id, agent, request.condition)
    refs = None if request.reference is None else reference_scores(request.reference, request.env_id)
    seeds = [episode_seeds(request.seed, k)[0] for k in range(request.episodes)]
    clash = evaluation_overlap(seeds)
    if clash:  # pragma: no cover - the stream is disjoint by construction; this guards a changed protocol
        raise ValueError(f"dataset seeds {clash[:3]} are evaluation seeds; choose another seed")
    block = {
        "agent": request.agent.strip(),
        "env_id": request.env_id,
        "env_kwargs": kwargs,
        "seed": request.seed,
        "evaluation_seed": EVALUATION_SEED,
        "episodes_planned": request.episodes,
        "complete": False,
        "reference": refs,
        "seed_protocol": "SeedSequence(seed, spawn_key=(9, episode)); benchmark trials use root seed 0, streams 0-8",
    }
    existing = _existing(ds_id)
    start = 0
    if existing is not None and force:
        shutil.rmtree(get_dataset_path(ds_id))
        existing = None
    if isinstance(existing, Path):
        raise ValueError(f"{existing} exists but holds no Minari dataset; remove it or pass --force")
    if existing is not None:
        old = existing.storage.metadata.get("electroloc")
        old = old if isinstance(old, dict) else {}
        if old.get("complete", True) or not resume:
            state = "a complete" if old.get("complete", True) else "an unfinished"
            raise ValueError(
                f"dataset {ds_id!r} exists ({state} one at {get_dataset_path(ds_id)}); pass --force "
                f"to replace it" + ("" if old.get("complete", True) else " or --resume to continue it")
            )
        same = {k: old.get(k) for k in ("agent", "env_id", "env_kwargs", "seed")}
        if same != {k: block[k] for k in same}:
            raise ValueError(f"dataset {ds_id!r} was started with other settings {same}; pass --force to replace it")
        start = int(existing.storage.total_episodes)
    env = gym.make(request.env_id, **kwargs)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # Minari's reminders of optional metadata
            bar = tqdm(total=request.episodes, initial=start, desc=ds_id, unit="episode", disable=not progress)
            for k in range(start, request.episodes):
                buffer = _episode_buffer(env, agent, k, request.seed)
                if k == 0:
                    extra = (
                        {}
                        if refs is None
                        else {"ref_min_score": refs["ref_min_score"], "ref_max_score": refs["ref_max_score"]}
                    )
                    minari.create_dataset_from_buffers(
                        ds_id,
                        [buffer],
                        env=env.spec,
                        algorithm_name=request.agent.strip(),
                        description=f"{request.agent.strip()} on {request.env_id} (electroloc-gym), episodes on "
                        f"training seeds",
                        author="electroloc-gym",
                        author_email="none",
                        code_permalink="electroloc_gym/dataset/collect.py",
                        data_format="arrow",
                        requirements=["electroloc-gym"],
                        **extra,
                    )
                    storage = _fast(minari.load_dataset(ds_id).storage)
                    storage.update_metadata({"electroloc": block})
                else:
                    storage = storage if k > start else _fast(minari.load_dataset(ds_id).storage)
                    storage.update_episodes([buffer])
                bar.update(1)
            bar.close()
            storage = storage if request.episodes > start else minari.load_dataset(ds_id).storage
            storage.update_metadata(
                {"electroloc": {**block, "complete": True}, "dataset_size": type(storage).get_size(storage)}
            )
    finally:
        env.close()
    return minari.load_dataset(ds_id)
