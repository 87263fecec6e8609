r"""Train an SB3 agent on an electroloc-gym env (also ``electroloc train``).

    python -m train --algo ppo --env ElectroLoc-v0 \
        --env-kwargs condition=random observation=belief randomize_target=true \
        --timesteps 1000000 --n-envs 8 --seed 1000 \
        --hyperparams train/hyperparams/ppo.yml --out runs/ppo-belief

The run directory gets ``model.zip`` (final), ``vecnormalize.pkl`` (if normalised), ``config.yml``
(the resolved hyper-parameters and env kwargs), ``args.json``, ``command.txt`` (the exact command,
seed and, at the end, the wall time), ``eval.csv`` (one row per evaluation), ``best/`` (the model
with the best evaluation), ``checkpoints/step_N/`` (resumable with ``--resume``) and ``tb/``
(TensorBoard, when installed). ``--timesteps`` counts *additional* steps when resuming.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import yaml

from electroloc_gym.train.config import HYPERPARAMS_DIR, ConfigError, algo_class, algo_kwargs, resolve_hyperparams

__all__ = ["Args", "parse_args", "main", "train"]

VEC_ENVS = ("dummy", "subproc", "native")
DEVICES = ("auto", "cpu", "cuda")


@dataclass
class Args:
    """Command-line arguments of ``python -m train`` (see ``--help``)."""

    algo: str = "ppo"
    env: str = "ElectroLoc-v0"
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    timesteps: int | None = None
    n_envs: int | None = None
    seed: int = 1000
    hyperparams: str | None = None
    out: str | None = None
    resume: str | None = None
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


def _parse_kwargs(items: Sequence[str] | None, flag: str) -> dict[str, Any]:
    """``["a=1", "b=random"]`` → ``{"a": 1, "b": "random"}`` (values read as YAML scalars)."""
    out: dict[str, Any] = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise ConfigError(f"{flag} expects key=value pairs, got {item!r}")
        out[key] = yaml.safe_load(value) if value else ""
    return out


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (defaults come from :class:`Args`)."""
    d = Args()
    p = argparse.ArgumentParser(prog="python -m train", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--algo", default=d.algo, help="ppo | sac | a2c | td3 | ddpg | dqn | recurrentppo | tqc | qrdqn")
    p.add_argument("--env", default=d.env, help="Gymnasium env id (default %(default)s)")
    p.add_argument("--env-kwargs", nargs="*", default=[], metavar="KEY=VALUE",
                   help="env kwargs, e.g. condition=random observation=belief n_particles=500")
    p.add_argument("--timesteps", type=int, default=None, help="env steps to train (default: n_timesteps in the YAML)")
    p.add_argument("--n-envs", type=int, default=None, help="parallel envs (default: n_envs in the YAML, else 1)")
    p.add_argument("--seed", type=int, default=d.seed, help="training seed; env i is seeded seed+i")
    p.add_argument("--hyperparams", default=None, help="YAML file (default train/hyperparams/<algo>.yml)")
    p.add_argument("--out", default=None, help="run directory (default runs/<algo>-<env>-s<seed>)")
    p.add_argument("--resume", default=None, help="continue from a model directory or zip (e.g. a checkpoint)")
    p.add_argument("--vec-env", default=d.vec_env, choices=VEC_ENVS)
    p.add_argument("--device", default=d.device, choices=DEVICES)
    p.add_argument("--eval-freq", type=int, default=d.eval_freq, help="env steps between evaluations")
    p.add_argument("--eval-episodes", type=int, default=d.eval_episodes, help="seeded episodes per evaluation")
    p.add_argument("--eval-seed", type=int, default=d.eval_seed, help="evaluation episode i uses reset seed S+i")
    p.add_argument("--eval-env-kwargs", nargs="*", default=[], metavar="KEY=VALUE",
                   help="overrides of the training env kwargs for evaluation (e.g. randomize_target=false)")
    p.add_argument("--checkpoint-freq", type=int, default=d.checkpoint_freq, help="env steps between checkpoints")
    p.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                   help="progress bar (default: on when stderr is a terminal)")
    p.add_argument("--tensorboard", action=argparse.BooleanOptionalAction, default=d.tensorboard,
                   help="TensorBoard logs in <out>/tb when tensorboard is installed")
    p.add_argument("--verbose", type=int, default=d.verbose)
    return p


def parse_args(argv: Sequence[str] | None = None) -> Args:
    """Parse the command line into :class:`Args` (raises ConfigError for malformed key=value pairs)."""
    ns = build_parser().parse_args(argv)
    args = Args(
        algo=ns.algo.lower(), env=ns.env, env_kwargs=_parse_kwargs(ns.env_kwargs, "--env-kwargs"),
        timesteps=ns.timesteps, n_envs=ns.n_envs, seed=ns.seed, hyperparams=ns.hyperparams, out=ns.out,
        resume=ns.resume, vec_env=ns.vec_env, device=ns.device, eval_freq=ns.eval_freq,
        eval_episodes=ns.eval_episodes, eval_seed=ns.eval_seed,
        eval_env_kwargs=_parse_kwargs(ns.eval_env_kwargs, "--eval-env-kwargs"),
        checkpoint_freq=ns.checkpoint_freq,
        progress=sys.stderr.isatty() if ns.progress is None else ns.progress,
        tensorboard=ns.tensorboard, verbose=ns.verbose,
    )
    for name in ("timesteps", "n_envs", "eval_freq", "eval_episodes", "checkpoint_freq"):
        v = getattr(args, name)
        if v is not None and v < 1:
            raise ConfigError(f"--{name.replace('_', '-')} must be ≥ 1, got {v}")
    if args.seed < 0:
        raise ConfigError(f"--seed must be ≥ 0, got {args.seed}")
    if args.hyperparams is None:
        args.hyperparams = str(HYPERPARAMS_DIR / f"{args.algo}.yml")
    if args.out is None:
        args.out = f"runs/{args.algo}-{args.env}-s{args.seed}"
    return args


def resolve_config(args: Args) -> dict[str, Any]:
    """The run's resolved config: YAML section + command line (the command line wins)."""
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
    }


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


def make_vec_env(args: Args, cfg: dict[str, Any]) -> Any:
    """The training vector env (dummy / subproc / native), seeded, normalised if configured."""
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize

    n = cfg["n_envs"]
    gamma = float(cfg["hyperparams"].get("gamma", 0.99))
    if args.vec_env == "native":
        try:
            from electroloc_gym.train.native_vec import make_native_vec_env
        except ImportError as exc:
            raise ConfigError(f"--vec-env native needs train/native_vec.py (make_native_vec_env), "
                              f"which is not available: {exc}") from exc
        venv = make_native_vec_env(cfg["env_id"], n, args.seed, cfg["env_kwargs"], shaping_coef=cfg["shaping_coef"],
                                   gamma=gamma)
        if cfg["frame_stack"] > 1:
            from stable_baselines3.common.vec_env import VecFrameStack

            # For 1-D observations VecFrameStack concatenates oldest → newest, zero-padded after a
            # reset: the same vector as FlatFrameStack, which the loaded agent reproduces.
            venv = VecFrameStack(venv, cfg["frame_stack"])
    else:
        fns = [make_env_fn(cfg["env_id"], cfg["env_kwargs"], cfg["frame_stack"], cfg["shaping_coef"], gamma)
               for _ in range(n)]
        venv = SubprocVecEnv(fns) if args.vec_env == "subproc" and n > 1 else DummyVecEnv(fns)
        venv.seed(args.seed)  # env i: reset seed seed+i at the first reset, then its own generator
    if cfg["normalize"] is not None and not args.resume:
        venv = VecNormalize(venv, **{"gamma": gamma, "norm_reward": False, **cfg["normalize"]})
    return venv


def build_model(args: Args, cfg: dict[str, Any], venv: Any, tb_dir: str | None) -> Any:
    """A new algorithm instance, or the one in ``--resume`` with its normalisation statistics."""
    cls = algo_class(args.algo)
    if args.resume:
        from stable_baselines3.common.vec_env import VecNormalize

        from electroloc_gym.train.policy import resolve_model_path

        zip_path = resolve_model_path(args.resume)
        vn_path = zip_path.parent / "vecnormalize.pkl"
        if cfg["normalize"] is not None:
            if not vn_path.is_file():
                raise ConfigError(f"--resume {args.resume}: the config normalises observations but "
                                  f"{vn_path} is missing")
            venv = VecNormalize.load(str(vn_path), venv)
            venv.training = True
        model = cls.load(zip_path, env=venv, device=args.device, tensorboard_log=tb_dir)
        return model
    kw = algo_kwargs(cfg["hyperparams"])
    policy = kw.pop("policy", "MlpPolicy")
    return cls(policy, venv, seed=args.seed, device=args.device, tensorboard_log=tb_dir, verbose=args.verbose, **kw)


def _command_text(argv: Sequence[str], extra: dict[str, Any] | None = None) -> str:
    lines = [f"cd {shlex.quote(os.getcwd())}", "python -m train " + shlex.join(list(argv))]
    for k, v in (extra or {}).items():
        lines.append(f"# {k}: {v}")
    return "\n".join(lines) + "\n"


def _setup_torch(device: str) -> str:
    import torch
    from stable_baselines3.common.utils import get_device

    dev = get_device(device)
    if dev.type == "cpu":
        torch.set_num_threads(1)  # DESIGN §10: one thread per process is fastest on this 2-core box
    return str(dev)


def train(args: Args, argv: Sequence[str] = ()) -> Path:
    """Run training as ``args`` says; returns the run directory."""
    from electroloc_gym.train.callbacks import ModelDirCheckpoint, SeededEvalCallback, atomic_write_text, save_model_dir

    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")  # inherited by subprocess envs
    cfg = resolve_config(args)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    device = _setup_torch(args.device)
    cfg["device"] = device
    t0 = time.time()
    atomic_write_text(out / "args.json", json.dumps(asdict(args), indent=2) + "\n")
    atomic_write_text(out / "config.yml", yaml.safe_dump(cfg, sort_keys=False))
    atomic_write_text(out / "command.txt", _command_text(argv, {"seed": args.seed}))

    tb_dir = None
    if args.tensorboard:
        try:
            import tensorboard  # noqa: F401

            tb_dir = str(out / "tb")
        except ImportError:
            pass
    venv = make_vec_env(args, cfg)
    model = build_model(args, cfg, venv, tb_dir)
    eval_kwargs = {**cfg["env_kwargs"], **args.eval_env_kwargs}
    seeds = [args.eval_seed + i for i in range(args.eval_episodes)]
    eval_cb = SeededEvalCallback(cfg["env_id"], eval_kwargs, seeds, args.eval_freq, out / "eval.csv", out / "best",
                                 cfg, frame_stack=cfg["frame_stack"], t0=t0, verbose=args.verbose)
    ckpt_cb = ModelDirCheckpoint(args.checkpoint_freq, out / "checkpoints", cfg, verbose=args.verbose)
    try:
        model.learn(total_timesteps=cfg["n_timesteps"], callback=[eval_cb, ckpt_cb], progress_bar=args.progress,
                    reset_num_timesteps=not args.resume, tb_log_name="run")
    finally:
        wall = time.time() - t0
        save_model_dir(model, out, cfg)
        summary = {"wall_time_s": round(wall, 1), "timesteps": int(model.num_timesteps), "device": device,
                   "steps_per_s": round(model.num_timesteps / max(wall, 1e-9), 1),
                   "best_mean_steps": eval_cb.best_mean_steps,
                   "last_eval": eval_cb.history[-1] if eval_cb.history else None}
        atomic_write_text(out / "summary.json", json.dumps(summary, indent=2) + "\n")
        atomic_write_text(out / "command.txt", _command_text(argv, {
            "seed": args.seed, "training wall time (s)": summary["wall_time_s"],
            "timesteps": summary["timesteps"], "device": device}))
        venv.close()
    if args.verbose:
        print(f"done: {model.num_timesteps} steps in {wall:.0f} s → {out}", flush=True)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point: ``python -m train ...`` and ``electroloc train ...``. Returns the exit status."""
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
