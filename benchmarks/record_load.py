"""Load time of a run's trial records: msgspec (the package's one schema) against pydantic and bare JSON.

Reads the 2 400-record reference run (``experiments/reference/bench``) and prints, best of ``--repeats``:

* the package's reader, :func:`electroloc_gym.bench.records.load_records`, on the stored file (msgspec
  decodes each line into :class:`~electroloc_gym.bench.schema.TrialRecord`, whose ``__post_init__`` checks
  the fields against each other; plus the reader's keying, duplicate and UTF-8 checks; the stored run
  writes two keys in their old names, which the reader renames);
* msgspec's typed decode alone (``msgspec.json.Decoder(TrialRecord)``, consistency checks included);
* pydantic (where installed): a ``BaseModel`` with the same fields, ranges and consistency check
  (``model_validator``), ``validate_json`` per line — the other library the project weighed;
* ``json.loads`` per line with no check at all (the floor);

each as ms and as a ratio to msgspec's decode, side by side. One thread.

    python benchmarks/record_load.py [--repeats 7]
"""

from __future__ import annotations

import argparse
import gzip
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, Literal

from electroloc_gym.utils.runtime import pin_threads

pin_threads()

import msgspec  # noqa: E402

from electroloc_gym.bench.records import load_records  # noqa: E402
from electroloc_gym.bench.schema import MAX_TEXT_CHARS, OLD_KEY_NAMES, POSITION_BOUND_MM, TrialRecord  # noqa: E402

RUN = Path(__file__).resolve().parents[1] / "experiments" / "reference" / "bench"


def best_ms(fn: Callable[[], Any], repeats: int) -> float:
    best = float("inf")
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return 1e3 * best


def pydantic_model() -> Any:
    """The record as a pydantic model: the same fields and ranges, and the same consistency check."""
    from pydantic import BaseModel, ConfigDict, Field, model_validator

    p, text = POSITION_BOUND_MM, Field(min_length=1, max_length=MAX_TEXT_CHARS)
    coord = Annotated[float, Field(ge=-p, le=p, allow_inf_nan=False)]
    xy = Annotated[list[coord], Field(min_length=2, max_length=2)]
    count = Annotated[int, Field(ge=1, le=2**63 - 1)]
    index = Annotated[int, Field(ge=0, le=2**63 - 1)]
    seed = Annotated[int, Field(ge=0, le=2**32 - 1)]
    offset = Annotated[float, Field(ge=-2 * p, le=2 * p, allow_inf_nan=False)]
    duration = Annotated[float, Field(ge=0.0, le=86_400e3, allow_inf_nan=False)]

    class Record(BaseModel):
        model_config = ConfigDict(extra="forbid", strict=True, frozen=True)
        condition: Annotated[str, Field(min_length=1, max_length=64)]
        agent: Annotated[str, text]
        agent_label: Annotated[str, text]
        table_layout: Literal["table4", "table1"]
        trial: index
        seed: seed
        agent_seed: seed
        success: bool
        ended_by: Literal["success", "cap", "agent"]
        readings: count
        error_mm: Annotated[float, Field(ge=0.0, le=2 * p, allow_inf_nan=False)] | None
        error_x_mm: offset | None
        error_y_mm: offset | None
        estimate: xy | None
        target: xy
        start: xy
        spread_mm: Annotated[float, Field(ge=0.0, le=1e6, allow_inf_nan=False)] | None
        decisions: index
        decision_ms_median: duration | None
        decision_ms_mean: duration | None
        sensor_model: Annotated[str, text]
        signal: Annotated[str, text]
        max_observations: count
        n_particles: count
        env_id: Annotated[str, text]
        wall_s: duration | None
        shape: dict[str, Any] | None = None
        gain_levels: Annotated[list[Annotated[float, Field(gt=0.0, le=1e12)]], Field(min_length=1)] | None = None
        sensor_layout: str | None = None
        distractors: Annotated[int, Field(ge=0, le=8)] = 0
        far_success: bool | None = None

        @model_validator(mode="after")
        def consistent(self) -> Record:
            TrialRecord._inconsistency(self)  # type: ignore[arg-type]  # the same checks, read by attribute
            return self

    return Record


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7, help="timed loads; the best is printed (default 7)")
    args = parser.parse_args()
    stored = gzip.open(RUN / "trials.jsonl.gz", "rb").read().splitlines()
    # the libraries compared on the records in the current key names (the stored run has two old ones)
    lines = [json.dumps({OLD_KEY_NAMES.get(k, k): v for k, v in json.loads(line).items()}).encode() for line in stored]
    decoder = msgspec.json.Decoder(TrialRecord)
    rows = [
        ("load_records (the package's reader)", lambda: load_records(RUN / "trials.jsonl")),
        ("msgspec decode into TrialRecord", lambda: [decoder.decode(line) for line in lines]),
    ]
    try:
        model = pydantic_model()
        validate = model.model_validate_json
        rows.append(("pydantic validate_json, same schema", lambda: [validate(line) for line in lines]))
    except ImportError:
        print("pydantic is not installed: its row is left out")
    rows.append(("json.loads, no check (floor)", lambda: [json.loads(line) for line in lines]))
    times = {name: best_ms(fn, args.repeats) for name, fn in rows}
    base = times["msgspec decode into TrialRecord"]
    print(f"{len(lines)} records of {RUN}, best of {args.repeats}, one thread")
    print(f"{'reader':42s} {'ms':>8s} {'× msgspec':>10s}")
    for name, ms in times.items():
        print(f"{name:42s} {ms:8.1f} {ms / base:10.2f}")


if __name__ == "__main__":
    main()
