"""One call from (algorithm, env, seed, budget) to an rl-zoo3 run folder and its export — resumable.

    from electroloc_gym.train.run import train
    run = train("ppo", "ElectroLoc-v0", seed=3000, timesteps=1_000_000, out="electroloc_gym/models/ppo-belief")

:func:`zoo_argv` is the exact ``python -m rl_zoo3.train`` command (through the native-vector-env
hook :mod:`electroloc_gym.train.zoo`); :func:`train` runs it in a child process (its own thread
pinning, its output teed to ``<log_folder>/<algo>/<env>_s<seed>.log``), then exports the chosen
checkpoint when ``out`` is given. The run folder is the one whose ``summary.json`` (written by the
evaluation callback, :mod:`electroloc_gym.train.callbacks`) records this command as finished.

Why a child process and not rl-zoo3's ``ExperimentManager`` in this one: the command a run records
is then exactly what rl-zoo3's own front door parsed (a user re-runs it as printed), the numeric
libraries of the run are pinned to one thread before they load, and a run that dies (out of memory,
an interrupt) leaves the caller — a suite of many runs — standing.

A run whose ``summary.json`` records the same command and finished is found again instead of
retrained, and an ``out`` already exported from it is kept: re-running a script of calls only trains
what is missing. Timing is the run's own (``summary.json``: wall time, validation time, training-only
fps).
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from electroloc_gym.registry import plugin_modules, resolve_env_name
from electroloc_gym.train.settings import ALGO_FILES, check_train_settings, hyperparams_file
from electroloc_gym.train.summary import read_summary
from electroloc_gym.utils.fileio import user_path
from electroloc_gym.utils.runtime import chosen_threads, thread_env

__all__ = [
    "ALGO_FILES",
    "ZOO_EXTRA_HINT",
    "check_zoo_installed",
    "child_env",
    "find_finished_run",
    "hyperparams_file",
    "train",
    "zoo_argv",
]

#: What a training run imports beyond the package's own dependencies (rl-zoo3 brings SB3 and torch).
ZOO_MODULES = ("rl_zoo3", "stable_baselines3", "sb3_contrib", "torch")
#: The one line a missing training dependency gets: the extra that installs all of them.
ZOO_EXTRA_HINT = 'training needs the zoo extra: pip install -c constraints.txt "electroloc-gym[zoo]"'


def child_env(log_folder: str | os.PathLike[str], threads: int | None = None) -> dict[str, str]:
    """The training process's environment: this one's, its threads pinned (:func:`thread_env`), and SB3's
    logger folder (``SB3_LOGDIR``, unless set) the run's log folder. SB3 makes that folder for a logger
    that writes no file (``verbose`` 0 or 1, no tensorboard); left unset, each run would leave an empty
    ``SB3-<date>`` folder in the system's temporary folder.
    """
    return {"SB3_LOGDIR": os.fspath(log_folder), **os.environ, **thread_env(threads)}


def check_zoo_installed() -> None:
    """Refuse to start a run that cannot import rl-zoo3 and its stack (checked before the run's process starts).

    Raises:
        ModuleNotFoundError: one line naming the missing modules and :data:`ZOO_EXTRA_HINT`.
    """
    missing = [m for m in ZOO_MODULES if importlib.util.find_spec(m) is None]
    if missing:
        raise ModuleNotFoundError(f"{ZOO_EXTRA_HINT} (missing: {', '.join(missing)})", name=missing[0])


def _py_literal(v: Any) -> str:
    return repr(v)  # rl-zoo3's StoreDict evaluates each value as a Python literal


def check_env_kwargs(env_id: str, env_kwargs: Mapping[str, Any]) -> None:
    """Refuse env kwargs the env would refuse, before rl-zoo3 starts: the env is built once with them
    (its parameter dataclasses validate every value) and closed.
    """
    import gymnasium as gym

    try:
        gym.make(env_id, **dict(env_kwargs)).close()
    except (TypeError, ValueError) as exc:
        text = str(exc).strip().splitlines()
        raise ValueError(
            f"env_kwargs {dict(env_kwargs)!r} are refused by {env_id}: "
            f"{(text[0] if text else type(exc).__name__)[:300]}"
        ) from None


def zoo_argv(
    algo: str,
    env_id: str,
    seed: int,
    *,
    timesteps: int | None = None,
    log_folder: str | Path = "logs",
    conf_file: str | Path | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    hyperparams: Mapping[str, Any] | None = None,
    native: bool = True,
    threads: int | None = None,
    gym_packages: Sequence[str] = (),
) -> list[str]:
    """The ``python -m rl_zoo3.train`` arguments (without the interpreter) for one run.

    Args:
        algo: an rl-zoo3 algorithm with a file in :data:`ALGO_FILES`.
        env_id: a registered id the file has a section for, or ``MODULE:ENV_ID`` (an env of your own module,
            imported here and in the run).
        seed: the run's seed (≥ 0).
        timesteps: env-step budget (None: the file's ``n_timesteps``).
        log_folder: rl-zoo3's ``--log-folder`` (runs go to ``<log_folder>/<algo>/<env>_<n>``).
        conf_file: another hyper-parameter file (default: :func:`hyperparams_file`).
        env_kwargs: replaces the file's ``env_kwargs`` (rl-zoo3's rule), values as Python literals.
        hyperparams: overrides of single hyper-parameters.
        native: train on the native vector env (False: rl-zoo3's default DummyVecEnv).
        threads: torch's threads in the run (rl-zoo3's ``--num-threads``; default
            :func:`~electroloc_gym.utils.runtime.chosen_threads`: ``$ELECTROLOC_THREADS`` or 1).
        gym_packages: modules rl-zoo3 imports too (``--gym-packages``): a researcher's module that registers
            ``env_id`` at import (``electroloc train --env my_module:MyTask-v0``).
    """
    check_train_settings(
        dict(
            algo=algo,
            env_id=env_id,
            seed=seed,
            timesteps=timesteps,
            log_folder=log_folder,
            conf_file=conf_file,
            env_kwargs=env_kwargs,
            hyperparams=hyperparams,
            native=native,
        ),
        lambda o: o.name,
    )
    env_id = resolve_env_name(env_id, "env_id")  # MODULE:ENV_ID imports MODULE, which registers ENV_ID
    gym_packages = tuple(dict.fromkeys((*gym_packages, *plugin_modules())))
    n_threads = chosen_threads(threads)
    conf = Path(conf_file) if conf_file is not None else hyperparams_file(algo)
    if conf.is_absolute() and conf.is_relative_to(Path.cwd()):
        conf = conf.relative_to(Path.cwd())  # the command as typed from the repository root
    if env_kwargs:
        check_env_kwargs(env_id, env_kwargs)
    argv = [
        "-m",
        "rl_zoo3.train",
        "--algo",
        algo,
        "--env",
        env_id,
        "--gym-packages",
        "electroloc_gym.train.zoo" if native else "electroloc_gym",
        *gym_packages,
        "--conf-file",
        str(conf),
        "--seed",
        str(seed),
        "--log-folder",
        str(user_path(log_folder)),
        "--eval-freq",
        "-1",
        "--num-threads",
        str(n_threads),
    ]
    if timesteps is not None:
        argv += ["-n", str(timesteps)]
    if env_kwargs:
        argv += ["--env-kwargs", *(f"{k}:{_py_literal(v)}" for k, v in env_kwargs.items())]
    if hyperparams:
        argv += ["--hyperparams", *(f"{k}:{_py_literal(v)}" for k, v in hyperparams.items())]
    return argv


def find_finished_run(log_folder: str | Path, algo: str, env_id: str, argv: Sequence[str]) -> Path | None:
    """The newest finished run folder whose ``summary.json`` records exactly ``argv``, or None."""
    found = []
    for summary in Path(log_folder, algo).glob(f"{env_id}_*/summary.json"):
        try:
            s = read_summary(summary)
        except ValueError:
            continue
        if s.finished and s.argv == list(argv):
            found.append(summary.parent)
    return max(found, key=lambda p: p.stat().st_mtime) if found else None


def train(
    algo: str,
    env_id: str,
    seed: int,
    *,
    timesteps: int | None = None,
    log_folder: str | Path = "logs",
    out: str | Path | None = None,
    conf_file: str | Path | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    hyperparams: Mapping[str, Any] | None = None,
    native: bool = True,
    quiet: bool = False,
    threads: int | None = None,
    gym_packages: Sequence[str] = (),
) -> Path:
    """Train (or find the finished run of) one configuration; export it to ``out``; return the run folder.

    Its settings are ``electroloc train``'s, declared once (:data:`~.settings.TRAIN_OPTIONS`: the same
    defaults, checks and one-line refusals; :func:`zoo_argv` says what each is). ``quiet`` keeps the run's
    output to its log only, ``gym_packages`` adds modules the run imports. The run's process starts with
    ``threads`` threads per numeric library.

    Raises:
        ValueError: a bad argument (one line naming it), or a run that fails (its log named).
        ModuleNotFoundError: rl-zoo3 or its stack missing (:func:`check_zoo_installed`: the zoo extra).
    """
    check_train_settings({"out": out}, lambda o: o.name)
    argv = zoo_argv(
        algo,
        env_id,
        seed,
        timesteps=timesteps,
        log_folder=log_folder,
        conf_file=conf_file,
        env_kwargs=env_kwargs,
        hyperparams=hyperparams,
        native=native,
        threads=threads,
        gym_packages=gym_packages,
    )
    env_id = argv[argv.index("--env") + 1]  # MODULE:ENV_ID resolved
    log_folder = user_path(log_folder)
    run = find_finished_run(log_folder, algo, env_id, argv)
    if run is None:
        check_zoo_installed()
        log = Path(log_folder, algo, f"{env_id}_s{seed}.log")
        log.parent.mkdir(parents=True, exist_ok=True)
        env = child_env(log.parent, threads)
        lines = []
        with (
            log.open("w", encoding="utf-8") as fh,
            subprocess.Popen(
                [sys.executable, *argv], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env
            ) as proc,
        ):
            if proc.stdout is None:
                raise RuntimeError("the training subprocess has no stdout pipe")
            for line in proc.stdout:
                fh.write(line)
                lines.append(line)
                if not quiet:
                    print(line, end="", flush=True)
        if proc.returncode != 0:
            tail = "".join(lines[-3:]).strip().splitlines()
            raise ValueError(f"rl-zoo3 run failed (exit {proc.returncode}; log {log}): {tail[-1] if tail else ''}")
        run = find_finished_run(log_folder, algo, env_id, argv)  # the callback's summary.json records argv
        if run is None:
            raise ValueError(
                f"rl-zoo3 finished but no run folder under {Path(log_folder, algo)} records this "
                f"command as finished (log {log})"
            )
    if out is not None:
        from electroloc_gym.train.export import export_run

        dest = user_path(out)
        done = dest / "summary.json"
        same = done.is_file() and read_summary(done).argv == read_summary(run / "summary.json").argv
        if not same:
            export_run(run, dest)
    return run
