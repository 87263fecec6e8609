"""Test configuration: one numeric thread per process (docs/performance.md), headless matplotlib, property
tests with fixed examples, the files of long tests first, the checks of the project's own text and plumbing
marked to run once."""

import os
import re
import tempfile
from pathlib import Path

import pytest

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
os.environ.setdefault("MPLBACKEND", "Agg")

try:  # pin already-loaded BLAS pools too
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)
except ImportError:  # pragma: no cover
    pass

try:
    import torch

    torch.set_num_threads(1)
except ImportError:  # pragma: no cover
    pass

# Property tests draw the same examples on every run and machine (a fixed seed, like every statistical
# check here): a failure found once is found again, and CI cannot pass or fail by chance.
from hypothesis import settings  # noqa: E402

settings.register_profile("fixed", derandomize=True, database=None)
settings.load_profile("fixed")


_EXTRA_MARK = re.compile(r"^pytestmark = pytest\.mark\.(rllib|zoo|minari)\b", re.M)


def pytest_ignore_collect(collection_path: Path, config: pytest.Config) -> bool | None:
    """A module marked for an optional extra is not imported when ``-m`` deselects its marker.

    Its imports need the extra, which a session that deselects it does not install (nox's ``lowest``
    and ``tests``); importing it anyway would fail or skip where the marker already says "not here".
    """
    if collection_path.suffix != ".py" or not config.option.markexpr:
        return None
    found = _EXTRA_MARK.search(collection_path.read_text(encoding="utf-8"))
    if found is None:
        return None
    from _pytest.mark.expression import Expression  # the parser of -m itself

    def matches(name: str, **_kwargs: object) -> bool:
        return name == found.group(1)

    return True if not Expression.compile(config.option.markexpr).evaluate(matches) else None


#: The test files whose outcome no declared minimum can change, marked ``once``: the tests session runs them, the
#: lowest session (the suite again on the declared minimum versions) does not. Three kinds:
#:
#: * the project's own text and plumbing — its docs and their snippets' references, the import graph, the literal
#:   and metric-name scans, the command lines' and scripts' option handling, the output path rule, the kept
#:   result files: they read the package's own code and files;
#: * the package tree and the operating system's side of a run — the installed tree, the benchmark's lock, its
#:   worker processes, kill-and-resume, the resume's record checks: files, signals and processes;
#: * the torch engine's graphs (the static gather under ``torch.cond``, ``torch.compile`` without graph breaks):
#:   torch is pinned to one release in both constraints files, so the lowest session would run the same torch.
ONCE_FILES = frozenset(
    {
        "test_docs_links.py",
        "test_docs_agree.py",
        "test_doc_blocks.py",
        "test_readme.py",
        "test_markdown.py",
        "test_table_literals.py",
        "test_imports.py",
        "test_metric_names.py",
        "test_env_names.py",
        "test_settings_parity.py",
        "test_output_paths.py",
        "test_script_args.py",
        "test_results_page.py",
        "test_stored_summaries.py",
        "test_kept_records.py",
        "test_smoke.py",
        "test_packaging.py",
        "test_bench_reliability.py",
        "test_bench_resume.py",
        "test_torch_gather.py",
        "test_torch_compile.py",
    }
)


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Files of :data:`ONCE_FILES` are marked ``once`` (before ``-m`` selects); the files holding a ``long``
    test run first, the rest in collection order.

    pytest-xdist's file scheduling (``--dist loadfile --no-loadscope-reorder``, the nox sessions) hands
    files to the workers in collection order. A two-minute file handed out late runs alone on one worker
    while the other has finished; xdist's default order (the files with the most tests first) handed the
    116 s file of six tests out near the end, and the other worker sat idle for the last 85 s of a 254 s
    run. Started first, it runs beside the rest. The order within a file is kept.
    """
    for item in items:
        if item.path.name in ONCE_FILES:
            item.add_marker(pytest.mark.once)
    long_files = {item.path for item in items if item.get_closest_marker("long")}
    if long_files:
        items.sort(key=lambda item: item.path not in long_files)


@pytest.fixture()
def train_summary_json():
    """Write a finished training run's ``summary.json`` (its one schema, ``electroloc_gym.train.summary``) for an env
    and its validation block: ``write(path, env_id, validation)``."""

    def write(path: Path, env_id: str, validation: dict) -> None:
        import msgspec

        from electroloc_gym.train.summary import TrainSummary, Validation

        run = (env_id, "ppo", 1, "python -m rl_zoo3.train", [], True, 0, 0.0, 0.0, None, None, Validation(**validation))
        path.write_bytes(msgspec.json.encode(TrainSummary(*run, chosen_by="", best=None, evaluations=0)))

    return write


@pytest.fixture(autouse=True, scope="session")
def _temporary_folders(tmp_path_factory: pytest.TempPathFactory):
    """What the tests make in the system's temporary folder goes to pytest's own temporary tree (kept for its
    last three runs) instead: SB3's logger, made by any ``learn()`` without one, makes a dated folder there
    even when it writes no file (``SB3_LOGDIR``); ``electroloc_gym.bench.run`` without ``out`` makes a new
    folder for its results (``tempfile``'s folder, in the test's process; Ray finds its own from ``TMPDIR``,
    left as it is: its socket paths must stay short)."""
    patch = pytest.MonkeyPatch()
    patch.setenv("SB3_LOGDIR", str(tmp_path_factory.mktemp("sb3-logger")))
    patch.setattr(tempfile, "tempdir", str(tmp_path_factory.mktemp("tempfile")))
    yield
    patch.undo()
