"""Minari datasets of any benchmark agent: the collection run of ``electroloc dataset``, :func:`build_dataset`.

A dataset ``electroloc/<env-id>/<agent>-v<N>`` is one agent's episodes on one env in Minari's own format under
``MINARI_DATASETS_PATH`` (docs/learned.md). Its env spec is the benchmark's env kwargs for the agent with
``condition="random"`` (a preset drawn per episode from the reset seed); each episode is reset with its training
seed (:func:`~electroloc_gym.dataset.seed_protocol.episode_seeds`) and stores per step the infos of
:func:`step_infos` — for analysis and privileged critics, never an agent's input. The header holds the reference
scores (:func:`~electroloc_gym.dataset.seed_protocol.reference_scores`), the agent spec as ``algorithm_name`` and
an ``electroloc`` block (the settings, the planned count, the reference's provenance, ``complete``).

The episodes are the benchmark's rollout loop (:func:`electroloc_gym.baselines.rollout.run_episode`) with the
agent built by :func:`electroloc_gym.bench.agents.make_bench_agent`: every spec ``electroloc bench --agents``
takes works here. The settings are :mod:`electroloc_gym.dataset.request`; how the files are written, resumed
and replaced is :mod:`electroloc_gym.dataset.store`.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from electroloc_gym.dataset import store
from electroloc_gym.dataset.request import (
    BUILD_OPTIONS,
    DATASET_OPTIONS,
    MAX_EPISODES,
    REQUEST_OPTIONS,
    DatasetRequest,
    check_settings,
    dataset_id,
)
from electroloc_gym.dataset.seed_protocol import EVALUATION_SEED, episode_seeds, evaluation_overlap, reference_scores
from electroloc_gym.options import message_names, message_words

__all__ = [
    "DatasetRequest",
    "REQUEST_OPTIONS",
    "BUILD_OPTIONS",
    "DATASET_OPTIONS",
    "check_settings",
    "build_dataset",
    "dataset_id",
    "step_infos",
    "dataset_env_kwargs",
    "MAX_EPISODES",
    "MINARI_HINT",
]

MINARI_HINT = "pip install 'electroloc-gym[minari]'"
_ENDS_ITSELF = "ends episodes itself (zero-crossing's Table 1 layout); a dataset needs episodes the env ends"
_SEED_PROTOCOL = "SeedSequence(seed, spawn_key=(9, episode)); benchmark trials use root seed 0, streams 0-8"


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
    own in the mapped tank) and ``error_mm``; the hidden shape beyond the position (``truth_radius_mm``,
    ``truth_chi`` for the unknown target) and the task's own estimates its metrics name
    (``Task.metrics.dataset_info``). Read from the env's documented evaluation accessors.
    """
    core = env.unwrapped
    cov = np.asarray(core.belief.covariance(), dtype=np.float64)
    out: dict[str, Any] = {
        "estimate_mm": np.asarray(info["estimate_mm"], dtype=np.float64),
        "covariance_mm2": np.array([cov[0, 0], cov[0, 1], cov[1, 1]]),
        "spread_mm": np.float64(info["spread_mm"]),
        "n_observations": np.int64(info["n_observations"]),
        "reading_V": np.float64(np.ravel(info["reading_V"])[0]),
        "success": np.bool_(info["success"]),
        "condition_index": np.int64(info["condition_index"]),
        "truth_mm": np.asarray(core.truth_mm, dtype=np.float64).reshape(2),
        "error_mm": np.float64(info["error_mm"]),
    }
    for key, value in zip(core.hidden_keys[2:], core.hidden_state()[2:]):  # the hidden shape beyond the position
        out["truth_" + key.removeprefix("target_")] = np.float64(value)
    for key in core.entry().task_class.metrics.dataset_info:  # the task's own estimates (its declaration)
        out[key] = np.float64(info[key])
    return out


def _episode_buffer(env: Any, agent: Any, k: int, root_seed: int) -> Any:
    """Episode ``k``: the benchmark's rollout, recorded step by step into a Minari ``EpisodeBuffer``."""
    from minari.data_collector.episode_buffer import EpisodeBuffer

    from electroloc_gym.baselines.rollout import run_episode

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
        raise ValueError(f"agent {getattr(agent, 'name', agent)!r} {_ENDS_ITSELF}")
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


def _dataset_fields(request: DatasetRequest, refs: dict[str, Any] | None) -> dict[str, Any]:
    """The dataset fields of the header, as ``minari.create_dataset_from_buffers`` writes them."""
    import minari

    agent = request.agent.strip()
    fields: dict[str, Any] = {
        "dataset_id": request.id,
        "code_permalink": "electroloc_gym/dataset/collect.py",
        "author": ["electroloc-gym"],
        "author_email": ["none"],
        "algorithm_name": agent,
        "description": f"{agent} on {request.env_id} (electroloc-gym), episodes on training seeds",
        "minari_version": minari.__version__,
    }
    if refs is not None:
        fields.update(ref_max_score=refs["ref_max_score"], ref_min_score=refs["ref_min_score"])
    fields["requirements"] = ["electroloc-gym"]
    return fields


def _arrow_storage(folder: Any, env: Any, env_spec: Any = None) -> Any:
    """A new Minari arrow storage of ``env``'s spaces in ``folder`` (which it makes)."""
    from minari.dataset.minari_storage import MinariStorage

    return MinariStorage.new(
        folder,
        observation_space=env.observation_space,
        action_space=env.action_space,
        env_spec=env_spec,
        data_format="arrow",
    )


def _storage_fields(env: Any) -> dict[str, Any]:
    """The storage fields of the header (format, spaces, env spec), as Minari's own storage writes them."""
    with tempfile.TemporaryDirectory(prefix="electroloc-header-") as tmp:
        _arrow_storage(tmp, env, env.spec)
        return json.loads((Path(tmp) / "metadata.json").read_text(encoding="utf-8"))


def _write_episode(folder: Path, staging: Any, buffer: Any, digest: str) -> int:
    """Write ``buffer`` by Minari's ``staging`` storage, add the sha256 of its arrow file and the settings'
    ``digest`` to its metadata, and move it into ``folder/data/<id>`` whole; returns its step count.
    """
    k = int(buffer.id)
    staging.update_episodes([buffer])
    staged = Path(staging.data_path) / str(k)
    sha = store.file_sha256(staged / "part-0.arrow")
    staging.update_episode_metadata([{"sha256": sha, "settings_sha256": digest}], [k])
    os.rename(staged, folder / "data" / str(k))
    return len(buffer.rewards)


def _notify_stderr(message: str) -> None:
    print(f"electroloc_gym.dataset: {message}", file=sys.stderr)


def build_dataset(
    request: DatasetRequest,
    *,
    resume: bool = False,
    force: bool = False,
    progress: bool = False,
    notify: Callable[[str], None] | None = None,
    names: Mapping[str, str] | None = None,
) -> Any:
    """Collect ``request`` into a local Minari dataset; returns the loaded ``MinariDataset``.

    ``resume``, ``force`` and ``progress`` are :data:`BUILD_OPTIONS`; ``notify`` is called with one line when a
    resume sets something aside (default: printed to stderr); ``names``: how its messages name the settings
    (:func:`~electroloc_gym.options.message_names`; None: as Python spells them, ``force=True``).

    Raises:
        ValueError: bad input, an existing id without ``resume``/``force``, a resumed dataset of other
            settings, an id that is not exactly one dataset's, an agent the env refuses or whose
            ``seed``/``reset``/``predict`` raises, ``MINARI_DATASETS_PATH`` unusable, Minari not
            installed — one line each.
    """
    try:
        import minari
    except ImportError as exc:
        raise ValueError(f"datasets need Minari ({MINARI_HINT}): {exc}") from None
    import gymnasium as gym
    from tqdm import tqdm

    from electroloc_gym.baselines.rollout import AgentCallError
    from electroloc_gym.bench.agents import make_bench_agent, policy_env_problem

    check_settings({"resume": resume, "force": force, "progress": progress}, lambda o: o.name)
    if notify is not None and not callable(notify):
        raise ValueError(f"notify must be None or a callable taking one line, got {notify!r}")
    notify = notify or _notify_stderr
    names = message_words(message_names(DATASET_OPTIONS, lambda opt: opt.name), names)
    ds_id = request.id
    agent = make_bench_agent(request.agent, trust_pickle=request.trust_pickle)
    try:  # every read of a plug-in's attributes goes through the benchmark's guard: what raises is one line
        why = policy_env_problem(request.agent, agent, request.env_id, None)
        if why is not None:
            raise ValueError(f"agent {request.agent!r} cannot run on {request.env_id}: {why}")
        if getattr(agent, "table_layout", None) == "table1":  # it reports its own estimate and stops (Table 1)
            raise ValueError(f"agent {request.agent!r} {_ENDS_ITSELF}")
        kwargs = dataset_env_kwargs(request.env_id, agent, request.condition)
    except AgentCallError as exc:
        raise ValueError(f"agent {request.agent!r}: {exc}") from None
    if request.dataset_id is None:  # the default id, from the agent's name
        try:
            store.check_dataset_id(ds_id)
        except ValueError as exc:
            raise ValueError(f"the default {exc}; pass a shorter {names['dataset_id']}") from None
    refs = None if request.reference is None else reference_scores(request.reference, request.env_id)
    seeds = [episode_seeds(request.seed, k)[0] for k in range(request.episodes)]
    clash = evaluation_overlap(seeds)
    if clash:  # pragma: no cover - the stream is disjoint by construction; this guards a changed protocol
        raise ValueError(f"dataset seeds {clash[:3]} are evaluation seeds; choose another seed")
    settings = {"agent": request.agent.strip(), "env_id": request.env_id, "env_kwargs": kwargs, "seed": request.seed}
    paths = store.DatasetFolder(store.datasets_root(), ds_id)
    paths.check_location()
    with paths.lock():
        store.recover_swap(paths)
        paths.check_location()
        with gym.make(request.env_id, **kwargs) as env:
            run = _Run(request, paths, env, settings, refs, seeds, notify, names)
            if run.prepare(resume=resume, force=force):
                with tqdm(
                    total=request.episodes, initial=len(run.kept), desc=ds_id, unit="episode", disable=not progress
                ) as bar:
                    for k in range(request.episodes):
                        if k in run.kept:
                            continue
                        try:
                            buffer = _episode_buffer(env, agent, k, request.seed)
                        except (AgentCallError, ValueError) as exc:  # a method raised, or the env refused an action
                            raise ValueError(f"agent {request.agent!r} in episode {k} of {ds_id}: {exc}") from None
                        run.write(buffer)
                        bar.update(1)
                run.finish()
    return minari.load_dataset(ds_id)


class _Run:
    """One run's writing: the partial folder it fills, its header, the episodes kept (index → steps)."""

    def __init__(
        self,
        request: DatasetRequest,
        paths: store.DatasetFolder,
        env: Any,
        settings: dict[str, Any],
        refs: dict[str, Any] | None,
        seeds: list[int],
        notify: Callable[[str], None],
        names: Mapping[str, str],
    ) -> None:
        self.request, self.paths, self.env, self.settings, self.seeds = request, paths, env, settings, seeds
        self.refs, self.notify, self.names = refs, notify, names
        self.digest = store.settings_digest(settings)
        self.storage_fields = _storage_fields(env)
        self.kept: dict[int, int] = {}
        self.started = False  # the partial folder holds this run's header
        self.staging: Any = None  # Minari's storage in the partial's staging folder

    def header(self, *, complete: bool = False, size: float | None = None) -> dict[str, Any]:
        """The header of the episodes kept so far (Minari counts only the unbroken run 0, 1, …)."""
        n = min(set(range(len(self.kept) + 1)) - self.kept.keys())
        block = {
            **self.settings,
            "evaluation_seed": EVALUATION_SEED,
            "episodes_planned": self.request.episodes,
            "complete": complete,
            "reference": self.refs,
            "seed_protocol": _SEED_PROTOCOL,
            "checksums": "each episode's metadata.json: the sha256 of its part-0.arrow and of these settings",
        }
        header = {
            **self.storage_fields,
            "total_episodes": n,
            "total_steps": sum(self.kept[k] for k in range(n)),
            **_dataset_fields(self.request, self.refs),
        }
        if size is not None:
            header["dataset_size"] = size
        header["electroloc"] = block
        return header

    def prepare(self, *, resume: bool, force: bool) -> bool:
        """Decide what is kept: on resume (or a --force run's own partial of these settings) check every
        episode and set the damaged ones aside. False: a complete, intact dataset with nothing to collect.
        """
        path, partial, ds_id = self.paths.path, self.paths.partial, self.request.id
        published, started = os.path.lexists(path), os.path.lexists(partial)
        if not resume and not force and (published or started):
            where = f"a complete one at {path}" if published else f"an unfinished one at {partial}"
            hint = "check its episodes and re-collect damaged ones" if published else "continue it"
            raise ValueError(
                f"dataset {ds_id!r} exists ({where}); pass {self.names['force']} to replace it or "
                f"{self.names['resume']} to {hint}"
            )
        if resume and started and published:
            raise ValueError(
                f"dataset {ds_id!r} has an unfinished replacement at {partial}; pass {self.names['force']} to "
                "continue it"
            )
        if (
            force
            and started
            and store.settings_of((store.read_header(partial)[0] or {}).get("electroloc")) != self.settings
        ):
            store.remove(partial)  # an earlier --force run's leftovers, of other settings
            started = False
        folder = partial if started else path if resume and published else None
        if folder is None:
            return True
        found = store.inspect_dataset(ds_id, folder, self.settings, self.seeds, self.header(), self.names["force"])
        if self.refs is None and found.header is not None:  # the reference it was started with
            old_refs = found.header["electroloc"].get("reference")
            self.refs = old_refs if isinstance(old_refs, dict) and store.REFERENCE_KEYS <= old_refs.keys() else None
        self.kept = found.kept
        if folder == path:
            if found.intact(self.request.episodes):
                self.notify(
                    f"{ds_id}: complete; all {len(self.kept)} episodes match their checksums and read back: "
                    "nothing to collect"
                )
                return False
            os.rename(path, partial)  # continued as a partial, published again when complete
        moved_to = store.set_aside(partial, found)
        line = found.report(moved_to, self.request.episodes - len(self.kept))
        if line is not None:
            self.notify(f"{ds_id}: {line}")
        store.write_header(partial, self.header())
        self.started = True
        return True

    def write(self, buffer: Any) -> None:
        """Write one episode into the partial folder (made, with its header, before the first one)."""
        partial = self.paths.partial
        if not self.started:
            from minari.namespace import create_namespace, list_local_namespaces

            namespace = self.request.id.rsplit("/", 1)[0]
            try:
                create_namespace(namespace)
            except ValueError:  # it exists (another id's run may have made it meanwhile)
                if namespace not in list_local_namespaces():
                    raise
            store.start_partial(self.paths, self.header())
            self.started = True
        if self.staging is None:  # Minari's arrow storage in a fresh staging folder
            staging = partial / store.STAGING
            store.remove(staging)  # MinariStorage.new makes the folder
            self.staging = _arrow_storage(staging, self.env)
        self.kept[int(buffer.id)] = _write_episode(partial, self.staging, buffer, self.digest)

    def finish(self) -> None:
        """Flush every file to the disk, write the complete header (with its counts and size), publish."""
        from minari.dataset.minari_storage import MinariStorage

        partial = self.paths.partial
        store.remove(partial / store.STAGING)
        store.flush_to_disk(partial)
        size = MinariStorage.read(partial / "data").get_size()
        store.write_header(partial, self.header(complete=True, size=size))
        store.publish(self.paths)
