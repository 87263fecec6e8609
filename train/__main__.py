r"""Train an SB3 agent on an electroloc-gym env (also ``electroloc train``).

    python -m electroloc_gym.train --algo ppo --env ElectroLoc-v0 \
        --env-kwargs condition=random observation=belief randomize_target=true \
        --timesteps 1000000 --n-envs 8 --seed 1000 \
        --hyperparams train/hyperparams/ppo.yml --out runs/ppo-belief

On top of plain SB3 (or rl-zoo3) the trainer adds: the native batched vector env (``--vec-env
native``), potential-based shaping on the belief spread, evaluation on fixed seeded episodes with
the benchmark's own metrics (``eval.csv``, ``best/``), the pickle-free policy export the benchmark
loads, strict hyper-parameter checks before any training, and run folders that never mix two runs.

The run folder gets ``policy.json`` + ``policy.safetensors`` (the final policy, pickle-free),
``model.zip`` (SB3's file, pickle-based), ``config.yml`` (the resolved hyper-parameters and env
kwargs), ``args.json`` (every segment's arguments, start, timesteps and wall time), ``command.txt``
(every segment's exact command), ``eval.csv``, ``best/`` (the model with the best evaluation),
``checkpoints/step_N/``, ``summary.json`` and ``tb/`` (TensorBoard, when installed).

An existing run is refused unless ``--resume`` (continue it: from its latest state, or from the
model folder given) or ``--force`` (delete it first). A resumed run keeps its own hyper-parameters;
``--timesteps`` then counts additional steps (default: the rest of the run's budget).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import yaml

from electroloc_gym.fileio import atomic_write_text
from electroloc_gym.train.config import HYPERPARAMS_DIR, ConfigError, algo_class, algo_kwargs
from electroloc_gym.train.runplan import plan_run, resolve_config

__all__ = ["Args", "parse_args", "main", "train", "resolve_config"]

VEC_ENVS = ("dummy", "subproc", "native")
DEVICES = ("auto", "cpu", "cuda")
_DEFAULTS = {"algo": "ppo", "env": "ElectroLoc-v0", "seed": 1000}


@dataclass
class Args:
    """Command-line arguments of ``python -m electroloc_gym.train`` (see ``--help``).

    ``explicit`` names the options given on the command line (a resumed run refuses options that
    contradict its saved configuration); ``resume`` is None, ``""`` (continue ``out`` from its latest
    state) or a model folder / zip.
    """

    algo: str = "ppo"
    env: str = "ElectroLoc-v0"
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    timesteps: int | None = None
    n_envs: int | None = None
    seed: int = 1000
    hyperparams: str | None = None
    out: str | None = None
    resume: str | None = None
    force: bool = False
    vec_env: str = "dummy"
    device: str = "auto"
    eval_freq: int = 20_000
    eval_episodes: int = 64
    eval_seed: int = 100_000
    eval_env_kwargs: dict[str, Any] = field(default_factory=dict)
    checkpoint_freq: int = 100_000
    progress: bool = False
    tensorboard: bool = True
    verbose: int = 1
    explicit: list[str] = field(default_factory=list)


def _parse_kwargs(items: Sequence[str] | None, flag: str) -> dict[str, Any]:
    """``["a=1", "b=random"]`` → ``{"a": 1, "b": "random"}`` (values read as YAML scalars)."""
    out: dict[str, Any] = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise ConfigError(f"{flag} expects key=value pairs, got {item!r}")
        try:
            out[key] = yaml.safe_load(value) if value else ""
        except yaml.YAMLError as exc:
            raise ConfigError(f"{flag}: cannot read the value of {item!r}: {exc}") from exc
    return out


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (defaults come from :class:`Args`); plain-text help with every default."""
    from electroloc_gym.cli import HelpFormatter

    d = Args()
    p = argparse.ArgumentParser(prog="python -m electroloc_gym.train", description=_plain(__doc__),
                                formatter_class=HelpFormatter)
    p.add_argument("--algo", default=None, help="ppo | sac | a2c | td3 | ddpg | dqn | recurrentppo | tqc | qrdqn "
                                                f"(default: {_DEFAULTS['algo']})")
    p.add_argument("--env", default=None, help=f"Gymnasium env id (default: {_DEFAULTS['env']})")
    p.add_argument("--env-kwargs", nargs="*", default=None, metavar="KEY=VALUE",
                   help="env kwargs, e.g. condition=random observation=belief n_particles=500 "
                        "(given ones override the YAML's env_kwargs; default: the YAML's)")
    p.add_argument("--timesteps", type=int, default=None,
                   help="env steps to train (default: n_timesteps in the YAML; when resuming: additional steps, "
                        "default the rest of the run's budget)")
    p.add_argument("--n-envs", type=int, default=None, help="parallel envs (default: n_envs in the YAML, else 1)")
    p.add_argument("--seed", type=int, default=None,
                   help=f"training seed; env i is seeded seed+i (default: {_DEFAULTS['seed']})")
    p.add_argument("--hyperparams", default=None, help="YAML file (default: train/hyperparams/<algo>.yml)")
    p.add_argument("--out", default=None, help="run directory (default: runs/<algo>-<env>-s<seed>)")
    p.add_argument("--resume", nargs="?", const="", default=None, metavar="MODEL_DIR",
                   help="continue the run in --out from its latest state, or from MODEL_DIR (e.g. a checkpoint)")
    p.add_argument("--force", action="store_true", help="delete the run in --out first and start over")
    p.add_argument("--vec-env", default=d.vec_env, choices=VEC_ENVS,
                   help="vector env: one process (dummy), a process per env (subproc), or the batched core (native)")
    p.add_argument("--device", default=d.device, choices=DEVICES, help="torch device")
    p.add_argument("--eval-freq", type=int, default=d.eval_freq, help="env steps between evaluations")
    p.add_argument("--eval-episodes", type=int, default=None,
                   help=f"seeded episodes per evaluation (default: {d.eval_episodes})")
    p.add_argument("--eval-seed", type=int, default=None,
                   help=f"evaluation episode i uses reset seed S+i (default: {d.eval_seed})")
    p.add_argument("--eval-env-kwargs", nargs="*", default=None, metavar="KEY=VALUE",
                   help="overrides of the training env kwargs for evaluation (e.g. randomize_target=false; "
                        "default: none)")
    p.add_argument("--checkpoint-freq", type=int, default=d.checkpoint_freq, help="env steps between checkpoints")
    p.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                   help="progress bar (default: on when stderr is a terminal)")
    p.add_argument("--tensorboard", action=argparse.BooleanOptionalAction, default=d.tensorboard,
                   help="TensorBoard logs in <out>/tb when tensorboard is installed (default: on)")
    p.add_argument("--verbose", type=int, default=d.verbose,
                   help="0: quiet; 1: a line per evaluation and SB3's training log")
    return p


def _plain(doc: str | None) -> str:
    """A reST docstring as plain help text: without the double backticks of inline literals."""
    return (doc or "").replace("``", "").strip()


def parse_args(argv: Sequence[str] | None = None) -> Args:
    """Parse the command line into :class:`Args` (raises ConfigError for malformed or out-of-range values)."""
    ns = build_parser().parse_args(argv)
    explicit = [k for k in ("algo", "env", "env_kwargs", "n_envs", "seed", "hyperparams", "eval_episodes",
                            "eval_seed", "eval_env_kwargs") if getattr(ns, k) is not None]
    d = Args()
    args = Args(
        algo=(ns.algo or _DEFAULTS["algo"]).lower(), env=ns.env or _DEFAULTS["env"],
        env_kwargs=_parse_kwargs(ns.env_kwargs, "--env-kwargs"), timesteps=ns.timesteps, n_envs=ns.n_envs,
        seed=_DEFAULTS["seed"] if ns.seed is None else ns.seed, hyperparams=ns.hyperparams, out=ns.out,
        resume=ns.resume, force=ns.force, vec_env=ns.vec_env, device=ns.device, eval_freq=ns.eval_freq,
        eval_episodes=d.eval_episodes if ns.eval_episodes is None else ns.eval_episodes,
        eval_seed=d.eval_seed if ns.eval_seed is None else ns.eval_seed,
        eval_env_kwargs=_parse_kwargs(ns.eval_env_kwargs, "--eval-env-kwargs"),
        checkpoint_freq=ns.checkpoint_freq,
        progress=sys.stderr.isatty() if ns.progress is None else ns.progress,
        tensorboard=ns.tensorboard, verbose=ns.verbose, explicit=explicit,
    )
    for name in ("timesteps", "n_envs", "eval_freq", "eval_episodes", "checkpoint_freq"):
        v = getattr(args, name)
        if v is not None and v < 1:
            raise ConfigError(f"--{name.replace('_', '-')} must be ≥ 1, got {v}")
    if args.seed < 0:
        raise ConfigError(f"--seed must be ≥ 0, got {args.seed}")
    if args.force and args.resume is not None:
        if args.resume == "":
            raise ConfigError("--force deletes the run in --out, --resume continues it: give one of them")
    if args.hyperparams is None:
        args.hyperparams = str(HYPERPARAMS_DIR / f"{args.algo}.yml")
    if args.out is None:
        args.out = f"runs/{args.algo}-{args.env}-s{args.seed}"
    return args


def check_config(args: Args, cfg: dict[str, Any]) -> None:
    """Checks that need the whole config: the env and its kwargs, n_steps × n_envs, the vector env."""
    from electroloc_gym.train.validation import check_env

    check_env(cfg["env_id"], cfg["env_kwargs"], "--env-kwargs / env_kwargs")
    if cfg["evaluation"]["env_kwargs"]:
        check_env(cfg["env_id"], {**cfg["env_kwargs"], **cfg["evaluation"]["env_kwargs"]}, "--eval-env-kwargs")
    n_steps = cfg["hyperparams"].get("n_steps")
    if cfg["algo"] in ("ppo", "a2c", "recurrentppo") and n_steps is not None and n_steps * cfg["n_envs"] < 2:
        raise ConfigError(f"n_steps × n_envs must be ≥ 2 (a rollout of one step cannot be learned from), "
                          f"got {n_steps} × {cfg['n_envs']}")
    if args.vec_env == "native":
        import gymnasium as gym

        if gym.spec(cfg["env_id"]).vector_entry_point is None:
            raise ConfigError(f"--vec-env native: {cfg['env_id']} has no native vector env; use dummy or subproc")


def make_env_fn(env_id: str, env_kwargs: dict[str, Any], frame_stack: int, shaping_coef: float,
                gamma: float) -> Callable[[], Any]:
    """A picklable thunk building one env: gym.make → Monitor → shaping → frame stack."""

    def thunk() -> Any:
        import gymnasium as gym
        from stable_baselines3.common.monitor import Monitor

        import electroloc_gym  # noqa: F401  (registers the ids)
        from electroloc_gym.train.wrappers import FlatFrameStack, PotentialShaping

        env = Monitor(gym.make(env_id, **env_kwargs))  # Monitor logs the unshaped return
        if shaping_coef > 0:
            env = PotentialShaping(env, shaping_coef, gamma)
        if frame_stack > 1:
            env = FlatFrameStack(env, frame_stack)
        return env

    return thunk


def make_vec_env(args: Args, cfg: dict[str, Any], normalization: dict[str, Any] | None = None) -> Any:
    """The training vector env (dummy / subproc / native), seeded, normalised if configured.

    ``normalization`` (a ``policy.json`` section) restores a resumed run's statistics.
    """
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize

    n = cfg["n_envs"]
    seed = cfg["seed"]
    gamma = float(cfg["hyperparams"].get("gamma", 0.99))
    if args.vec_env == "native":
        from electroloc_gym.train.native_vec import make_native_vec_env

        venv = make_native_vec_env(cfg["env_id"], n, seed, cfg["env_kwargs"], shaping_coef=cfg["shaping_coef"],
                                   gamma=gamma, frame_stack=cfg["frame_stack"])
    else:
        fns = [make_env_fn(cfg["env_id"], cfg["env_kwargs"], cfg["frame_stack"], cfg["shaping_coef"], gamma)
               for _ in range(n)]
        venv = SubprocVecEnv(fns) if args.vec_env == "subproc" and n > 1 else DummyVecEnv(fns)
        venv.seed(seed)  # env i: reset seed seed+i at the first reset, then its own generator
    if normalization is not None:
        from electroloc_gym.train.resume import vec_normalize_from_export

        return vec_normalize_from_export(venv, normalization, training=True)
    if cfg["normalize"] is not None:
        venv = VecNormalize(venv, **{"gamma": gamma, "norm_reward": False, **cfg["normalize"]})
    return venv


def build_model(args: Args, cfg: dict[str, Any], venv: Any, tb_dir: str | None, resume_zip: Path | None) -> Any:
    """A new algorithm instance, or the run in ``resume_zip`` continued (loaded without unpickling)."""
    cls = algo_class(cfg["algo"])
    kw = algo_kwargs(cfg["hyperparams"])
    if resume_zip is not None:
        from electroloc_gym.train.resume import load_for_resume

        model = load_for_resume(resume_zip, cls, venv, kw, device=args.device, tensorboard_log=tb_dir,
                                verbose=args.verbose)
        model.set_random_seed(cfg["seed"])
        return model
    policy = kw.pop("policy", "MlpPolicy")
    try:
        return cls(policy, venv, seed=cfg["seed"], device=args.device, tensorboard_log=tb_dir, verbose=args.verbose,
                   **kw)
    except (TypeError, ValueError, AssertionError) as exc:
        raise ConfigError(f"{cls.__name__} rejects the hyper-parameters: {exc}") from exc


def _setup_torch(device: str) -> str:
    import torch
    from stable_baselines3.common.utils import get_device

    dev = get_device(device)
    if dev.type == "cpu":
        torch.set_num_threads(1)  # one thread per process is fastest for these small networks
    return str(dev)


def train(args: Args, argv: Sequence[str] = ()) -> Path:
    """Run training as ``args`` says; returns the run directory."""
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")  # inherited by subprocess envs
    plan = plan_run(args)  # every check before anything is written
    check_config(args, plan.config)
    rd = plan.run_dir
    rd.lock()
    try:
        return _train_locked(args, argv, plan)
    finally:
        rd.unlock()


def _train_locked(args: Args, argv: Sequence[str], plan: Any) -> Path:
    """The run itself, with the folder's lock held."""
    from electroloc_gym.train.callbacks import ModelDirCheckpoint, SeededEvalCallback, save_model_dir
    from electroloc_gym.train.rundir import git_commit, strict_json, versions

    cfg, rd, out = plan.config, plan.run_dir, plan.run_dir.path
    if args.force:
        rd.wipe()
    set_aside = rd.set_aside_after(plan.timesteps_done) if plan.continues_out else None
    device = _setup_torch(args.device)
    cfg["device"] = device
    tb_dir = None
    if args.tensorboard:
        try:
            import tensorboard  # noqa: F401

            tb_dir = str(out / "tb")
        except ImportError:
            pass
    venv = make_vec_env(args, cfg, plan.normalization)
    try:
        model = build_model(args, cfg, venv, tb_dir, plan.resume_zip)
    except BaseException:
        venv.close()
        raise
    atomic_write_text(out / "config.yml", yaml.safe_dump(cfg, sort_keys=False))
    rd.start_segment(argv, asdict(args), timesteps_start=plan.timesteps_done,
                     resumed_from=None if plan.resume_zip is None else str(plan.resume_zip),
                     set_aside=None if set_aside is None else str(set_aside))
    provenance = {"commands": rd.commands(), "seed": cfg["seed"], "run": str(out), **git_commit(),
                  "versions": versions()}
    t0 = time.time() - rd.previous_wall_time_s()  # eval.csv's wall_time_s counts the whole run
    ev = cfg["evaluation"]
    eval_kwargs = {**cfg["env_kwargs"], **ev["env_kwargs"]}
    seeds = [ev["seed"] + i for i in range(ev["episodes"])]
    eval_cb = SeededEvalCallback(cfg["env_id"], eval_kwargs, seeds, args.eval_freq, out / "eval.csv", out / "best",
                                 cfg, frame_stack=cfg["frame_stack"], t0=t0, verbose=args.verbose,
                                 best_mean_steps=plan.best_mean_steps, provenance=provenance,
                                 on_evaluate=rd.update_segment)
    ckpt_cb = ModelDirCheckpoint(args.checkpoint_freq, out / "checkpoints", cfg, verbose=args.verbose,
                                 provenance=provenance, on_save=rd.update_segment)
    status = "interrupted"
    try:
        model.learn(total_timesteps=cfg["n_timesteps"] - plan.timesteps_done, callback=[eval_cb, ckpt_cb],
                    progress_bar=args.progress, reset_num_timesteps=plan.resume_zip is None, tb_log_name="run")
        status = "finished"
    finally:
        save_model_dir(model, out, cfg, provenance=provenance)
        rd.update_segment(int(model.num_timesteps), status)
        wall = rd.total_wall_time_s()
        trained = sum(int(s.get("timesteps_end", 0)) - int(s.get("timesteps_start", 0)) for s in rd.segments)
        best = eval_cb.best_mean_steps
        summary = {"status": status, "wall_time_s": wall, "timesteps": int(model.num_timesteps),
                   "segments": len(rd.segments), "device": device,
                   "steps_per_s": round(trained / max(wall, 1e-9), 1),
                   "best_mean_steps": best, "best_timesteps": eval_cb.best_timesteps or plan.best_timesteps,
                   "last_eval": eval_cb.history[-1] if eval_cb.history else None}
        atomic_write_text(out / "summary.json", strict_json(summary))
        venv.close()
    if args.verbose:
        print(f"done: {model.num_timesteps} steps, {wall:.0f} s in {len(rd.segments)} segment(s) → {out}", flush=True)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point: ``python -m electroloc_gym.train ...`` and ``electroloc train ...``. Returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        args = parse_args(argv)
        train(args, argv)
    except (ConfigError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
