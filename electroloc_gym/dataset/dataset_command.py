"""``electroloc dataset``: one agent's episodes on one env as a local Minari dataset (:mod:`.collect`).

Bad input is one line (``electroloc dataset: error: …``, exit 2) before anything is written: the integer
options take ASCII digits only (the benchmark's own parser), an agent whose ``predict`` raises is named
with its episode as ``electroloc bench`` names it with its trial, and a file-system failure names the file.
A dataset without reference scores is said to be one.
"""

from __future__ import annotations

import argparse
import sys

__all__ = ["DESCRIPTION", "add_arguments", "run"]

PROG = "electroloc dataset"

DESCRIPTION = (
    "Run any agent the benchmark takes (the paper's controllers, lookahead, infotaxis, eedi, shipped "
    "policies, a policy folder, package.module:factory[...]) on a registered env and write its episodes "
    "as a local Minari dataset electroloc/<env-id>/<agent>-vN under MINARI_DATASETS_PATH (no hub). "
    "Episodes use training seeds, disjoint from the benchmark's evaluation seeds; the infos hold the "
    "belief summary and the truth. Resumable after any interruption (--resume checks every episode it keeps "
    "against its recorded checksums and re-collects a damaged one); an existing id is refused unless --force, "
    "which replaces exactly that dataset once its replacement is complete."
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``electroloc dataset``."""
    from electroloc_gym.bench.bench_command import ascii_int
    from electroloc_gym.registry import ENV_IDS, PAPER_ENV_ID

    parser.add_argument(
        "--env",
        default=PAPER_ENV_ID,
        help=f"a registered env id ({', '.join(ENV_IDS)}), or package.module:ENV_ID, an env your own module "
        "registers (a task of your own, electroloc_gym.tasks): imported like any module, it runs your code "
        "(default: %(default)s)",
    )
    parser.add_argument("--agent", required=True, help="an agent spec as electroloc bench --agents takes one")
    parser.add_argument("--episodes", type=ascii_int, required=True, help="episodes to collect (≥ 1)")
    parser.add_argument(
        "--seed",
        type=ascii_int,
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
        "(e.g. experiments/learned/results/<env-id>/_baselines/bench); without it the dataset has no "
        "reference scores (the command says so)",
    )
    parser.add_argument(
        "--id",
        default=None,
        dest="dataset_id",
        help="the dataset id, NAMESPACE/NAME-vN, at most 200 characters "
        "(default electroloc/<env-id>/<agent>-v<version>)",
    )
    parser.add_argument(
        "--version", type=ascii_int, default=None, help="the default id's version N (≥ 0; default 0; not with --id)"
    )
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue an unfinished dataset of the same settings, or check a complete one (every kept episode "
        "checked; a damaged one set aside in the dataset's quarantine/ folder and collected again)",
    )
    parser.add_argument(
        "--force",
        action="store_true",
        help="replace the existing dataset of this id, once the new one is complete (a failed or killed run "
        "leaves the old one as it was)",
    )
    parser.add_argument(
        "--trust-pickle",
        action="store_true",
        help="let an SB3 .zip policy load (unpickling runs code: only files you trust)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    """Build the dataset ``args`` describe; print its id, size and path. 0 on success, 2 on bad input."""
    from electroloc_gym.dataset.collect import DatasetRequest, build_dataset
    from electroloc_gym.dataset.seed_protocol import DEFAULT_DATASET_SEED
    from electroloc_gym.registry import resolve_env_name

    def notify(message: str) -> None:
        print(f"{PROG}: {message}", file=sys.stderr)

    try:
        if args.resume and args.force:
            raise ValueError("--resume and --force exclude each other")
        if args.dataset_id is not None and args.version is not None:
            raise ValueError("--version sets the default id's version; an --id carries its own -vN")
        request = DatasetRequest(
            env_id=resolve_env_name(args.env, "--env"),  # MODULE:ENV_ID imports MODULE
            agent=args.agent,
            episodes=args.episodes,
            seed=DEFAULT_DATASET_SEED if args.seed is None else args.seed,
            reference=args.reference,
            version=0 if args.version is None else args.version,
            dataset_id=args.dataset_id,
            condition=args.condition,
            trust_pickle=args.trust_pickle,
        )
        ds = build_dataset(request, resume=args.resume, force=args.force, progress=not args.no_progress, notify=notify)
    except ValueError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(
            f"{PROG}: interrupted; nothing is lost: an unfinished dataset keeps its episodes (--resume "
            "continues it) and a --force run leaves the dataset it was replacing as it was",
            file=sys.stderr,
        )
        return 130
    meta = ds.storage.metadata
    print(
        f"{meta['dataset_id']}: {ds.total_episodes} episodes, {ds.total_steps} steps, "
        f"{meta.get('dataset_size', 0)} MB at {ds.storage.data_path.parent}"
    )
    if meta.get("ref_min_score") is None or meta.get("ref_max_score") is None:
        notify(
            "note: no reference scores (ref_min_score, ref_max_score; minari.get_normalized_score needs them): "
            "pass --reference with a benchmark of rnd-wlk and a planner on the env, e.g. "
            f"experiments/learned/results/{request.env_id}/_baselines/bench"
        )
    return 0
