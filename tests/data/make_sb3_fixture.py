"""make_sb3_fixture: SB3's actions of each shipped policy on fixed observations, for tests/test_shipped_policies.py.

The shipped policies (``electroloc_gym/models/NAME/``: ``policy.json`` + ``policy.safetensors``) were exported
from SB3 models (``model.zip``). The zips are pickles (loading one runs code) and about 0.7 MB each, so the
repository does not keep them: ``tests/data/sb3_actions.npz`` keeps what the format test needs instead, per
model, fixed observations and the actions SB3's ``predict(obs, deterministic=True)`` gave for them. The test
checks that the numpy policy gives the same actions (to ``ATOL``), without SB3, torch or a pickle.

This script wrote that file once, from the zips of commit ``bdde56c496de973d9858e109e5b5734945cdae1c``
(the last commit that held ``electroloc_gym/models/*/model.zip``). To make it again, take the zips from git history::

    git worktree add /tmp/with-zips bdde56c496de973d9858e109e5b5734945cdae1c
    python tests/data/make_sb3_fixture.py --models /tmp/with-zips/electroloc_gym/models
    git worktree remove /tmp/with-zips

For a newly shipped model, put its (trusted) SB3 zip at ``DIR/NAME/model.zip`` and run
``python tests/data/make_sb3_fixture.py --models DIR --update``: the model's entry is added, the others kept.
NAME must be a shipped policy: the script checks that the exported numpy policy acts as the zip before it
writes anything. The zip itself is not committed.

The observations: for each model, draws of ``uniform{-127..127} / 128`` (exact in float32 and float64, so
stored as int8: a few kB a model) at the width of the network's input (a frame-stacked model's stacked
input), from ``numpy.random.default_rng(SEED)``. For a Box action space, ``N_INSIDE`` of them give an action
SB3 leaves unclipped (every component inside the bounds by ``MARGIN``: the whole network shows in the
action) and ``N_CLIPPED`` give one that it clips (the clip shows); other action spaces take the first
``N_INSIDE + N_CLIPPED`` draws.

It unpickles the zips (``PPO.load``): only for the project's own files.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
OUT = Path(__file__).resolve().parent / "sb3_actions.npz"
ZIPS_COMMIT = "bdde56c496de973d9858e109e5b5734945cdae1c"
SEED = 0
OBS_SCALE = 128  # an observation is int8 / OBS_SCALE
N_INSIDE = 24
N_CLIPPED = 8
MARGIN = 0.02  # "inside": every component of SB3's Gaussian mean at least this far within the bounds
MAX_DRAWS = 65536
ATOL = 1e-5  # the test's tolerance on a continuous action (the numpy policy computes in float64, SB3 in float32)


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _select(model: Any, rng: np.random.Generator) -> np.ndarray:
    """int8 observations (N_INSIDE unclipped, then N_CLIPPED clipped for a Box action space)."""
    import torch
    from gymnasium import spaces

    dim = int(np.prod(model.observation_space.shape))
    n = N_INSIDE + N_CLIPPED
    if not isinstance(model.action_space, spaces.Box):
        return rng.integers(-127, 128, (n, dim), dtype=np.int8)
    low, high = model.action_space.low, model.action_space.high
    inside: list[np.ndarray] = []
    clipped: list[np.ndarray] = []
    drawn = 0
    while len(inside) < N_INSIDE or len(clipped) < N_CLIPPED:
        if drawn >= MAX_DRAWS:
            raise SystemExit(f"{MAX_DRAWS} draws gave {len(inside)} unclipped and {len(clipped)} clipped actions")
        q = rng.integers(-127, 128, (256, dim), dtype=np.int8)
        drawn += len(q)
        with torch.no_grad():
            x = torch.as_tensor(q.astype(np.float32) / OBS_SCALE).reshape((len(q), *model.observation_space.shape))
            mean = model.policy.get_distribution(x).distribution.mean.numpy().reshape(len(q), -1)
        is_inside = ((mean > low.ravel() + MARGIN) & (mean < high.ravel() - MARGIN)).all(axis=1)
        is_clipped = ((mean < low.ravel()) | (mean > high.ravel())).any(axis=1)
        inside += list(q[is_inside])
        clipped += list(q[is_clipped])
    return np.stack(inside[:N_INSIDE] + clipped[:N_CLIPPED])


def _entry(name: str, zip_path: Path) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    from stable_baselines3 import PPO

    from electroloc_gym.models import shipped_models
    from electroloc_gym.policy import load_policy

    folder = shipped_models().get(name)
    if folder is None or not (folder / "policy.json").is_file():
        raise SystemExit(f"{zip_path}: {name!r} is not a shipped policy (electroloc_gym/models/{name}/policy.json)")
    model = PPO.load(zip_path, device="cpu")  # the project's own files: trusted
    q = _select(model, np.random.default_rng(SEED))
    obs = (q.astype(np.float32) / OBS_SCALE).reshape((len(q), *model.observation_space.shape))
    actions = np.asarray(model.predict(obs, deterministic=True)[0])
    got, _ = load_policy(folder).actor(obs)
    if np.issubdtype(actions.dtype, np.integer):
        ok = np.array_equal(got, actions)
    else:
        ok = np.allclose(got, actions, rtol=0, atol=ATOL)
    if not ok:
        raise SystemExit(f"{name}: the shipped numpy policy does not act as {zip_path}: export it again first")
    arrays = {f"{name}.obs_q": q, f"{name}.actions": actions}
    info = {
        "zip_sha256": _sha256(zip_path),
        "weights_sha256": _sha256(folder / "policy.safetensors"),
        "n_obs": len(q),
        "max_abs_diff": float(np.max(np.abs(np.asarray(got, dtype=np.float64) - actions))),
    }
    return arrays, info


def _git_head(folder: Path) -> str | None:
    r = subprocess.run(["git", "rev-parse", "HEAD"], cwd=folder, capture_output=True, text=True, check=False)
    return r.stdout.strip() if r.returncode == 0 else None


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--models", type=Path, required=True, help="a folder of NAME/model.zip (SB3 zips, trusted)")
    p.add_argument("--update", action="store_true", help="keep the other models' entries of the existing file")
    p.add_argument("--out", type=Path, default=OUT)
    a = p.parse_args(argv)
    zips = sorted(a.models.glob("*/model.zip"))
    if not zips:
        print(f"error: --models: no NAME/model.zip under {a.models}", file=sys.stderr)
        return 2
    import stable_baselines3
    import torch

    arrays: dict[str, np.ndarray] = {}
    meta: dict[str, Any] = {"models": {}}
    if a.update and a.out.is_file():
        with np.load(a.out, allow_pickle=False) as old:
            arrays = {k: old[k] for k in old.files if k != "meta"}
            meta = json.loads(str(old["meta"]))
    for zip_path in zips:
        name = zip_path.parent.name
        arrays = {k: v for k, v in arrays.items() if not k.startswith(f"{name}.")}
        new, info = _entry(name, zip_path)
        arrays.update(new)
        info["source_commit"] = _git_head(zip_path.parent)
        meta["models"][name] = info
        print(f"{name}: {info['n_obs']} observations, max |numpy - SB3| = {info['max_abs_diff']:.3g}")
    meta.update(
        made_by="tests/data/make_sb3_fixture.py",
        obs_scale=OBS_SCALE,
        atol=ATOL,
        versions={
            "stable_baselines3": stable_baselines3.__version__,
            "torch": torch.__version__,
            "numpy": np.__version__,
        },
    )
    meta["models"] = dict(sorted(meta["models"].items()))
    np.savez_compressed(a.out, meta=np.array(json.dumps(meta, indent=1)), **dict(sorted(arrays.items())))
    print(f"wrote {a.out} ({a.out.stat().st_size} bytes)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
