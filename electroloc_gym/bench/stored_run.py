"""A stored run read back: its config.json, the rules its records obey, and the one public reader.

:func:`read_run_records` reads a run's folder (``electroloc bench --out``) with the run's own rules
(:func:`record_rules`), so every reader of benchmark records (``--resume``, the reports) keeps and sets aside
the same records; :func:`read_config` is ``--resume``'s read of ``config.json`` (a damaged one is set aside),
:func:`load_config` the strict one.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import msgspec

from electroloc_gym.bench.config import IDENTITY_KEYS, BenchConfig
from electroloc_gym.bench.records import CONFIG_FILE, TRIALS_FILE, LoadedRecords, load_records, stored_trials
from electroloc_gym.bench.schema import OPTIONAL_RECORD_KEYS, RecordRules
from electroloc_gym.registry import env_entry
from electroloc_gym.utils.fileio import user_path

__all__ = ["RunRecords", "read_run_records", "record_rules", "read_config", "config_from_json", "load_config"]


#: Keys every config.json holds (those added later, as to the records, read as their defaults when absent).
_REQUIRED = ("seed", *(k for k in IDENTITY_KEYS if k not in OPTIONAL_RECORD_KEYS))


def _config(stored: Any) -> BenchConfig:
    """``stored`` (a parsed config.json) decoded by msgspec into the one declaration of a run, :class:`BenchConfig`
    (its field types, then its settings' checks in ``__post_init__``; keys beyond its fields are the record's).

    Raises:
        ValueError: not a run's config — one line naming the field.
    """
    if isinstance(stored, dict):
        missing = [k for k in _REQUIRED if k not in stored]
        if missing:
            raise ValueError(f"missing key(s) {missing}")
    try:
        return msgspec.convert(stored, BenchConfig)
    except msgspec.ValidationError as exc:
        raise ValueError(str(exc)) from None


def _decode(data: bytes) -> Any:
    """A config.json's bytes as JSON (a ValueError saying why they are not: malformed, not UTF-8, nested too deep)."""
    try:
        return msgspec.json.decode(data)
    except (msgspec.DecodeError, RecursionError) as exc:
        raise ValueError(f"not valid UTF-8 JSON ({type(exc).__name__}: {exc})") from None


def read_config(path: Path, log: Callable[[str], None] | None) -> dict[str, Any] | None:
    """config.json of a stored run; a damaged one is reported, set aside (renamed) and ignored."""
    if not path.exists():
        return None
    try:
        stored = _decode(path.read_bytes())
        _config(stored)
    except ValueError as exc:
        why = str(exc)
    else:
        return stored
    aside = path.with_name("config.rejected.json")
    os.replace(path, aside)
    if log is not None:
        log(f"{path}: {why}; moved to {aside.name}; every record is checked on its own instead")
    return None


def config_from_json(stored: Any, where: str = CONFIG_FILE) -> BenchConfig:
    """The :class:`BenchConfig` a config.json holds.

    Raises:
        ValueError: not a run's config (one line naming ``where`` and the problem).
    """
    try:
        return _config(stored)
    except ValueError as exc:
        raise ValueError(f"{where}: not a benchmark run's config: {exc}") from None


def load_config(path: str | os.PathLike[str]) -> BenchConfig:
    """The :class:`BenchConfig` of the config.json at ``path``, read strictly (a report's or a script's read:
    nothing is set aside, unlike :func:`read_config`'s on ``--resume``).

    Raises:
        ValueError: unreadable, not JSON, or not a run's config — one line naming the file.
    """
    path = Path(path)
    try:
        stored = _decode(path.read_bytes())
    except OSError as exc:
        raise ValueError(f"{path}: not readable ({exc.strerror or type(exc).__name__})") from None
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    return config_from_json(stored, str(path))


class _StartReplay:
    """(condition, agent, env seed) → the start the trial's env draws on ``reset(seed)``, mm.

    The start is a function of the run's settings, the agent's env kwargs and the seed; it is replayed
    on one env per (condition, agent kind), built as the trial's (no trial is run).
    """

    def __init__(self, config: BenchConfig, trust_pickle: bool) -> None:
        self.config, self.trust_pickle = config, trust_pickle
        self._envs: dict[tuple[str, str], Any] = {}

    def __call__(self, condition: str, agent: str, seed: int) -> tuple[float, float] | None:
        import gymnasium as gym

        from electroloc_gym.bench.agents import builtin_agent

        cfg = self.config
        own = builtin_agent(agent)  # a built-in agent may set its own workspace; a plug-in's kwargs cannot move it
        key = (condition, agent if own is not None else "")
        if key not in self._envs:
            kwargs = cfg.env_kwargs(own, condition, builtin=own is not None)
            try:
                self._envs[key] = gym.make(cfg.env_id, **kwargs)
            except (TypeError, ValueError):
                self._envs[key] = None
        env = self._envs[key]
        if env is None:
            return None
        _, info = env.reset(seed=int(seed))
        start = info["position_mm"]
        return float(start[0]), float(start[1])


def record_rules(
    config: BenchConfig, stored: dict[str, Any] | None = None, *, trust_pickle: bool = False
) -> RecordRules:
    """What a record of ``config``'s run (continuing ``stored``, a config.json) may hold.

    Each agent's cap and success criterion are those its trials' env is built with
    (:meth:`~electroloc_gym.bench.config.BenchConfig.env_kwargs`): only the built-in agents declare their own
    (zero-crossing, the paper's Table-1 protocol, in its ``env_kwargs``); every other agent is held to the
    run's, so no plug-in code is run here.
    """
    from electroloc_gym.bench.agents import builtin_agent

    stored = stored or {}
    agents = frozenset([*config.agents, *(a for a in stored.get("agents", []) if isinstance(a, str))])
    conditions = frozenset([*config.conditions, *(c for c in stored.get("conditions", []) if isinstance(c, str))])
    trials = max(config.trials, stored["trials"] if isinstance(stored.get("trials"), int) else 0)
    caps, criteria, table_layouts = {}, {}, {}
    for spec in agents:
        agent = builtin_agent(spec)
        kwargs = config.env_kwargs(agent, builtin=agent is not None)
        caps[spec] = int(kwargs["max_observations"])
        criteria[spec] = float(kwargs["success_spread_mm"])
        table_layouts[spec] = str(getattr(agent, "table_layout", "table4"))
    return RecordRules(
        conditions=conditions,
        agents=agents,
        trials=trials,
        success_spread_mm=float(config.success_spread_mm),
        metrics=env_entry(config.env_id).task_class.metrics,
        caps=caps,
        criteria=criteria,
        table_layouts=table_layouts,
        start_of=_StartReplay(config, trust_pickle),
    )


@dataclass(frozen=True)
class RunRecords:
    """A benchmark run read back by :func:`read_run_records`.

    Attributes:
        config: the run (its ``config.json``).
        loaded: its records, kept, rejected and foreign (:class:`~electroloc_gym.bench.records.LoadedRecords`).
    """

    config: BenchConfig
    loaded: LoadedRecords

    @property
    def records(self) -> list[dict[str, Any]]:
        """The kept records, in file order."""
        return list(self.loaded.records.values())

    @property
    def n_set_aside(self) -> int:
        """Lines not kept: rejected plus foreign."""
        return self.loaded.n_rejected + self.loaded.n_foreign

    def messages(self) -> list[str]:
        """One line per line not kept: ``FILE:LINE: reason``."""
        return self.loaded.messages() + [
            f"{self.loaded.path}:{n}: not of this run: {why}" for n, why in self.loaded.foreign
        ]


def read_run_records(out_dir: str | os.PathLike[str]) -> RunRecords:
    """Read a benchmark run's folder (``electroloc bench --out``) as ``--resume`` reads it, writing nothing.

    ``OUT/config.json`` gives the run; every line of ``OUT/trials.jsonl`` (or of a kept run's
    ``trials.jsonl.gz``) is checked through the record schema and the run's rules (:func:`record_rules`); a
    line that fails is set aside and counted, a valid record of another run counted as foreign.

    Raises:
        ValueError: one line naming the file: the folder, its config.json or its trials.jsonl missing or
            unreadable, or config.json not a run's config.
    """
    folder = user_path(out_dir)
    if not folder.is_dir():
        raise ValueError(f"{folder}: not a benchmark output folder (no such folder)")
    config_path, trials_path = folder / CONFIG_FILE, stored_trials(folder / TRIALS_FILE)
    for path in (config_path, trials_path):
        if not path.is_file():
            raise ValueError(f"{path}: missing (not a benchmark output folder)")
    try:
        raw = config_path.read_bytes()
        if len(raw) > 1 << 20:
            raise ValueError(f"{len(raw)} bytes (a config is a few hundred)")
        stored = msgspec.json.decode(raw)
    except (OSError, msgspec.DecodeError, RecursionError, ValueError) as exc:
        raise ValueError(f"{config_path}: not readable as a run's config ({type(exc).__name__}: {exc})") from None
    config = config_from_json(stored, str(config_path))
    loaded = load_records(trials_path, config, record_rules(config, stored))
    return RunRecords(config=config, loaded=loaded)
