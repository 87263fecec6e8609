"""``electroloc dataset``: one agent's episodes on one env as a local Minari dataset (:mod:`.collect`).

Its options are :data:`~electroloc_gym.dataset.request.DATASET_OPTIONS`. Bad input is one line
(``electroloc dataset: error: …``, exit 2) before anything is written; an agent whose ``predict`` raises is
named with its episode as ``electroloc bench`` names it with its trial. A dataset without reference scores is
said to be one.
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
    "against the checksum it carries and re-collects a damaged one); an existing id is refused unless --force, "
    "which replaces exactly that dataset once its replacement is complete."
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``electroloc dataset``."""
    from electroloc_gym.dataset.request import DATASET_OPTIONS
    from electroloc_gym.options import add_options

    add_options(parser, DATASET_OPTIONS)


def run(args: argparse.Namespace) -> int:
    """Build the dataset ``args`` describe; print its id, size and path. 0 on success, 2 on bad input."""
    from electroloc_gym.dataset.collect import build_dataset
    from electroloc_gym.dataset.request import DATASET_OPTIONS, REQUEST_OPTIONS, DatasetRequest, check_settings
    from electroloc_gym.options import message_names
    from electroloc_gym.registry import resolve_env_name

    def notify(message: str) -> None:
        print(f"{PROG}: {message}", file=sys.stderr)

    values = {o.name: getattr(args, o.name) for o in DATASET_OPTIONS}
    try:
        values["env_id"] = resolve_env_name(values["env_id"], "--env")  # MODULE:ENV_ID imports MODULE
        check_settings(values, lambda o: o.option)  # named by their flags, before the request names them
        request = DatasetRequest(**{o.name: values[o.name] for o in REQUEST_OPTIONS})
        ds = build_dataset(
            request,
            resume=args.resume,
            force=args.force,
            progress=args.progress,
            notify=notify,
            names=message_names(DATASET_OPTIONS, lambda o: o.option),
        )
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
