"""The reference datasets: every agent of :data:`DATASETS` on its env, one command, resumable, with a manifest.

Run (from the repository root; ``MINARI_DATASETS_PATH`` picks the folder, Minari's default otherwise)::

    python experiments/offline/make_datasets.py                  # the reference datasets
    python experiments/offline/make_datasets.py --scale 0.01     # the same plan, 1 % of the episodes

Each dataset is ``electroloc dataset --env ENV --agent AGENT --episodes N --reference
experiments/learned/results/<env-id>/_baselines/bench`` (:func:`electroloc_gym.dataset.build_dataset`); a finished
one is
kept, an unfinished one resumes. ``manifest.json`` (``--manifest``) lists per dataset its id, episodes, steps,
wall time of the run that finished it, size, and the sha256 of every file (relative to the dataset's folder).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path

from electroloc_gym.baselines.agent import RANDOM_AGENT
from electroloc_gym.baselines.infotaxis import InfotaxisAgent
from electroloc_gym.baselines.lookahead import LookaheadAgent
from electroloc_gym.baselines.min_variance import MinVarianceAgent
from electroloc_gym.registry import PAPER_ENV_ID, task_entry

ROOT = Path(__file__).resolve().parents[2]
LEARNED = ROOT / "experiments" / "learned" / "results"
#: (env id, agent, episodes) of the reference datasets.
DATASETS = (
    (PAPER_ENV_ID, RANDOM_AGENT, 1000),
    (PAPER_ENV_ID, MinVarianceAgent.name, 300),
    (PAPER_ENV_ID, LookaheadAgent.name, 500),
    (PAPER_ENV_ID, InfotaxisAgent.name, 500),
    (PAPER_ENV_ID, "ppo-belief", 500),
    (task_entry("global").env_id, MinVarianceAgent.name, 200),
    (task_entry("global").env_id, LookaheadAgent.name, 200),
)


def file_digests(folder: Path) -> dict[str, str]:
    """sha256 of every file under ``folder``, by path relative to it (sorted)."""
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def main(argv: list[str] | None = None) -> int:
    """Build (or resume) every dataset of the plan and update the manifest."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    from electroloc_gym.bench.bench_command import ascii_int

    parser.add_argument("--scale", type=float, default=1.0, help="fraction of each dataset's episodes (0, 1]")
    parser.add_argument("--only", default="", help="comma-separated env-id/agent to build; default all")
    parser.add_argument("--manifest", type=Path, default=ROOT / "experiments" / "offline" / "manifest.json")
    parser.add_argument("--version", type=ascii_int, default=0, help="the ids' version (0 … 10**6)")
    args = parser.parse_args(argv)
    if not 0 < args.scale <= 1:
        parser.error(f"--scale must be in (0, 1], got {args.scale}")
    if not 0 <= args.version <= 10**6:
        parser.error(f"--version must be an integer in [0, 1000000], got {args.version}")
    plan = [f"{env_id}/{agent}" for env_id, agent, _ in DATASETS]
    bad = [x for x in (s.strip() for s in args.only.split(",")) if x and x not in plan]
    if bad:
        parser.error(f"--only names {bad}; choose from {plan}")
    manifest_path = args.manifest.expanduser()
    if manifest_path.is_dir() or any(p.exists() and not p.is_dir() for p in manifest_path.absolute().parents):
        parser.error(f"--manifest {str(args.manifest)!r} must be a file in a folder (it is a folder or under a file)")
    from minari.storage.datasets_root_dir import get_dataset_path

    from electroloc_gym.dataset import DatasetRequest, build_dataset
    from electroloc_gym.utils.fileio import write_json_atomic

    only = {s.strip() for s in args.only.split(",") if s.strip()}
    manifest = json.loads(args.manifest.read_text(encoding="utf-8")) if args.manifest.is_file() else {}
    for env_id, agent, episodes in DATASETS:
        if only and f"{env_id}/{agent}" not in only:
            continue
        n = max(1, round(episodes * args.scale))
        request = DatasetRequest(
            env_id, agent, n, version=args.version, reference=LEARNED / env_id / "_baselines" / "bench"
        )
        t0 = time.perf_counter()
        try:
            ds = build_dataset(request, resume=True, progress=True)
        except ValueError as exc:
            if "exists (a complete one" not in str(exc):
                raise
            import minari

            ds = minari.load_dataset(request.id)
            if ds.total_episodes != n:
                raise ValueError(
                    f"{request.id} holds {ds.total_episodes} episodes, not {n}: pass another --version or remove it"
                ) from None
        wall = time.perf_counter() - t0
        folder = Path(get_dataset_path(request.id))
        digests = file_digests(folder)
        size = sum((folder / p).stat().st_size for p in digests)
        old = manifest.get(request.id, {})
        manifest[request.id] = {
            "env_id": env_id,
            "agent": agent,
            "episodes": ds.total_episodes,
            "steps": ds.total_steps,
            "bytes": size,
            "files": len(digests),
            "wall_s": round(wall, 1) if wall > 5 or "wall_s" not in old else old["wall_s"],
            "s_per_episode": round(wall / n, 4) if wall > 5 or "wall_s" not in old else old.get("s_per_episode"),
            "ref_min_score": ds.storage.metadata.get("ref_min_score"),
            "ref_max_score": ds.storage.metadata.get("ref_max_score"),
            "sha256": digests,
        }
        write_json_atomic(args.manifest, manifest)
        print(
            f"{request.id}: {ds.total_episodes} episodes, {ds.total_steps} steps, {size / 2**20:.2f} MiB, {wall:.0f} s",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
