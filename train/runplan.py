"""What a training invocation will do, decided — and checked — before anything is written.

:func:`plan_run` turns the command line into a :class:`RunPlan`: a new run (config from the YAML
and the command line) or a resumed one (config from the resumed run's own ``config.yml``; options
that contradict it are refused), the model to continue from, the best evaluation score so far and
the observation statistics to restore. Every refusal is a :class:`ConfigError` naming the option.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from electroloc_gym.train.config import ConfigError, algo_class, resolve_hyperparams
from electroloc_gym.train.rundir import RunDir

if TYPE_CHECKING:
    from electroloc_gym.train.__main__ import Args

__all__ = ["RunPlan", "plan_run", "resolve_config", "latest_state", "best_so_far"]

_CONFIG_KEYS = ("algo", "env_id", "env_kwargs", "n_envs", "n_timesteps", "seed", "frame_stack", "shaping_coef",
                "normalize", "hyperparams")
_YAML_KEYS = ("hyperparams", "normalize", "frame_stack", "shaping_coef")


@dataclass(frozen=True)
class RunPlan:
    """A checked training invocation.

    Attributes:
        run_dir: the ``--out`` folder.
        config: the run's configuration (``config.yml``); ``n_timesteps`` is the run's total budget.
        resume_zip: the model zip continued from, or None for a new run.
        continues_out: the resumed model lies inside ``--out`` (the same run goes on).
        timesteps_done: timesteps already trained (0 for a new run).
        normalization: the ``policy.json`` statistics to restore, or None.
        best_mean_steps: best evaluation score of the run so far (``inf`` if none).
        best_timesteps: when it was reached.
    """

    run_dir: RunDir
    config: dict[str, Any]
    resume_zip: Path | None = None
    continues_out: bool = False
    timesteps_done: int = 0
    normalization: dict[str, Any] | None = None
    best_mean_steps: float = math.inf
    best_timesteps: int | None = None


def resolve_config(args: Args) -> dict[str, Any]:
    """A new run's resolved config: YAML section + command line (the command line wins), all checked."""
    algo_class(args.algo)  # fail early on an unknown / uninstalled algorithm
    hp = resolve_hyperparams(args.hyperparams, args.algo, args.env)
    env_kwargs = {**hp.get("env_kwargs", {}), **args.env_kwargs}
    normalize = hp.get("normalize", False)
    normalize = ({} if normalize else None) if isinstance(normalize, bool) else dict(normalize)
    return {
        "algo": args.algo,
        "env_id": args.env,
        "env_kwargs": env_kwargs,
        "n_envs": int(args.n_envs or hp.get("n_envs", 1)),
        "n_timesteps": int(args.timesteps or hp.get("n_timesteps", 100_000)),
        "seed": args.seed,
        "frame_stack": int(hp.get("frame_stack", 1)),
        "shaping_coef": float(hp.get("shaping_coef", 0.0)),
        "normalize": normalize,
        "hyperparams": {k: v for k, v in hp.items()
                        if k not in ("env_kwargs", "n_envs", "n_timesteps", "frame_stack", "shaping_coef",
                                     "normalize")},
        "hyperparams_file": str(args.hyperparams),
        "evaluation": _evaluation(args),
    }


def _evaluation(args: Args) -> dict[str, Any]:
    """The evaluation protocol: part of the run, since best/ compares scores measured with it."""
    return {"episodes": args.eval_episodes, "seed": args.eval_seed, "env_kwargs": dict(args.eval_env_kwargs)}


def latest_state(folder: Path) -> Path:
    """The model zip of ``folder``'s run with the most timesteps (final model or a checkpoint).

    Raises:
        ConfigError: the run has no saved model.
    """
    from electroloc_gym.train.resume import zip_timesteps

    candidates = [(zip_timesteps(p), p.parent == folder, p)
                  for p in [folder / "model.zip", *folder.glob("checkpoints/step_*/model.zip")] if p.is_file()]
    if not candidates:
        raise ConfigError(f"--resume: {folder} holds no saved model (model.zip or checkpoints/step_N/) to continue")
    return max(candidates, key=lambda c: (c[0], c[1]))[2]


def best_so_far(folder: Path) -> tuple[float, int | None]:
    """The run's best evaluation score (mean steps) and its timesteps, from ``best/``; (inf, None) if none.

    Raises:
        ConfigError: ``best/`` exists but its score cannot be read (it would be replaced blindly).
    """
    best = folder / "best"
    if not best.is_dir():
        return math.inf, None
    row = None
    try:
        if (best / "policy.json").is_file():
            row = json.loads((best / "policy.json").read_text(encoding="utf-8")).get("evaluation")
        elif (best / "config.yml").is_file():
            import yaml

            row = (yaml.safe_load((best / "config.yml").read_text(encoding="utf-8")) or {}).get("eval")
        if row is None:
            return math.inf, None
        return float(row["mean_steps"]), int(row["timesteps"])
    except (ValueError, TypeError, KeyError, AttributeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"--resume: cannot read the best evaluation score in {best} ({type(exc).__name__}: "
                          f"{exc}); a resumed run compares against it before replacing best/ — fix or remove "
                          f"{best}") from exc


def _inside(path: Path, folder: Path) -> bool:
    try:
        path.resolve().relative_to(folder.resolve())
    except ValueError:
        return False
    return True


def _saved_config(folder: Path) -> dict[str, Any]:
    from electroloc_gym.train.policy import read_run_config
    from electroloc_gym.train.validation import check_algo_values, check_policy_kwargs

    try:
        cfg = read_run_config(folder)
    except ValueError as exc:
        raise ConfigError(f"--resume: {exc}") from exc
    missing = [k for k in _CONFIG_KEYS if k not in cfg]
    if missing:
        raise ConfigError(f"--resume: {folder}/config.yml lacks {missing}; cannot continue a run without its "
                          f"configuration")
    where = f"{folder}/config.yml"
    hp = dict(cfg["hyperparams"] or {})
    check_algo_values(hp, cfg["algo"], where)
    if hp.get("policy_kwargs"):
        check_policy_kwargs(hp["policy_kwargs"], cfg["algo"], hp.get("policy", "MlpPolicy"), where)
    cfg.pop("eval", None)
    cfg.pop("device", None)
    return cfg


def _conflicts(args: Args, saved: dict[str, Any], same_run: bool) -> list[str]:
    """Options given on the command line that contradict the resumed run's own configuration.

    The evaluation protocol only matters when the same run goes on (``same_run``): its ``best/`` holds a
    score measured with it. A run branched into a new folder may evaluate differently.
    """
    out = []
    given = set(args.explicit)
    if "algo" in given and args.algo != saved["algo"]:
        out.append(f"--algo {args.algo} (the run: {saved['algo']})")
    if "env" in given and args.env != saved["env_id"]:
        out.append(f"--env {args.env} (the run: {saved['env_id']})")
    if "n_envs" in given and args.n_envs != saved["n_envs"]:
        out.append(f"--n-envs {args.n_envs} (the run: {saved['n_envs']})")
    if "env_kwargs" in given:
        for k, v in args.env_kwargs.items():
            if saved["env_kwargs"].get(k, "<unset>") != v:
                out.append(f"--env-kwargs {k}={v} (the run: {saved['env_kwargs'].get(k, '<unset>')})")
    ev = (saved.get("evaluation") or {}) if same_run else {}
    for key, flag in (("episodes", "eval_episodes"), ("seed", "eval_seed"), ("env_kwargs", "eval_env_kwargs")):
        if flag in given and key in ev and getattr(args, flag) != ev[key]:
            out.append(f"--{flag.replace('_', '-')} {getattr(args, flag)} (the run evaluates with {ev[key]}; "
                       f"best/ compares scores of that protocol)")
    if "hyperparams" in given:
        new = resolve_config(replace(args, algo=saved["algo"], env=saved["env_id"], env_kwargs={}))
        for key in _YAML_KEYS:
            if new[key] != saved[key]:
                if isinstance(new[key], dict) and isinstance(saved[key], dict):
                    keys = sorted(k for k in set(new[key]) | set(saved[key]) if new[key].get(k) != saved[key].get(k))
                    out.append(f"--hyperparams {args.hyperparams}: {key} differs in {keys}")
                else:
                    out.append(f"--hyperparams {args.hyperparams}: {key} = {new[key]!r} (the run: {saved[key]!r})")
        for k, v in new["env_kwargs"].items():
            if saved["env_kwargs"].get(k, "<unset>") != v:
                out.append(f"--hyperparams {args.hyperparams}: env_kwargs {k}={v!r} "
                           f"(the run: {saved['env_kwargs'].get(k, '<unset>')!r})")
    return out


def _saved_normalization(folder: Path, cfg: dict[str, Any]) -> dict[str, Any] | None:
    from electroloc_gym.train.policy_format import PolicyFormatError, read_export

    if cfg["normalize"] is None:
        return None
    try:
        export = read_export(folder)
    except PolicyFormatError as exc:
        raise ConfigError(f"--resume: the run normalises observations but their statistics cannot be read: {exc} "
                          f"(vecnormalize.pkl is never read: it is a pickle)") from exc
    norm = export.meta.get("normalization")
    if norm is None:
        raise ConfigError(f"--resume: {folder}/config.yml normalises observations but policy.json has no "
                          f"normalisation statistics")
    return norm


def plan_run(args: Args) -> RunPlan:
    """Check the invocation against ``--out`` and decide what it does (nothing is written).

    Raises:
        ConfigError: mixing two runs, resuming nothing, contradicting a resumed run's configuration, a
            finished budget, or any bad hyper-parameter.
    """
    from electroloc_gym.train.policy import resolve_model_path
    from electroloc_gym.train.resume import zip_timesteps

    rd = RunDir(args.out)
    resume_zip: Path | None = None
    if args.resume == "":
        if not rd.holds_run():
            raise ConfigError(f"--resume: --out {str(rd.path)!r} holds no run to continue (give the model folder "
                              f"to start from: --resume MODEL_DIR)")
        resume_zip = latest_state(rd.path)
    elif args.resume is not None:
        try:
            resume_zip = resolve_model_path(args.resume)
        except ValueError as exc:
            raise ConfigError(f"--resume: {exc}") from exc
    continues_out = resume_zip is not None and _inside(resume_zip, rd.path)
    if args.force and continues_out:
        raise ConfigError(f"--force would delete the model being resumed ({resume_zip} is inside --out)")
    if resume_zip is not None and not continues_out and rd.holds_run() and not args.force:
        raise ConfigError(f"--out {str(rd.path)!r} already holds another run; resuming {args.resume} into it would "
                          f"mix two runs — choose a new --out (or --force to delete that run)")
    rd.check_can_start(resume=continues_out, force=args.force)
    if resume_zip is None:
        return RunPlan(run_dir=rd, config=resolve_config(args))

    folder = resume_zip.parent
    saved = _saved_config(folder)
    bad = _conflicts(args, saved, continues_out)
    if bad:
        raise ConfigError("--resume continues the run with its own configuration (" + str(folder / "config.yml") +
                          "); these options contradict it: " + "; ".join(bad) +
                          ". Drop them, or start a new run in a new --out")
    done = zip_timesteps(resume_zip)
    cfg = dict(saved)
    if args.timesteps is not None:
        cfg["n_timesteps"] = done + args.timesteps
    elif int(saved["n_timesteps"]) <= done:
        raise ConfigError(f"--resume: the run already has {done} of its {saved['n_timesteps']} timesteps; pass "
                          f"--timesteps N to train N more")
    if "seed" in args.explicit:
        cfg["seed"] = args.seed
    cfg["evaluation"] = {**_evaluation(args), **((saved.get("evaluation") or {}) if continues_out else {})}
    best, best_t = best_so_far(rd.path) if continues_out else (math.inf, None)
    return RunPlan(run_dir=rd, config=cfg, resume_zip=resume_zip, continues_out=continues_out, timesteps_done=done,
                   normalization=_saved_normalization(folder, cfg), best_mean_steps=best, best_timesteps=best_t)
