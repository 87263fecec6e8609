"""The settings of a training run, declared once: ``electroloc train``'s options and :func:`~.run.train`'s keywords.

Each setting is one :class:`~electroloc_gym.options.Option` of :data:`TRAIN_OPTIONS`: its flag, help, check and
defaults. The command line's parser is built from them (:func:`~electroloc_gym.options.add_options`), the Python
API checks its keywords with the same checks (:func:`check_train_settings`), and a refusal is the same one line
from both front ends, the setting named as each spells it (``--env`` / ``env_id``). Two settings are maps
(``env_kwargs``, ``hyperparams``): ``KEY=VALUE`` words on the command line (a value is a Python literal or else a
bare word, a string: the agent specs' rule), a mapping in Python. What is not a setting of the run stays with its
front end: ``--print-command`` and ``--threads`` (the process's) on the command line, ``quiet`` and
``gym_packages`` in Python.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import MISSING
from pathlib import Path
from typing import Any

from electroloc_gym.options import Option, SettingError, int_in, is_bool, one_of
from electroloc_gym.registry import ENV_IDS, PAPER_ENV_ID, resolve_env_name
from electroloc_gym.utils.fileio import check_output_folder

__all__ = ["ALGO_FILES", "MAX_TIMESTEPS", "SEED_LIMIT", "TRAIN_OPTIONS", "check_train_settings", "hyperparams_file"]

#: rl-zoo3 algorithm name → the project's hyper-parameter file (electroloc_gym/train/hyperparams/, keyed by env id).
ALGO_FILES = {
    "ppo": "ppo.yml",
    "a2c": "a2c.yml",
    "sac": "sac.yml",
    "crossq": "crossq.yml",
    "ppo_lstm": "ppo_lstm.yml",
    "qrdqn": "qrdqn.yml",
}
#: Seeds rl-zoo3 hands to ``np.random.seed`` (which takes [0, 2**32)).
SEED_LIMIT = 2**32
#: The largest env-step budget accepted (a trillion steps: far past any run, well inside SB3's int counters).
MAX_TIMESTEPS = 10**12


def hyperparams_file(algo: str) -> Path:
    """The shipped hyper-parameter file of ``algo`` (one of :data:`ALGO_FILES`)."""
    if algo not in ALGO_FILES:
        raise ValueError(f"algo must be one of {sorted(ALGO_FILES)}, got {algo!r}")
    return Path(__file__).parent / "hyperparams" / ALGO_FILES[algo]


def _env_name(name: str, value: Any) -> None:
    """A registered env id, or ``MODULE:ENV_ID`` (imports MODULE, which registers ENV_ID)."""
    import gymnasium as gym

    env_id = resolve_env_name(value, name)
    if not isinstance(env_id, str) or env_id not in gym.registry:
        raise SettingError(name, f"a registered env id ({', '.join(ENV_IDS)}) or package.module:ENV_ID", value)


def _folder(name: str, value: Any) -> None:
    """An output folder by the one rule of every command (:func:`~electroloc_gym.utils.fileio.check_output_folder`:
    nothing on its way a file, no dangling link, names within the limit, a real write; nothing created).
    """
    if not isinstance(value, (str, os.PathLike)):
        raise SettingError(name, "a folder path", value)
    check_output_folder(name, value)


def _file(name: str, value: Any) -> None:
    if not isinstance(value, (str, os.PathLike)) or not Path(value).is_file():
        raise SettingError(name, "an existing hyper-parameter file (YAML, rl-zoo3's format)", value)


def _mapping(name: str, value: Any) -> None:
    if not isinstance(value, Mapping) or not all(isinstance(k, str) and k.isidentifier() for k in value):
        raise SettingError(name, "a mapping of keyword names to values", value)


TRAIN_OPTIONS: tuple[Option, ...] = (
    Option(
        "algo",
        default=MISSING,
        check=one_of(lambda: sorted(ALGO_FILES)),
        choices=lambda: sorted(ALGO_FILES),
        bad=("td3", 3),
        help="rl-zoo3 algorithm",
    ),
    Option(
        "env_id",
        default=PAPER_ENV_ID,
        python_default=MISSING,
        flag="--env",
        check=_env_name,
        bad=("Nope-v0",),
        help="env id (a section of the algorithm's file, or of --conf-file), or package.module:ENV_ID, an env "
        "your own module registers (a task of your own, electroloc_gym.tasks): imported like any module, it "
        "runs your code, here and in the rl-zoo3 run (--gym-packages) (default: %(default)s)",
    ),
    Option(
        "seed",
        default=MISSING,
        kind="int",
        check=int_in(0, SEED_LIMIT - 1, " (NumPy's seed range)"),
        bad=(-1, SEED_LIMIT, True),
        help="the run's seed, 0 to 2**32 − 1",
    ),
    Option(
        "timesteps",
        default=None,
        kind="int",
        check=int_in(1, MAX_TIMESTEPS),
        bad=(0, MAX_TIMESTEPS + 1),
        help="env-step budget (default: the file's)",
    ),
    Option(
        "log_folder", default="logs", check=_folder, bad=("", 5), help="rl-zoo3's log folder (default: %(default)s)"
    ),
    Option("out", default=None, check=_folder, bad=(" ",), help="export the chosen checkpoint to this policy folder"),
    Option(
        "conf_file",
        default=None,
        check=_file,
        bad=("/no/such/file.yml",),
        help="another hyper-parameter file in rl-zoo3's format (default: the algorithm's shipped file)",
    ),
    Option(
        "env_kwargs",
        default=None,
        kind="pairs",
        check=_mapping,
        bad=(5, {"": 1}),
        help="replace the file's env_kwargs (rl-zoo3's rule), KEY=VALUE words (a value is a Python literal or "
        "else a bare word, a string: observation=belief)",
    ),
    Option(
        "hyperparams",
        default=None,
        kind="pairs",
        check=_mapping,
        bad=(["n_envs"],),
        help="override hyper-parameters, KEY=VALUE words (a value is a Python literal or else a bare word, a "
        "string: policy=MlpPolicy)",
    ),
    Option(
        "native",
        default=True,
        kind="negated",
        flag="--dummy",
        check=is_bool,
        bad=("yes",),
        help="rl-zoo3's default DummyVecEnv instead of the native env",
    ),
)


def check_train_settings(values: Mapping[str, Any], spell: Callable[[Option], str]) -> None:
    """The settings in ``values`` checked, each refusal one line naming the setting as ``spell`` spells it; with
    ``algo`` and ``env_id``, the env has a section in the hyper-parameter file (or the file a ``default`` one), as
    the rl-zoo3 run needs (a Python file is rl-zoo3's to run: not read here).
    """
    name = {opt.name: spell(opt) for opt in TRAIN_OPTIONS}
    for opt in TRAIN_OPTIONS:
        if opt.name in values:
            opt.check_value(name[opt.name], values[opt.name])
    if values.get("algo") is None or values.get("env_id") is None:
        return
    conf = Path(values["conf_file"]) if values.get("conf_file") is not None else hyperparams_file(values["algo"])
    if conf.suffix not in (".yml", ".yaml"):
        return
    import yaml

    try:
        sections = yaml.safe_load(conf.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise SettingError(name["conf_file"], "a hyper-parameter file in rl-zoo3's format", f"{conf}: {exc}") from None
    if not isinstance(sections, dict):
        raise SettingError(name["conf_file"], "a hyper-parameter file keyed by env id (rl-zoo3's format)", str(conf))
    env_id = str(resolve_env_name(values["env_id"], name["env_id"]))
    if env_id not in sections and "default" not in sections:
        raise SettingError(name["env_id"], f"an env id with a section in {conf.name} ({list(sections)})", env_id)
