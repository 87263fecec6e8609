"""The learned suite's records as rliable score matrices, and every statistic the report states.

Reads the benchmark runs of a learned-baseline results folder (:mod:`learned_report` lays it out) through
the bench's own record schema, arranges them into rliable's (runs × conditions) matrices of readings and
successes, normalises the readings between rnd-wlk and the best planner, and computes the aggregates,
their 95 % stratified bootstrap intervals and the probabilities of improvement (:func:`analyse`). rliable
computes every aggregate and interval; this module only arranges the records and makes the bootstrap
reproducible from a seed (:func:`bootstrap` says why that needs doing). :mod:`learned_report` turns the
result into tables and figures; the offline report (``experiments/offline/report.py``) reuses it.

A **tracking env** — one whose task has no success criterion (``Task.metrics.success_criterion`` false:
ElectroLocTrack-v0, :func:`tracks`) — runs every trial to its reading cap, so readings and successes say
nothing there. Its scores, one per (run, condition), are the task's declared score and rate
(``Task.metrics.score``, ``.rate``; the moving target's **tracking error**, the mean over the condition's
trials of the belief mean's mean distance to the swimming target over the episode's second half, mm, lower
better, and its **capture** fraction); the normalised score, the probabilities of improvement and the
learned pairs (:data:`TRACK_COMPARISONS`) are computed on that score exactly as on the readings elsewhere
(:func:`analyse`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from electroloc_gym.baselines.agent import RANDOM_AGENT
from electroloc_gym.baselines.lookahead import LookaheadAgent
from electroloc_gym.baselines.min_variance import MinVarianceAgent

if TYPE_CHECKING:
    from electroloc_gym.bench.config import BenchConfig

BASELINES_DIR = "_baselines"


class NoLearnedRuns(ValueError):
    """An env of the results folder has no learned run with a finished benchmark yet."""


RND = RANDOM_AGENT
#: The non-learned agents the probability of improvement is stated against (when they were benched): on the moving
#: target also min-var with the velocity belief, the belief the off-policy rows train with.
REFERENCES = (MinVarianceAgent.name, LookaheadAgent.name, f"{MinVarianceAgent.name}[motion_model=swimmer]")
#: Pairs of learned configurations (suite labels) whose P(A better than B) the report states when both
#: ran on an env: memory against stacked frames on the raw reading, and the belief given against memory.
COMPARISONS = (("ppo_lstm-raw", "ppo-framestack-raw"), ("ppo", "ppo_lstm-raw"))
#: The pairs stated by default on a tracking env: the belief given against stacked raw readings, and the off-policy
#: learners (on the velocity belief) against PPO and each other.
TRACK_COMPARISONS = (("ppo", "ppo-framestack-raw"), ("sac", "ppo"), ("crossq", "ppo"), ("crossq", "sac"))


class ReportError(ValueError):
    """A results folder the report cannot read (a missing, empty or unreadable file): one line."""


#: The most bootstrap replications accepted (each keeps a runs × conditions matrix per replication).
MAX_REPS = 100_000


def env_metrics(env_id: str) -> Any:
    """The metrics ``env_id``'s task declares (``Task.metrics``); an id the table does not know: the paper's
    localisation metrics (its benchmark config is refused when read).
    """
    from electroloc_gym.engines.numba_core.task import LOCALIZATION_METRICS
    from electroloc_gym.registry import env_entry

    try:
        return env_entry(env_id).task_class.metrics
    except ValueError:
        return LOCALIZATION_METRICS


def tracks(env_id: str) -> bool:
    """Whether ``env_id`` is a tracking env: its task has no success criterion (module docstring)."""
    return not env_metrics(env_id).success_criterion


def _config(bench: Path) -> BenchConfig:
    """The run ``bench/config.json`` holds, decoded by msgspec into the package's one declaration of a run
    (:func:`~electroloc_gym.bench.stored_run.load_config`: a
    :class:`~electroloc_gym.bench.config.BenchConfig`, its field types and its settings' checks).

    Raises:
        ReportError: the file is unreadable, not JSON or not a run's config — one line naming it.
    """
    from electroloc_gym.bench.records import CONFIG_FILE
    from electroloc_gym.bench.stored_run import load_config

    try:
        return load_config(bench / CONFIG_FILE)
    except ValueError as exc:  # names the file and the field
        raise ReportError(str(exc)) from None


def read_trials(path: Path, set_aside: list[str] | None = None) -> list[dict[str, Any]]:
    """The valid trial records of one benchmark run's ``trials.jsonl`` (or its kept ``trials.jsonl.gz``),
    read through the bench's own record schema (:func:`electroloc_gym.bench.records.load_records` with the
    run's :class:`~electroloc_gym.bench.schema.RecordRules` from its ``config.json``, read by :func:`_config`:
    its conditions, agents, trial range, success criterion and task): a damaged or impossible line — out of
    range, inconsistent, another run's agent or condition, a duplicate, or (an env whose records carry their
    task's results) a ``shape`` with other keys than the env's ``record_keys`` — is left out and named in
    ``set_aside``.

    Raises:
        ReportError: the file is missing or holds no valid record, or the run's config.json is not one (one line).
    """
    from electroloc_gym.bench.records import load_records, stored_trials
    from electroloc_gym.bench.schema import RecordRules
    from electroloc_gym.registry import env_entry

    if not stored_trials(path).is_file():
        raise ReportError(f"{path} is missing")
    config = _config(path.parent)
    rules = RecordRules(
        conditions=frozenset(config.conditions),
        agents=frozenset(config.agents),
        trials=config.trials,
        success_spread_mm=config.success_spread_mm,
        metrics=env_entry(config.env_id).task_class.metrics,
    )
    loaded = load_records(path, rules=rules)
    if set_aside is not None:
        set_aside.extend(loaded.messages())
    rows = list(loaded.records.values())  # the schema sets aside another task's results (the rules' metrics)
    if not rows:
        raise ReportError(f"{path} holds no valid trial record")
    return rows


def condition_scores(
    records: Sequence[dict[str, Any]], conditions: Sequence[str], metrics: Any = None
) -> dict[str, np.ndarray]:
    """``{"readings", "success"}`` → (conditions,) scores of one run of one agent; a tracking env's ``metrics``
    (its task's, :func:`tracks`) add its score and rate under their names (the moving target's
    ``"tracking_error"``, mean ``tracking_error_mm`` in mm, and ``"capture"``, the fraction captured).
    """
    readings, success, error, capture = [], [], [], []
    for cond in conditions:
        rows = [r for r in records if r["condition"] == cond]
        if not rows:
            raise ValueError(f"no trials of condition {cond!r}")
        cap = [int(r["max_observations"]) for r in rows]
        readings.append(float(np.mean([r["readings"] if r["success"] else c for r, c in zip(rows, cap)])))
        success.append(float(np.mean([bool(r["success"]) for r in rows])))
        if metrics is not None:
            error.append(float(np.mean([metrics.score.of_record(r) for r in rows])))
            capture.append(float(np.mean([metrics.rate.of_record(r) for r in rows])))
    out = {"readings": np.array(readings), "success": np.array(success)}
    if metrics is not None:
        out.update({metrics.score.name: np.array(error), metrics.rate.name: np.array(capture)})
    return out


def collect(
    results: Path, env_id: str, set_aside: list[str] | None = None, extra: Sequence[Path] = ()
) -> tuple[list[str], dict[str, dict[str, np.ndarray]], dict[str, dict[str, np.ndarray]], dict[str, list[str]]]:
    """(conditions, learned, baselines, seeds) of one env; what was left out is appended to ``set_aside``.

    ``learned[algo][metric]`` is a (seeds × conditions) matrix; ``baselines[agent][metric]`` is (1 ×
    conditions); ``seeds[algo]`` names the runs in row order (``seed-<integer>`` folders only). ``extra``
    folders (laid out as ``EXTRA/<env-id>/<label>/seed-<k>/bench/``, e.g. the offline suite's results) add
    their labels beside the suite's, scored against the same baselines' run; a label in two folders is an
    error, and their runs must cover the baselines' conditions. A tracking env's matrices add
    ``"tracking_error"`` and ``"capture"`` (:func:`condition_scores`).
    """
    set_aside = [] if set_aside is None else set_aside
    own = env_metrics(env_id) if tracks(env_id) else None  # a tracking env's own score and rate
    env_dir = results / env_id
    base_path = env_dir / BASELINES_DIR / "bench" / "trials.jsonl"
    base_rows = read_trials(base_path, set_aside)
    conditions = sorted({r["condition"] for r in base_rows})
    base_keys = {(r["condition"], int(r["trial"])) for r in base_rows}
    baselines: dict[str, dict[str, np.ndarray]] = {}
    for agent in sorted({r["agent"] for r in base_rows}):
        s = condition_scores([r for r in base_rows if r["agent"] == agent], conditions, own)
        baselines[agent] = {k: v[None, :] for k, v in s.items()}
    learned: dict[str, dict[str, np.ndarray]] = {}
    seeds: dict[str, list[str]] = {}
    algo_dirs = sorted(p for p in env_dir.iterdir() if p.is_dir() and p.name != BASELINES_DIR)
    for folder in extra:
        more = sorted(p for p in (folder / env_id).iterdir() if p.is_dir()) if (folder / env_id).is_dir() else []
        clash = sorted({p.name for p in more} & {p.name for p in algo_dirs if any(p.glob("seed-*"))})
        if clash:
            raise ReportError(f"{folder}: labels {clash} are already in {results} (each label once)")
        algo_dirs += more
    for algo_dir in algo_dirs:
        runs = sorted(p for p in algo_dir.glob("seed-*") if (p / "bench" / "summary.json").is_file())
        odd = [p for p in runs if not p.name[len("seed-") :].isdecimal() or not p.name.isascii()]
        set_aside.extend(f"{p}: not a seed-<integer> folder" for p in odd)
        runs = [p for p in runs if p not in odd]
        if not runs:
            continue
        records = [read_trials(p / "bench" / "trials.jsonl", set_aside) for p in runs]
        if not algo_dir.is_relative_to(env_dir):  # an extra folder's run: on the baselines' very trials
            for p, rows in zip(runs, records):
                if {(r["condition"], int(r["trial"])) for r in rows} != base_keys:
                    raise ReportError(f"{p}: its benchmark ran other trials than {base_path} (run it on the same)")
        per_run = [condition_scores(rows, conditions, own) for rows in records]
        learned[algo_dir.name] = {k: np.stack([s[k] for s in per_run]) for k in per_run[0]}
        seeds[algo_dir.name] = [p.name for p in runs]
    return conditions, learned, baselines, seeds


def normalised(
    readings: np.ndarray, baselines: dict[str, dict[str, np.ndarray]], metric: str = "readings"
) -> np.ndarray:
    """The normalised score of a (runs × conditions) matrix of ``metric`` (lower better: the readings, or
    a tracking env's ``"tracking_error"``): 0 at rnd-wlk, 1 at the best planner on each condition.
    """
    if RND not in baselines:
        raise ValueError(f"the baselines' run must include {RND!r} to normalise")
    planners = [v[metric][0] for k, v in baselines.items() if k != RND]
    if not planners:
        raise ValueError("the baselines' run must include a planner besides rnd-wlk to normalise")
    rnd = baselines[RND][metric][0]
    best = np.min(np.stack(planners), axis=0)
    gap = rnd - best
    if np.any(gap <= 0):
        raise ValueError("rnd-wlk is not worse than the best planner on some condition; the score is undefined")
    return (rnd - readings) / gap


def bootstrap(score_dict: dict[str, Any], func: Any, reps: int, seed: int) -> tuple[dict, dict]:
    """Point estimates and 95 % stratified bootstrap CIs (rliable), reproducible from ``seed``.

    rliable 1.2's bootstraps draw their resampling indices from NumPy's global stream
    (``np.random.choice`` in ``update_indices``), so its ``random_state`` argument does not make a run
    repeatable. Each entry is therefore resampled after seeding the global stream with ``seed`` (its
    previous state restored afterwards): the same records give the same intervals, and an algorithm's
    interval depends on its own runs only, not on which other algorithms are in the table.
    """
    from rliable import library as rly

    point, ci = {}, {}
    saved = np.random.get_state()
    try:
        for k, scores in score_dict.items():
            np.random.seed(seed)
            p, c = rly.get_interval_estimates({k: scores}, func, reps=reps)
            point[k], ci[k] = p[k], c[k]
    finally:
        np.random.set_state(saved)
    return point, ci


def interval(score_dict: dict[str, Any], func: Any, reps: int, seed: int) -> dict[str, list[float]]:
    """``{name: [point, lower, upper]}`` of ``func`` with a 95 % stratified bootstrap CI (rliable)."""
    point, ci = bootstrap(score_dict, func, reps, seed)
    return {k: [float(np.ravel(point[k])[0]), float(np.ravel(ci[k])[0]), float(np.ravel(ci[k])[1])] for k in score_dict}


def p_better(x: np.ndarray, y: np.ndarray, reps: int, seed: int) -> list[float]:
    """P(a run of X needs fewer readings than a run of Y on a condition) [95 % CI]: rliable's probability
    of improvement of (−X) over (−Y), the readings matrices (runs × conditions) negated, lower being better
    (a tracking env's tracking-error matrices the same way).
    """
    from rliable import metrics

    func = lambda a, b: np.array([metrics.probability_of_improvement(a, b)])  # noqa: E731
    return interval({"p": (-x, -y)}, func, reps, seed)["p"]


def analyse(
    results: Path,
    env_id: str,
    reps: int = 2000,
    seed: int = 0,
    comparisons: Sequence[tuple[str, str]] | None = None,
    extra: Sequence[Path] = (),
) -> dict[str, Any]:
    """Every statistic of one env (plain data, see the module docstring); ``comparisons`` are the
    (A, B) pairs of learned labels whose P(A better than B) is stated, where both ran on the env (None:
    :data:`COMPARISONS`, on a tracking env :data:`TRACK_COMPARISONS`); ``extra``: more results folders
    whose labels join the table (:func:`collect`). A tracking env is scored by its tracking error and
    capture (:func:`statistics`), and its analysis has ``"metric"``: its score's key (``"tracking_error_mm"``).
    """
    set_aside: list[str] = []
    conditions, learned, baselines, seeds = collect(results, env_id, set_aside, extra)
    if not learned:
        raise NoLearnedRuns(f"no learned runs with a benchmark under {results / env_id}")
    tracking = tracks(env_id)
    if comparisons is None:
        comparisons = TRACK_COMPARISONS if tracking else COMPARISONS
    metrics = env_metrics(env_id)
    score, share = metrics.score.name, metrics.rate.name  # readings and success unless the task declares its own
    out: dict[str, Any] = {
        "env_id": env_id,
        **({"metric": metrics.score.key} if tracking else {}),
        "conditions": conditions,
        "seeds": seeds,
        "reps": reps,
        "seed": seed,
        "algorithms": {},
        "baselines": {},
    }
    out.update(statistics(conditions, learned, baselines, reps, seed, comparisons, score, share))
    out["set_aside"] = set_aside
    return out


def statistics(
    conditions: list[str],
    learned: dict[str, dict[str, np.ndarray]],
    baselines: dict[str, dict[str, np.ndarray]],
    reps: int,
    seed: int,
    comparisons: Sequence[tuple[str, str]],
    score: str,
    share: str,
) -> dict[str, Any]:
    """The statistics of one env's matrices (:func:`collect`): ``score`` is the lower-better score
    (``"readings"``, or a tracking env's ``"tracking_error"``), ``share`` the fraction beside it (``"success"``,
    ``"capture"``). Per learned label, the IQM and mean of both with their 95 % stratified bootstrap CIs, the
    normalised score's IQM (0 at rnd-wlk, 1 at the best non-learned agent of each condition), each
    condition's values and the probabilities of a lower score than each of :data:`REFERENCES` benched; per
    baseline agent, the means and each condition's values; the probability of a lower score between the
    labels of each ``comparisons`` pair run on the env. Keys are named after ``score`` and ``share``
    (``readings_iqm``, ``per_condition_capture``, ...).
    """
    from rliable import metrics

    iqm = lambda x: np.array([metrics.aggregate_iqm(x)])  # noqa: E731
    mean = lambda x: np.array([metrics.aggregate_mean(x)])  # noqa: E731
    values = {a: v[score] for a, v in learned.items()}
    shares = {a: v[share] for a, v in learned.items()}
    norm = {a: normalised(v, baselines, score) for a, v in values.items()} if RND in baselines else {}
    stats = {
        f"{score}_iqm": interval(values, iqm, reps, seed),
        f"{score}_mean": interval(values, mean, reps, seed),
        f"{share}_iqm": interval(shares, iqm, reps, seed),
        f"{share}_mean": interval(shares, mean, reps, seed),
    }
    if norm:
        stats["normalised_iqm"] = interval(norm, iqm, reps, seed)
    algorithms: dict[str, Any] = {}
    for algo in learned:
        row = {k: v[algo] for k, v in stats.items()}
        row[f"per_condition_{score}"] = {c: values[algo][:, j].tolist() for j, c in enumerate(conditions)}
        row[f"per_condition_{share}"] = {c: shares[algo][:, j].tolist() for j, c in enumerate(conditions)}
        row["p_improvement"] = {
            ref: p_better(values[algo], baselines[ref][score], reps, seed) for ref in REFERENCES if ref in baselines
        }
        algorithms[algo] = row
    rows: dict[str, Any] = {}
    for agent, v in baselines.items():
        row = {
            f"{score}_mean": float(v[score].mean()),
            f"{share}_mean": float(v[share].mean()),
            f"per_condition_{score}": dict(zip(conditions, v[score][0].tolist())),
            f"per_condition_{share}": dict(zip(conditions, v[share][0].tolist())),
        }
        if norm:
            row["normalised_mean"] = float(normalised(v[score], baselines, score).mean())
        rows[agent] = row
    return {
        "algorithms": algorithms,
        "baselines": rows,
        "comparisons": [
            {"better": a, "than": b, "p": p_better(values[a], values[b], reps, seed)}
            for a, b in comparisons
            if a in values and b in values
        ],
        "_matrices": {"normalised": norm, score: values, share: shares},
    }
