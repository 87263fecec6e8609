"""The optional Ray benchmark backend: same trials as the process backend; skipped without Ray."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from electroloc_gym.bench.backends import BACKENDS, make_backend
from electroloc_gym.bench.ray_backend import RayBackend


def _records(out: Path) -> dict[tuple[str, str, int], dict]:
    recs = [json.loads(line) for line in (out / "trials.jsonl").read_text().splitlines() if line.strip()]

    def timing(k: str) -> bool:  # measured durations differ between runs; everything else must not
        return "_ms" in k or "time" in k or k.endswith("_s") or k in ("worker", "pid")

    return {(r["condition"], r["agent"], r["trial"]): {k: v for k, v in r.items() if not timing(k)} for r in recs}


def test_ray_backend_is_registered_and_validates_options() -> None:
    assert BACKENDS["ray"] is RayBackend
    assert make_backend("ray", 2, address="auto").address == "auto"
    with pytest.raises(ValueError, match="address"):
        RayBackend(address="")
    with pytest.raises(ValueError, match="workers"):
        RayBackend(workers=0)


def test_ray_backend_gives_the_process_backends_trials(tmp_path: Path) -> None:
    pytest.importorskip("ray")
    from electroloc_gym.bench.config import BenchConfig
    from electroloc_gym.bench.runner import run_benchmark

    config = BenchConfig(agents=("rnd-wlk",), conditions=("fresh-steel-12.7", "salt-delrin-38.1"), trials=3,
                         n_particles=300, max_observations=12)
    run_benchmark(config, tmp_path / "process", workers=2, backend="process", progress=False, log=None)
    run_benchmark(config, tmp_path / "ray", workers=2, backend="ray", progress=False, log=None)
    a, b = _records(tmp_path / "process"), _records(tmp_path / "ray")
    assert len(a) == 6 and a.keys() == b.keys()
    for key in a:
        assert a[key] == b[key], key
