"""The torch backend's scripts: examples/ppo_torch.py and benchmarks/device_throughput.py refuse bad input
with one ``prog: error: …`` line naming the option (exit 2) before any work, say every option's help and
default, choose their threads; and the benchmark — the GPU machine's one command — runs where only torch,
numpy, numba, scipy, gymnasium and msgspec are installed (everything else blocked at import), writing its JSON and
markdown.
"""

from __future__ import annotations

import importlib.metadata as md
import importlib.util
import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

torch = pytest.importorskip("torch")

from electroloc_gym.utils.runtime import user_numba_cache_dir  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
GPU_MACHINE = ("torch", "numpy", "numba", "scipy", "gymnasium", "msgspec")


def _load(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def ppo():
    return _load(ROOT / "examples" / "ppo_torch.py", "script_args_ppo_torch")


@pytest.fixture(scope="module")
def bench():
    return _load(ROOT / "benchmarks" / "device_throughput.py", "script_args_device_throughput")


def _refused(capsys, parse, argv: list[str], *words: str) -> None:
    with pytest.raises(SystemExit) as exc:
        parse(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    last = err[-1]
    assert ": error: " in last and "Traceback" not in "\n".join(err), err
    for w in words:
        assert w in last, (w, last)


def _a_file(tmp_path: Path) -> Path:
    f = tmp_path / "a_file"
    f.write_text("x")
    return f


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--num-minibatches", "0"], ["--num-minibatches", "[1, 16384]"]),
        (["--num-envs", "2", "--num-steps", "4", "--total-timesteps", "8", "--num-minibatches", "9"], ["[1, 8]"]),
        (["--eval-episodes", "0"], ["--eval-episodes", "≥ 1"]),
        (["--condition", "nope"], ["--condition", "'random'", "fresh-steel-12.7"]),
        (["--seed", "-1"], ["--seed", "≥ 0"]),
        (["--device", "cuda:7"], ["--device", "cuda:7"]),
        (["--device", "meta"], ["--device"]),
        (["--device", "nope"], ["--device", "nope"]),
        (["--gamma", "2"], ["--gamma", "≤ 1"]),
        (["--gae-lambda", "-0.1"], ["--gae-lambda"]),
        (["--clip-coef", "-1"], ["--clip-coef", "> 0"]),
        (["--update-epochs", "0"], ["--update-epochs", "≥ 1"]),
        (["--learning-rate", "nan"], ["--learning-rate", "finite"]),
        (["--learning-rate", "inf"], ["--learning-rate", "finite"]),
        (["--max-grad-norm", "0"], ["--max-grad-norm"]),
        (["--threads", "0"], ["--threads", "[1, 1024]"]),
        (["--total-timesteps", "10"], ["--total-timesteps", "16384"]),
        (["--bench-trials", "-2"], ["--bench-trials"]),
    ],
)
def test_ppo_torch_refuses_bad_input_in_one_line(ppo, capsys, argv, words):
    _refused(capsys, ppo.parse_args, argv, *words)


def test_ppo_torch_refuses_a_save_path_before_training(ppo, capsys, tmp_path):
    _refused(capsys, ppo.parse_args, ["--save", str(_a_file(tmp_path) / "policy.pt")], "--save", "is a file")
    _refused(capsys, ppo.parse_args, ["--save", str(tmp_path)], "--save", "directory")
    assert ppo.parse_args(["--save", str(tmp_path / "new" / "policy.pt"), "--device", "cpu"]).save.endswith("policy.pt")
    assert not (tmp_path / "new").exists()  # checked, nothing written


def test_ppo_torch_pins_its_threads(ppo, monkeypatch):
    """main() pins the numeric libraries' threads (the package's rule: --threads, else $ELECTROLOC_THREADS,
    else 1) before training."""
    seen = []
    monkeypatch.setattr(ppo, "pin_threads", seen.append)
    monkeypatch.setattr(ppo, "train", lambda args: (_ for _ in ()).throw(RuntimeError("stop")))
    for argv in (["--device", "cpu"], ["--device", "cpu", "--threads", "3"]):
        with pytest.raises(RuntimeError, match="stop"):
            ppo.main(argv)
    assert seen == [None, 3]


def _options_and_defaults(parse, capsys) -> tuple[list[str], str]:
    with pytest.raises(SystemExit) as exc:
        parse(["--help"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    options = re.findall(r"^  (--[a-z0-9-]+)", text, flags=re.M)
    return options, text


def test_every_option_has_help_and_default(ppo, bench, capsys):
    for parse in (ppo.parse_args, bench.parse_args):
        options, text = _options_and_defaults(parse, capsys)
        assert "--threads" in options and len(options) >= 10
        blocks = re.split(r"\n  (?=--[a-z])", text.split("options:", 1)[1])[1:]
        assert len(blocks) == len(options)
        for block in blocks:
            if not block.startswith("--help"):
                assert "default" in block, block  # "(default: …)", or the default said in words


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--seconds", "nan"], ["--seconds", "finite"]),
        (["--seconds", "inf"], ["--seconds", "finite"]),
        (["--seconds", "0"], ["--seconds", "> 0"]),
        (["--budget-s", "nan"], ["--budget-s"]),
        (["--env-kwargs", '{"n_particles": 0}'], ["--env-kwargs", "n_particles"]),
        (["--env-kwargs", '{"nope": 1}'], ["--env-kwargs", "nope"]),
        (["--env-kwargs", "[1, 2]"], ["--env-kwargs", "JSON object"]),
        (["--env-kwargs", "{not json"], ["--env-kwargs"]),
        (["--env-kwargs", '{"device": "cpu"}'], ["--env-kwargs", "device"]),
        (["--env-kwargs", '{"gain_levels": [1, 2]}'], ["--env-kwargs", "gain_levels"]),
        (["--device", "cuda:7"], ["--device", "cuda:7"]),
        (["--device", "nope"], ["--device", "nope"]),
        (["--threads", "0"], ["--threads", "[1, 1024]"]),
        (["--n-envs", "0"], ["--n-envs", "[1, 2147483647]"]),
        (["--ppo-n", "-4"], ["--ppo-n"]),
        (["--numba-n", "-1"], ["--numba-n"]),
        (["--numba-n", "1000000000"], ["--numba-n", "GiB"]),
        (["--numba-n", str(2**31)], ["--numba-n", "2147483647"]),
        (["--n-envs", "4", "1000000000"], ["--n-envs", "1000000000", "GiB"]),
        (["--ppo-n", "1000000000"], ["--ppo-n", "GiB"]),
        (["--seconds", "1000", "--budget-s", "5"], ["--seconds", "--budget-s", "2.5"]),
        (["--budget-s", "1e9"], ["--budget-s", "86400"]),
    ],
)
def test_device_throughput_refuses_bad_input_in_one_line(bench, capsys, argv, words):
    _refused(capsys, bench.parse_args, argv, *words)


def test_device_throughput_keeps_to_its_budget(bench, tmp_path):
    """Every row — the numba one first — checks the time left before it starts: the rows that would pass
    --budget-s are listed as skipped in the JSON and the markdown, and the command ends within about its
    budget."""
    out = tmp_path / "budget.json"
    argv = ["--n-envs", "4", "8", "16", "32", "64", "--numba-n", "4", "--ppo-n", "4", "--seconds", "0.2"]
    t0 = time.perf_counter()
    assert bench.main([*argv, "--budget-s", "1", "--out", str(out)]) == 0
    wall = time.perf_counter() - t0
    result = json.loads(out.read_text())
    assert wall < 1 + 2 * 0.2 + 1.0, wall  # the budget, a row's expected time, and slack for the writes
    skipped = [r for r in result["torch_rows"] + result["ppo"] if "skipped" in r]
    assert skipped and "skipped" in out.with_suffix(".md").read_text()
    assert result["numba"]["steps"] > 0  # the first row starts with the whole budget left
    # a budget of exactly two rows' timed seconds: no row fits, the numba row too is skipped and said to be
    assert bench.main([*argv, "--budget-s", "0.4", "--out", str(out)]) == 0
    result = json.loads(out.read_text())
    assert "skipped" in result["numba"] and all("skipped" in r for r in result["torch_rows"] + result["ppo"])
    assert "| numba native vector env (1 CPU core) | 4 | skipped" in out.with_suffix(".md").read_text()


def test_device_throughput_refuses_output_paths_before_timing(bench, capsys, tmp_path, monkeypatch):
    monkeypatch.setattr(bench, "numba_rate", lambda *a: pytest.fail("timed before the path check"))
    _refused(capsys, bench.main, ["--out", str(_a_file(tmp_path) / "x.json")], "--out", "is a file")
    _refused(capsys, bench.main, ["--out", str(tmp_path)], "--out", "directory")
    _refused(capsys, bench.main, ["--md", str(_a_file(tmp_path) / "x.md")], "--md", "is a file")


def _norm(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _gpu_machine_dists() -> set[str]:
    """The GPU machine's distributions: its five packages and everything they require on this Python (no
    extras; a requirement whose environment marker is false here, such as ``importlib-metadata; python <
    3.10``, is not one)."""
    from packaging.requirements import Requirement  # pytest's own dependency

    dists, todo = set(), list(GPU_MACHINE)
    while todo:
        name = _norm(re.split(r"[ ;<>=!~\[(]", todo.pop(), maxsplit=1)[0])
        if name in dists:
            continue
        dists.add(name)
        for req in md.requires(name) or []:
            marker = Requirement(req).marker
            if marker is None or marker.evaluate({"extra": ""}):
                todo.append(req)
    return dists


def _bare_site(folder: Path) -> Path:
    """A site folder holding links to the GPU machine's packages only (their modules, metadata and bundled
    libraries) and to this package as installed here (``pip install --no-deps``: its modules or its
    editable install's path hooks, and its metadata)."""
    dists = _gpu_machine_dists() | {"electroloc-gym"}
    tops = {top for top, owners in md.packages_distributions().items() if any(_norm(d) in dists for d in owners)}
    site = Path(md.distribution("torch").locate_file(""))
    folder.mkdir()
    for entry in site.iterdir():
        name = entry.name
        if name.endswith(".dist-info"):
            keep = _norm(name.split("-")[0]) in dists
        elif name.endswith(".libs"):
            keep = _norm(name[: -len(".libs")]) in dists
        elif name.endswith(".pth"):
            keep = "electroloc_gym" in name
        else:
            keep = name.split(".")[0] in tops or ("electroloc_gym" in name and name.startswith("__editable__"))
        if keep:
            (folder / name).symlink_to(entry)
    return folder


RUN_BARE = """
import runpy, site, sys
site.addsitedir(sys.argv[1])  # python -S: this folder is the only site-packages
script = sys.argv[2]
sys.argv = [script] + sys.argv[3:]
runpy.run_path(script, run_name="__main__")
"""


def test_the_gpu_command_runs_on_a_bare_machine_and_on_the_cpu(tmp_path):
    """The benchmark with only the GPU machine's packages importable (no SB3, minari, matplotlib …), on
    the CPU at tiny N: eager and compiled rows (dynamo's eager backend: the capture, no code generation),
    the PPO row, the profile and the peak bytes; JSON and markdown written. The numba kernels load from
    this process's kernel cache (the nox sessions' warm-up fills it) instead of compiling again."""
    out = tmp_path / "res" / "cpu.json"
    site = _bare_site(tmp_path / "site")
    script = str(ROOT / "benchmarks" / "device_throughput.py")
    cmd = [sys.executable, "-S", "-c", RUN_BARE, str(site), script]  # -S: no site-packages
    cmd += ["--n-envs", "4", "--numba-n", "4", "--seconds", "0.05", "--ppo-n", "4", "--compile"]
    cmd += ["--compile-backend", "eager", "--profile", "--cpu-peak", "--out", str(out)]
    env = {"PATH": "/usr/bin:/bin", "OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1", "HOME": str(tmp_path)}
    env["NUMBA_CACHE_DIR"] = os.environ.get("NUMBA_CACHE_DIR") or str(user_numba_cache_dir())
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600, cwd=tmp_path, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    result = json.loads(out.read_text())
    rows = result["torch_rows"]
    assert [(r["n_envs"], r["compile"]) for r in rows] == [(4, False), (4, True)]  # eager, PPO, compiled
    for r in rows:
        assert r["env_steps_per_s"] > 0 and r["state_bytes_per_env"] > 0 and r["peak_bytes_per_env"] > 0
    assert result["ppo"][0]["train_steps_per_s"] > 0
    assert len(result["profile"]["top"]) == 10 and result["profile"]["compile"]
    assert result["device_info"]["torch"] == torch.__version__
    page = out.with_suffix(".md").read_text()
    assert "torch, compiled | 4 |" in page and f"torch {torch.__version__}" in page
    assert "numba" in page and "PPO" in page
    for absent in ("stable_baselines3", "minari", "matplotlib", "filelock_", "rl_zoo3"):
        assert not (site / absent).exists()


def test_the_gpu_script_refuses_seconds_beyond_its_budget():
    """experiments/on_device/run_gpu.sh passes its own --budget-s: a --seconds that no row could keep to is
    one line, exit 2, before anything is timed or written."""
    results = ROOT / "experiments" / "on_device" / "results"
    before = sorted(p.name for p in results.iterdir())
    env = {**os.environ, "DEVICE": "cpu", "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    proc = subprocess.run(
        ["bash", str(ROOT / "experiments" / "on_device" / "run_gpu.sh"), "--seconds", "1000"],
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
    )
    assert proc.returncode == 2, proc.stderr[-2000:]
    last = proc.stderr.strip().splitlines()[-1]
    assert "--seconds" in last and "--budget-s" in last and "Traceback" not in proc.stderr, proc.stderr
    assert sorted(p.name for p in results.iterdir()) == before


# ---- examples/rllib_ppo.py without Ray ----------------------------------------------------------------------
def test_rllib_ppo_without_ray_is_one_line_before_any_work(tmp_path):
    """Where Ray is not installed the RLlib example refuses in one ``prog: error: …`` line, the wording of
    ``electroloc bench --backend ray`` (exit 2, no traceback, nothing created), not a traceback from ``import ray``.
    """
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    code = (
        "import sys; sys.modules['ray'] = None; import runpy; sys.argv = ['rllib_ppo.py', '--out', sys.argv[1]]; "
        f"runpy.run_path({str(ROOT / 'examples' / 'rllib_ppo.py')!r}, run_name='__main__')"
    )
    out = tmp_path / "run"
    done = subprocess.run([sys.executable, "-c", code, str(out)], capture_output=True, text=True, env=env, timeout=120)
    err = done.stderr.strip().splitlines()
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    assert err[-1].endswith(
        "error: examples/rllib_ppo.py needs Ray, which is not installed here: pip install 'electroloc-gym[rllib]'"
    )
    assert not out.exists()
    from electroloc_gym.bench.ray_backend import ray_missing

    assert ray_missing("--backend ray") == (
        "--backend ray needs Ray, which is not installed here: pip install 'electroloc-gym[ray]' (or pip install ray)"
    )


# ---- the experiments' long scripts say what they wrote ------------------------------------------------------
#: (script, its argv with {tmp} for the test's folder, the files it writes) — each run as small as it goes.
WRITERS = [
    (
        "experiments/distractors/distractor_comparison.py",
        ["--report-only", "--out", "{tmp}/dc", "--table", "{tmp}/dc.md"],
        ["dc/comparison.json", "dc.md"],
    ),
    (
        "experiments/array/commutativity.py",
        ["--trials", "2", "--particles", "50", "--conditions", "fresh-steel-12.7", "--out", "{tmp}/c.json"],
        ["c.json"],
    ),
    (
        "experiments/distractors/distractor_budget.py",
        ["--agents", "rnd-wlk", "--trials", "1", "--budget", "3", "--out", "{tmp}/b.json"],
        ["b.json"],
    ),
    (
        "experiments/planners/lookahead_budget.py",
        ["--trials", "1", "--global-trials", "0", "--conditions", "fresh-steel-12.7", "--n-particles", "100"]
        + ["--max-observations", "3", "--out", "{tmp}/l.png"],
        ["l.json", "l.png"],
    ),
    (
        "experiments/gain/dynamic_gain.py",
        ["--trials", "1", "--settings", "paper", "--plot", "{tmp}/g.png"],
        ["g.png"],
    ),
]


def _run_script(script: str, argv: list[str], tmp_path: Path) -> subprocess.CompletedProcess:
    args = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}
    return subprocess.run(
        [sys.executable, str(ROOT / script), *args], capture_output=True, text=True, env=env, timeout=300, cwd=ROOT
    )


def _wrote(stderr: str) -> list[str]:
    return [line.removeprefix("wrote: ") for line in stderr.splitlines() if line.startswith("wrote: ")]


@pytest.mark.parametrize(("script", "argv", "files"), WRITERS, ids=[w[0].split("/")[-1] for w in WRITERS])
def test_an_experiment_script_lists_every_file_it_wrote(script, argv, files, tmp_path):
    done = _run_script(script, argv, tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    wrote = _wrote(done.stderr)
    assert sorted(wrote) == sorted(str(tmp_path / f) for f in files), done.stderr[-2000:]
    assert all(Path(p).is_file() for p in wrote)


def test_the_array_tradeoff_run_and_report_list_what_they_wrote(tmp_path):
    run = _run_script(
        "experiments/array/array_tradeoff.py",
        ["run", "--trials", "1", "--layouts", "single", "--agents", "rnd-wlk", "--out", "{tmp}/r.jsonl"],
        tmp_path,
    )
    assert run.returncode == 0 and _wrote(run.stderr) == [str(tmp_path / "r.jsonl")], run.stderr[-2000:]
    report = _run_script(
        "experiments/array/array_tradeoff.py",
        ["report", "{tmp}/r.jsonl", "--table", "{tmp}/a.md", "--figure", "{tmp}/a.png"],
        tmp_path,
    )
    assert report.returncode == 0 and _wrote(report.stderr) == [str(tmp_path / "a.md"), str(tmp_path / "a.png")]
