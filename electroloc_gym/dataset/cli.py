"""``electroloc dataset``: one agent's episodes on one env as a local Minari dataset (:mod:`.collect`)."""

from __future__ import annotations

import argparse
import sys

__all__ = ["DESCRIPTION", "add_arguments", "run"]

DESCRIPTION = (
    "Run any agent the benchmark takes (the paper's controllers, lookahead, infotaxis, eedi, shipped "
    "policies, a policy folder, package.module:factory[...]) on a registered env and write its episodes "
    "as a local Minari dataset electroloc/<env-id>/<agent>-vN under MINARI_DATASETS_PATH (no hub). "
    "Episodes use training seeds, disjoint from the benchmark's evaluation seeds; the infos hold the "
    "belief summary and the truth. Resumable (--resume); an existing id is refused unless --force."
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``electroloc dataset``."""
    from electroloc_gym.registry import ENV_IDS

    parser.add_argument("--env", default="ElectroLoc-v0", choices=list(ENV_IDS), help="the registered env id")
    parser.add_argument("--agent", required=True, help="an agent spec as electroloc bench --agents takes one")
    parser.add_argument("--episodes", type=int, required=True, help="episodes to collect (≥ 1)")
    parser.add_argument(
        "--seed",
        type=int,
        default=None,
        help="root seed of the episodes (≥ 1; default 1; 0 is the benchmark's evaluation seed)",
    )
    parser.add_argument("--condition", default="random", help="'random' (a preset per episode) or a preset name")
    parser.add_argument(
        "--reference",
        default=None,
        metavar="BENCH",
        help="a benchmark folder (or trials.jsonl) with rnd-wlk and a planner on the env: "
        "ref_min_score / ref_max_score "
        "(e.g. experiments/learned/results/<env-id>/_baselines/bench)",
    )
    parser.add_argument(
        "--id", default=None, dest="dataset_id", help="the dataset id (default electroloc/<env-id>/<agent>-v<version>)"
    )
    parser.add_argument("--version", type=int, default=0, help="the id's version N (≥ 0)")
    parser.add_argument("--resume", action="store_true", help="continue an unfinished dataset of the same settings")
    parser.add_argument("--force", action="store_true", help="replace an existing dataset of the same id")
    parser.add_argument(
        "--trust-pickle",
        action="store_true",
        help="let an SB3 .zip policy load (unpickling runs code: only files you trust)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    """Build the dataset ``args`` describe; print its id, size and path. 0 on success, 2 on bad input."""
    from electroloc_gym.dataset.collect import DatasetRequest, build_dataset
    from electroloc_gym.dataset.protocol import DEFAULT_DATASET_SEED

    try:
        if args.resume and args.force:
            raise ValueError("--resume and --force exclude each other")
        request = DatasetRequest(
            env_id=args.env,
            agent=args.agent,
            episodes=args.episodes,
            seed=DEFAULT_DATASET_SEED if args.seed is None else args.seed,
            reference=args.reference,
            version=args.version,
            dataset_id=args.dataset_id,
            condition=args.condition,
            trust_pickle=args.trust_pickle,
        )
        ds = build_dataset(request, resume=args.resume, force=args.force, progress=not args.no_progress)
    except ValueError as exc:
        print(f"electroloc dataset: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(
            "electroloc dataset: interrupted; the episodes written so far are kept (--resume continues)",
            file=sys.stderr,
        )
        return 130
    meta = ds.storage.metadata
    print(
        f"{meta['dataset_id']}: {ds.total_episodes} episodes, {ds.total_steps} steps, "
        f"{meta.get('dataset_size', 0)} MB at {ds.storage.data_path.parent}"
    )
    return 0
