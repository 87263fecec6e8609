r"""Convert a trusted SB3 model to the pickle-free policy format, and check it acts the same.

    python -m electroloc_gym.train.export models/ppo-belief [--remove-pickle]
    python -m electroloc_gym.train.export logs/ppo/ElectroLoc-v0_1/ElectroLoc-v0.zip \
        --vecnormalize logs/ppo/ElectroLoc-v0_1/ElectroLoc-v0/vecnormalize.pkl --observation belief

``SRC`` is a model folder of this project (``model.zip``, ``config.yml``, ``vecnormalize.pkl``) or
any SB3 zip (e.g. one trained by rl-zoo3) with its layout given by options. Conversion *unpickles*
``SRC`` — run it only on files you trust (your own runs); afterwards nothing needs to be unpickled
again. The converted policy is loaded back through :func:`~electroloc_gym.train.policy.load_policy`
and must give bit-identical deterministic actions to SB3's ``model.predict`` on a batch of env
observations (normalised with the pickled statistics), else the export is refused.
"""

from __future__ import annotations

import argparse
import pickle
import shutil
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from electroloc_gym.fileio import atomic_write_text

__all__ = ["export_model_dir", "verify_export", "main"]


def _sample_observations(env_id: str, env_kwargs: dict[str, Any], n: int = 64, seed: int = 0) -> np.ndarray:
    """Raw env observations from seeded episodes under random actions (one frame each)."""
    import gymnasium as gym

    import electroloc_gym  # noqa: F401

    env = gym.make(env_id, **env_kwargs)
    env.action_space.seed(seed)
    out = []
    obs, _ = env.reset(seed=seed)
    while len(out) < n:
        out.append(np.asarray(obs, dtype=np.float32))
        obs, _, term, trunc, _ = env.step(env.action_space.sample())
        if term or trunc:
            obs, _ = env.reset(seed=seed + len(out))
    env.close()
    return np.stack(out)


def verify_export(model: Any, vn: Any, folder: Path, env_kwargs: dict[str, Any], frame_stack: int,
                  env_id: str = "ElectroLoc-v0", n: int = 64) -> dict[str, Any]:
    """Compare the exported policy with the SB3 model on ``n`` observations; raise if any action differs.

    The network input is built as training built it (frame stack, then VecNormalize's statistics);
    the comparison is exact (``np.array_equal``) for the torch policy and for the agent the
    benchmark runs.

    Returns:
        ``{"observations": n, "identical": True, "max_abs_diff_agent": float}``.
    """
    from electroloc_gym.train.policy import SB3Agent, load_policy

    agent = load_policy(folder)
    old = SB3Agent(model, obs_rms=None if vn is None or not vn.norm_obs else vn.obs_rms,
                   clip_obs=getattr(vn, "clip_obs", 10.0), epsilon=getattr(vn, "epsilon", 1e-8),
                   frame_stack=frame_stack, env_kwargs=agent.env_kwargs)
    frames = _sample_observations(env_id, {**env_kwargs, **agent.env_kwargs}, n * frame_stack)
    raw = frames.reshape(n, frame_stack * frames.shape[1]) if frame_stack > 1 else frames
    x = raw if vn is None or not vn.norm_obs else vn.normalize_obs(raw).astype(np.float32)
    a_sb3, _ = model.predict(x, deterministic=True)
    a_new, _ = agent.policy.predict(x, deterministic=True)
    if not np.array_equal(a_sb3, a_new):
        raise ValueError(f"{folder}: the exported policy's actions differ from SB3's (max |Δ| "
                         f"{np.abs(np.asarray(a_sb3, float) - np.asarray(a_new, float)).max():.3g})")
    old.reset(None)
    agent.reset(None)
    single = frames[:n]
    a_old, _ = old.predict(single)
    a_agent, _ = agent.predict(single)
    if not np.array_equal(a_old, a_agent):
        raise ValueError(f"{folder}: the loaded agent's actions differ from the pickle-loaded agent's")
    return {"observations": int(n), "identical": True,
            "max_abs_diff_agent_vs_sb3": float(np.abs(np.asarray(agent._numpy_actor(x), float)
                                                      - np.asarray(a_sb3, float)).max())
            if agent._numpy_actor is not None else 0.0}


def _read_command(folder: Path) -> list[str]:
    p = folder / "command.txt"
    if not p.is_file():
        return []
    return [ln.strip() for ln in p.read_text(encoding="utf-8").splitlines() if ln.startswith("python -m")]


def _zip_versions(zip_path: Path) -> dict[str, str]:
    """The versions SB3 wrote into the zip's plain-text ``system_info.txt`` ("- Python: 3.11.7 ...")."""
    import zipfile

    try:
        with zipfile.ZipFile(zip_path) as archive:
            text = archive.read("system_info.txt").decode("utf-8", "replace")
    except (KeyError, zipfile.BadZipFile, OSError):
        return {}
    out = {}
    for line in text.splitlines():
        key, sep, value = line.lstrip("- ").partition(":")
        if sep and key.strip() in ("Python", "Stable-Baselines3", "PyTorch", "Numpy", "Gymnasium"):
            out[key.strip()] = value.strip().split(" ")[0]
    return out


def export_model_dir(src: str | Path, *, out: str | Path | None = None, vecnormalize: str | Path | None = None,
                     overrides: dict[str, Any] | None = None, remove_pickle: bool = False,
                     verify: bool = True) -> Path:
    """Write ``policy.json`` + ``policy.safetensors`` for the trusted SB3 model ``src``.

    Args:
        src: a model folder (``model.zip`` + ``config.yml`` [+ ``vecnormalize.pkl``]) or an SB3 zip.
        out: the folder to write (default: the model's own folder). ``model.zip`` is copied there.
        vecnormalize: the VecNormalize pickle (default: ``vecnormalize.pkl`` beside the zip, if any).
        overrides: config entries for a bare zip: ``algo``, ``env_id``, ``frame_stack``, ``env_kwargs``.
        remove_pickle: delete the ``vecnormalize.pkl`` beside the export once it is verified.
        verify: compare actions with the SB3 model (refuse the export if any differs).

    Raises:
        ValueError: unreadable model, or the exported policy does not act as the SB3 model.
    """
    import torch

    from electroloc_gym.train.callbacks import _observation_info
    from electroloc_gym.train.config import algo_class
    from electroloc_gym.train.policy import _guess_algo, read_run_config, resolve_model_path
    from electroloc_gym.train.policy_format import export_policy, normalization_from_vecnormalize
    from electroloc_gym.train.rundir import git_commit, versions

    torch.set_num_threads(1)
    zip_path = resolve_model_path(src)
    folder = zip_path.parent
    cfg = dict(read_run_config(folder)) if zip_path.name == "model.zip" else {}
    for k, v in (overrides or {}).items():
        cfg[k] = {**cfg.get(k, {}), **v} if k == "env_kwargs" else v
    cfg.setdefault("env_id", "ElectroLoc-v0")
    algo = str(cfg.get("algo") or _guess_algo(zip_path))
    cfg["algo"] = algo
    model = algo_class(algo).load(zip_path, device="cpu")  # trusted: this unpickles
    vn_path = Path(vecnormalize) if vecnormalize else folder / "vecnormalize.pkl"
    vn = None
    if vn_path.is_file():
        with vn_path.open("rb") as fh:
            vn = pickle.load(fh)  # noqa: S301 - trusted conversion
    elif vecnormalize:
        raise ValueError(f"--vecnormalize: no such file {str(vn_path)!r}")
    dest = Path(out) if out else folder
    dest.mkdir(parents=True, exist_ok=True)
    if dest.resolve() != folder.resolve():
        shutil.copyfile(zip_path, dest / "model.zip")
    if not (dest / "config.yml").is_file() or dest.resolve() != folder.resolve():
        atomic_write_text(dest / "config.yml", yaml.safe_dump(cfg, sort_keys=False))
    evaluation = cfg.get("eval")
    provenance = {
        "commands": _read_command(folder), "seed": cfg.get("seed", getattr(model, "seed", None)),
        "timesteps": int(model.num_timesteps), "git_commit": None, "git_dirty": None,  # not recorded by SB3
        "versions": _zip_versions(zip_path),
        "converted": {"from": zip_path.name, "utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                      **git_commit(), "versions": versions()},
    }
    export_policy(model, dest, observation=_observation_info(model, cfg),
                  normalization=normalization_from_vecnormalize(vn), provenance=provenance, evaluation=evaluation)
    report = verify_export(model, vn, dest, dict(cfg.get("env_kwargs") or {}), int(cfg.get("frame_stack", 1)),
                           env_id=cfg["env_id"]) if verify else None
    if remove_pickle and (dest / "vecnormalize.pkl").is_file():
        (dest / "vecnormalize.pkl").unlink()
    if report is not None:
        print(f"{dest}: exported and verified — identical deterministic actions on {report['observations']} "
              f"observations (numpy fast path within {report['max_abs_diff_agent_vs_sb3']:.1e} of SB3)")
    return dest


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m electroloc_gym.train.export SRC [SRC ...]``; returns the exit status."""
    p = argparse.ArgumentParser(prog="python -m electroloc_gym.train.export", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("src", nargs="+", help="model folders or SB3 zips (trusted: they are unpickled)")
    p.add_argument("--out", default=None, help="output folder (one SRC only; default: the model's folder)")
    p.add_argument("--vecnormalize", default=None, help="VecNormalize pickle (default: vecnormalize.pkl beside)")
    p.add_argument("--algo", default=None, help="algorithm of a bare zip (default: from the zip)")
    p.add_argument("--env-id", default=None, help="env id of a bare zip (default ElectroLoc-v0)")
    p.add_argument("--observation", choices=("belief", "raw"), default=None, help="observation mode of a bare zip")
    p.add_argument("--action-type", choices=("continuous", "discrete"), default=None)
    p.add_argument("--frame-stack", type=int, default=None, help="frames stacked in training (bare zip)")
    p.add_argument("--remove-pickle", action="store_true", help="delete vecnormalize.pkl once verified")
    p.add_argument("--no-verify", action="store_true", help="skip the action comparison")
    ns = p.parse_args(argv)
    if ns.out and len(ns.src) > 1:
        print("error: --out takes one SRC", file=sys.stderr)
        return 2
    overrides: dict[str, Any] = {}
    if ns.algo:
        overrides["algo"] = ns.algo
    if ns.env_id:
        overrides["env_id"] = ns.env_id
    if ns.frame_stack:
        overrides["frame_stack"] = ns.frame_stack
    kw = {k: v for k, v in (("observation", ns.observation), ("action_type", ns.action_type)) if v}
    if kw:
        overrides["env_kwargs"] = kw
    try:
        for src in ns.src:
            export_model_dir(src, out=ns.out, vecnormalize=ns.vecnormalize, overrides=overrides,
                             remove_pickle=ns.remove_pickle, verify=not ns.no_verify)
    except (ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
