"""The benchmark's agent registry: the paper's controllers, the shipped learned policies, policy paths.

An agent *spec* (what ``--agents`` takes, and the ``agent`` key of every trial record) is one of

* a controller of the paper, optionally with options: ``rnd-wlk``, ``min-var``, ``zero-crossing``,
  ``min-var[n_voters=2500]`` — built by :func:`electroloc_gym.baselines.make_agent`;
* the name of a shipped learned policy, ``ppo-belief`` — a folder of ``electroloc_gym.models``
  (the repository's ``models/``, installed with the package);
* a path to a model folder or a policy file (anything with a ``/``, starting with ``.`` or ``~``,
  ending in ``.zip``, or an existing folder).

Learned policies load through :func:`electroloc_gym.train.policy.load_policy`, which reads the
project's pickle-free policy files; a bare SB3 ``.zip`` (pickle inside) loads only with
``trust_pickle=True`` (``--trust-pickle``). The paper's controllers never import the training package.
Nothing is picked up from the working directory: a default run uses the shipped models only.
"""

from __future__ import annotations

import importlib.util
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from electroloc_gym.baselines.agent import AGENT_REGISTRY, EXTRA_AGENTS, make_agent

__all__ = [
    "AgentChoice",
    "shipped_models",
    "is_policy_path",
    "agent_kind",
    "agent_display_name",
    "make_bench_agent",
    "cached_agent",
    "default_agents",
    "TRAIN_EXTRA_HINT",
]

TRAIN_EXTRA_HINT = "pip install 'electroloc-gym[train]'"


@dataclass(frozen=True)
class AgentChoice:
    """An agent a default run considered: its spec, and why it was skipped (None: it runs)."""

    spec: str
    skipped: str | None = None


def shipped_models() -> dict[str, Path]:
    """Name → folder of every shipped learned policy (a folder of ``electroloc_gym.models``)."""
    from electroloc_gym.models import MODELS_DIR

    return {p.name: p for p in sorted(MODELS_DIR.iterdir())
            if p.is_dir() and not p.name.startswith((".", "_")) and any(p.iterdir())}


def is_policy_path(spec: str) -> bool:
    """True when ``spec`` is written as a path (``/``, leading ``.`` or ``~``, ``.zip``) or is a folder."""
    return ("/" in spec or "\\" in spec or spec.startswith((".", "~")) or spec.endswith(".zip")
            or Path(spec).is_dir())


def agent_kind(spec: str) -> str:
    """``"baseline"``, ``"shipped"`` or ``"path"``.

    Raises:
        ValueError: a spec that is none of them (the message lists the choices).
    """
    if not isinstance(spec, str) or not spec.strip():
        raise ValueError(f"agent must be a non-empty string, got {spec!r}")
    spec = spec.strip()
    name = spec.split("[", 1)[0]
    if name in AGENT_REGISTRY or name in EXTRA_AGENTS:  # the paper's controllers, and ours beyond the paper
        return "baseline"
    if spec in shipped_models():
        return "shipped"
    if is_policy_path(spec):
        return "path"
    raise ValueError(f"unknown agent {name!r}; choose from {list(AGENT_REGISTRY + EXTRA_AGENTS)} (options as "
                     f"NAME[key=value]), "
                     f"a shipped model {sorted(shipped_models())}, or a path to a model folder / policy file")


def agent_display_name(spec: str) -> str:
    """A short name for progress bars and logs: the spec itself, or a path's folder / file name."""
    if "/" not in spec and "\\" not in spec:
        return spec
    p = Path(spec.rstrip("/\\"))
    return p.parent.name if p.name == "model.zip" and p.parent.name else (p.stem if p.suffix == ".zip" else p.name)


def _policy_path(spec: str) -> Path:
    if spec in shipped_models():
        return shipped_models()[spec]
    path = Path(spec).expanduser()
    if not path.exists():
        raise ValueError(f"agent path {spec!r} does not exist (expected a model folder or a policy file)")
    return path


def make_bench_agent(spec: str, *, seed: int | None = None, trust_pickle: bool = False) -> Any:
    """Build the agent a spec names.

    Args:
        spec: see the module docstring.
        seed: seed of a controller's own generator (the runner re-seeds before each trial anyway).
        trust_pickle: allow a learned policy whose files need unpickling (SB3's bare zip). Only for
            files you trust: unpickling runs code.

    Raises:
        ValueError: an unknown name, bad options, a missing path, the training extra not installed, or
            a policy that does not load (the message names the path).
    """
    kind = agent_kind(spec)
    spec = spec.strip()
    if kind == "baseline":
        return make_agent(spec, seed=seed)
    path = _policy_path(spec)
    try:
        from electroloc_gym.policy import load_policy
    except ImportError as exc:
        raise ValueError(f"cannot load policy {str(path)!r}: the training extra is not installed "
                         f"({TRAIN_EXTRA_HINT}): {exc}") from exc
    try:
        agent = load_policy(path, trust_pickle=trust_pickle)
    except ValueError as exc:
        raise ValueError(f"cannot load policy {spec!r}: {exc}") from exc
    except Exception as exc:  # noqa: BLE001 - any loader failure is reported with the path
        raise ValueError(f"cannot load policy {spec!r} ({path}): {type(exc).__name__}: {exc}") from exc
    if kind == "shipped":
        agent.name = spec
    return agent


_CACHE: dict[tuple[str, bool], Any] = {}


def cached_agent(spec: str, *, trust_pickle: bool = False) -> Any:
    """:func:`make_bench_agent`, built once per process (the runner re-seeds and resets it every trial)."""
    key = (spec, bool(trust_pickle))
    if key not in _CACHE:
        _CACHE[key] = make_bench_agent(spec, trust_pickle=trust_pickle)
    return _CACHE[key]


def _training_extra_missing() -> str | None:
    """Why learned policies cannot run here (None: they can)."""
    for module in ("electroloc_gym.policy",):
        try:
            if importlib.util.find_spec(module) is None:
                return f"the training extra is not installed ({module} missing; {TRAIN_EXTRA_HINT})"
        except (ImportError, ValueError) as exc:
            return f"the training extra is not importable ({module}: {exc})"
    return None


def shipped_model_env(folder: Path) -> tuple[str, tuple[float, ...] | None] | None:
    """(env id, gain levels) a shipped policy was trained on (its policy.json's ``observation.env_id``
    and ``env_kwargs.gain_levels``; plain JSON), or None if the file does not say.
    """
    try:
        with open(folder / "policy.json", encoding="utf-8") as f:
            meta = json.load(f)
        env_id = meta["observation"]["env_id"]
        gains = (meta.get("env_kwargs") or {}).get("gain_levels")
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None
    if not isinstance(env_id, str):
        return None
    return env_id, None if gains is None else tuple(float(g) for g in gains)


def default_agents(*, table4_only: bool = False, trust_pickle: bool = False, env_id: str = "ElectroLoc-v0",
                   gain_levels: tuple[float, ...] | None = None) -> list[AgentChoice]:
    """What a run without ``--agents`` considers: the paper's controllers, then every shipped model
    trained on ``env_id``.

    A shipped model that cannot run here is listed with the reason it is skipped (the training
    extra missing, its files not loading, or another env).

    Args:
        table4_only: only particle-filter controllers (the global env: rnd-wlk, min-var), then the
            shipped models trained on ``env_id``.
        trust_pickle: passed to the policy loader.
        env_id: the run's env.
        gain_levels: the run's dynamic-gain levels (then min-var runs twice: choosing the gain, and at the
            preset gain).
    """
    choices = [AgentChoice("rnd-wlk"), AgentChoice("min-var")] if table4_only else \
        [AgentChoice(name) for name in AGENT_REGISTRY]
    if gain_levels is not None:
        choices.insert(2, AgentChoice("min-var[gain=preset]"))
    models = shipped_models()
    missing = _training_extra_missing() if models else None
    for name, folder in models.items():
        trained_on = shipped_model_env(folder)
        if trained_on is not None and trained_on != (env_id, gain_levels):
            what = trained_on[0] + ("" if trained_on[1] is None else f" with gain_levels={list(trained_on[1])}")
            here = env_id + ("" if gain_levels is None else f" with gain_levels={list(gain_levels)}")
            choices.append(AgentChoice(name, skipped=f"trained on {what}, not {here}"))
            continue
        if missing:
            choices.append(AgentChoice(name, skipped=missing))
            continue
        try:
            cached_agent(name, trust_pickle=trust_pickle)
        except ValueError as exc:
            choices.append(AgentChoice(name, skipped=str(exc)))
        else:
            choices.append(AgentChoice(name))
    return choices
