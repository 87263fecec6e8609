"""Datasets under faults: killed runs resume to the uninterrupted dataset, damaged files are set aside and
re-collected, --force replaces exactly the dataset it names, and bad input is one line before any write.

The kills are real SIGKILLs of a running writer, with no hook in the package: a forked copy of this
process (no interpreter start) killed when the test sees a moment of the write on disk (the partial's
header, an episode staged, moved in, the header marked complete) or after a fraction of an uninterrupted
run's time, and the command itself killed in a subprocess. A staged episode lasts milliseconds, less than a
loaded machine may leave the polling test unscheduled, so the forked writer that is killed at a seen moment
keeps each staged episode staged :data:`HOLD_S` before its move (its own ``os.rename`` waits; the package
runs unchanged).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

minari = pytest.importorskip("minari")  # the dev extra installs it; the numpy lower-bound session deselects these

from electroloc_gym.cli import main as cli_main  # noqa: E402
from electroloc_gym.dataset import DatasetRequest, build_dataset  # noqa: E402
from electroloc_gym.dataset import store as st  # noqa: E402
from electroloc_gym.utils.fileio import FolderLock  # noqa: E402

pytestmark = pytest.mark.minari

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "experiments" / "learned" / "results" / "ElectroLoc-v0" / "_baselines" / "bench"
ID = "electroloc/ElectroLoc-v0/rnd-wlk-v0"
N = 4  # episodes of the datasets below (rnd-wlk: about 0.01 s each)
LONG = 30  # episodes of the runs killed at a moment
THREADS = {"OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
HOLD_S = 0.03  # how long the killed writer keeps a staged episode staged (a poll every 0.2 ms then sees it)


def _request(episodes: int = N, **kwargs) -> DatasetRequest:
    return DatasetRequest("ElectroLoc-v0", "rnd-wlk", episodes, **kwargs)


def _build(episodes: int = N, notes: list[str] | None = None, **kwargs):
    options = {k: kwargs.pop(k) for k in ("resume", "force") if k in kwargs}
    sink = notes if notes is not None else []
    return build_dataset(_request(episodes, **kwargs), progress=False, notify=sink.append, **options)


def _tree(folder: Path) -> dict[str, str]:
    """sha256 of every file under ``folder``/data, by relative path (the header included)."""
    data = folder / "data"
    files = [p for p in data.rglob("*") if p.is_file()]
    return {str(p.relative_to(data)): hashlib.sha256(p.read_bytes()).hexdigest() for p in files}


@pytest.fixture()
def root(tmp_path, monkeypatch) -> Path:
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    return tmp_path / "minari"


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory) -> dict:
    """The files of uninterrupted runs (episodes → their data/ tree), and the long run's wall time (s)."""
    out: dict = {}
    with pytest.MonkeyPatch.context() as mp:
        for episodes in (N, LONG):
            base = tmp_path_factory.mktemp(f"uninterrupted{episodes}")
            mp.setenv("MINARI_DATASETS_PATH", str(base))
            start = time.perf_counter()
            _build(episodes)
            out["seconds"] = time.perf_counter() - start
            out[episodes] = _tree(base.joinpath(*ID.split("/")))
    return out


def _folder(root: Path, ds_id: str = ID) -> Path:
    return root.joinpath(*ds_id.split("/"))


def _partial(root: Path, ds_id: str = ID) -> Path:
    return st.DatasetFolder(root, ds_id).partial


def _unpublish(root: Path) -> Path:
    """What a run killed before its last rename leaves: the dataset as the partial folder."""
    _folder(root).rename(_partial(root))
    return _partial(root)


def _siblings(root: Path) -> list[str]:
    return sorted(p.name for p in _folder(root).parent.iterdir())


def _hold_staged_episodes() -> None:
    """In the forked writer only: each rename out of the staging folder waits :data:`HOLD_S` first."""
    rename = os.rename

    def held(src, dst, *args, **kwargs):
        if Path(src).parent.name == st.STAGING:
            time.sleep(HOLD_S)
        return rename(src, dst, *args, **kwargs)

    os.rename = held


def _kill_when(moment: Callable[[Path], bool] | float, root: Path, episodes: int = LONG, **build_kwargs) -> bool:
    """Run ``_build`` in a forked copy of this process and SIGKILL it when ``moment(root)`` first holds (polled
    every 0.2 ms) or after ``moment`` seconds; True when the kill landed before the run ended.
    """
    pid = os.fork()
    if pid == 0:  # the child: never returns into pytest
        code = 4
        try:
            if not isinstance(moment, float):
                _hold_staged_episodes()
            _build(episodes, **build_kwargs)
            code = 0
        finally:
            os._exit(code)
    if isinstance(moment, float):
        time.sleep(moment)
    else:
        deadline = time.monotonic() + 120
        while not moment(root) and time.monotonic() < deadline:
            done, status = os.waitpid(pid, os.WNOHANG)
            if done:
                assert os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0, status
                return False
            time.sleep(0.0002)
    os.kill(pid, signal.SIGKILL)
    _, status = os.waitpid(pid, 0)
    if os.WIFEXITED(status):
        assert os.WEXITSTATUS(status) == 0, status
        return False
    assert os.WTERMSIG(status) == signal.SIGKILL, status
    return True


# ---- kills -----------------------------------------------------------------------------------------------
def _complete(root: Path) -> bool:
    return _partial(root).is_dir() and st.is_complete(_partial(root))


# (what the test waits to see on disk, whether the run may finish before the kill lands)
MOMENTS = {
    "the partial's header": (lambda r: st.header_path(_partial(r)).exists(), False),
    "the first episode staged": (lambda r: (_partial(r) / st.STAGING / "0").exists(), False),
    "episode 9 moved in": (lambda r: (_partial(r) / "data" / "9").exists(), False),
    "episode 20 staged": (lambda r: (_partial(r) / st.STAGING / "20").exists(), False),
    "the last episode moved in": (lambda r: (_partial(r) / "data" / str(LONG - 1)).exists(), True),
    "the header marked complete": (_complete, True),
}
FRACTIONS = (0.15, 0.35, 0.55, 0.75, 0.95)


@pytest.mark.parametrize("moment", [*MOMENTS, *FRACTIONS], ids=str)
def test_a_run_killed_at_any_moment_resumes_to_the_uninterrupted_dataset(root, uninterrupted, moment):
    if isinstance(moment, str):
        seen, late = MOMENTS[moment]
        killed = _kill_when(seen, root)
        assert killed or late, f"the run ended before {moment}"
    else:
        _kill_when(moment * uninterrupted["seconds"], root)
    notes: list[str] = []
    ds = _build(LONG, resume=True, notes=notes)
    assert ds.total_episodes == LONG and ds.storage.metadata["electroloc"]["complete"]
    assert _tree(_folder(root)) == uninterrupted[LONG]
    assert notes == [] or notes[0].endswith("nothing to collect")  # a kill leaves nothing damaged to report
    assert not (_folder(root) / st.QUARANTINE).exists() and not (_folder(root) / st.STAGING).exists()
    assert _siblings(root) == ["namespace_metadata.json", "rnd-wlk-v0"]  # no partial, no old copy left


def test_a_run_killed_while_a_resume_sets_files_aside_resumes_again(root, uninterrupted):
    _build(LONG)
    folder = _folder(root)
    for k in range(5, 25):
        (folder / "data" / str(k) / "part-0.arrow").write_bytes(b"damaged")
    assert _kill_when(lambda r: (_partial(r) / st.QUARANTINE / "1").exists(), root, resume=True)
    notes: list[str] = []
    _build(LONG, resume=True, notes=notes)
    assert _tree(folder) == uninterrupted[LONG]
    moved = sorted(int(p.parent.name) for p in (folder / st.QUARANTINE).rglob("part-0.arrow"))
    assert moved == list(range(5, 25))  # every damaged file kept, in one set-aside folder or two


def test_the_command_killed_at_an_arbitrary_moment_resumes(root, uninterrupted):
    env = {**os.environ, **THREADS, "MINARI_DATASETS_PATH": str(root)}
    argv = [sys.executable, "-m", "electroloc_gym.cli", "dataset", "--no-progress", "--agent", "rnd-wlk"]
    proc = subprocess.Popen(
        [*argv, "--episodes", str(LONG)], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    data = _partial(root) / "data"
    deadline = time.monotonic() + 300
    while not (data / "2").exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.001)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    assert proc.returncode == -signal.SIGKILL  # killed mid-run, not finished
    with pytest.raises(
        ValueError, match=r"exists \(an unfinished one at .*electroloc-partial\); .*resume=True to continue"
    ):
        _build(LONG)
    proc = subprocess.run(
        [*argv, "--episodes", str(LONG), "--resume"], env=env, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr
    assert f"{ID}: {LONG} episodes" in proc.stdout
    assert _tree(_folder(root)) == uninterrupted[LONG]


# ---- damaged files ---------------------------------------------------------------------------------------
def _flip(path: Path, offsets=(0.3, 0.5, 0.7)) -> None:
    data = bytearray(path.read_bytes())
    for f in offsets:
        data[int(f * len(data))] ^= 0xFF
    path.write_bytes(bytes(data))


def _truncate(path: Path) -> None:
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def _rewrite_json(path: Path, **changes) -> None:
    meta = json.loads(path.read_text(encoding="utf-8"))
    meta.update(changes)
    path.write_text(json.dumps(meta), encoding="utf-8")


def _zeros(key: str) -> Callable[[Path], None]:
    return lambda f: _rewrite_json(f / "data/1/metadata.json", **{key: "0" * 64})


# (damage, what is set aside under quarantine/1, words of the one line)
DAMAGES = {
    "truncated arrow": (lambda f: _truncate(f / "data/1/part-0.arrow"), ["data/1/part-0.arrow"], "1: part-0.arrow"),
    "flipped arrow bytes": (lambda f: _flip(f / "data/2/part-0.arrow"), ["data/2/part-0.arrow"], "2: part-0.arrow"),
    "flipped episode metadata": (
        lambda f: _flip(f / "data/0/metadata.json", (0.5,)),
        ["data/0/metadata.json"],
        "0: metadata.json",
    ),
    "missing arrow": (lambda f: (f / "data/1/part-0.arrow").unlink(), ["data/1/metadata.json"], "1: no part-0.arrow"),
    "missing episode metadata": (
        lambda f: (f / "data/3/metadata.json").unlink(),
        ["data/3/part-0.arrow"],
        "3: no metadata.json",
    ),
    "missing episode": (lambda f: shutil.rmtree(f / "data/2"), [], "episode 2 missing"),
    "another episode's metadata": (
        lambda f: shutil.copy(f / "data/2/metadata.json", f / "data/1/metadata.json"),
        ["data/1/metadata.json"],
        "1: metadata.json does not name this episode",
    ),
    "an altered checksum": (_zeros("sha256"), ["data/1"], "1: part-0.arrow does not match its checksum"),
    "another run's episode": (_zeros("settings_sha256"), ["data/1"], "1: written with other settings"),
    "a length the arrow file does not hold": (
        lambda f: _rewrite_json(f / "data/1/metadata.json", total_steps=2),
        ["data/1"],
        "1: part-0.arrow holds",
    ),
    "junk file in data": (
        lambda f: (f / "data/junk.bin").write_bytes(b"\0junk"),
        ["data/junk.bin"],
        "data/junk.bin: not part of the dataset",
    ),
    "junk folder in data": (lambda f: (f / "data/tmp").mkdir(), ["data/tmp"], "data/tmp: not part of the dataset"),
    "an episode that is a file": (
        lambda f: (shutil.rmtree(f / "data/3"), (f / "data/3").write_text("x")),
        ["data/3"],
        "1 damaged episode (3: not part of the dataset)",
    ),
    "extra arrow in an episode": (
        lambda f: shutil.copy(f / "data/2/part-0.arrow", f / "data/2/part-1.arrow"),
        ["data/2/part-1.arrow"],
        "data/2/part-1.arrow: not a file of episode 2",
    ),
    "empty header": (
        lambda f: (f / "data/metadata.json").write_bytes(b""),
        ["data/metadata.json"],
        "data/metadata.json unreadable",
    ),
    "garbage header": (lambda f: _flip(f / "data/metadata.json", (0.0,)), ["data/metadata.json"], "unreadable"),
    "header of a list": (
        lambda f: (f / "data/metadata.json").write_text("[1, 2]"),
        ["data/metadata.json"],
        "not a JSON object",
    ),
    "altered header": (
        lambda f: _rewrite_json(f / "data/metadata.json", env_spec="{}"),
        ["data/metadata.json"],
        "differs from the header of these settings",
    ),
    "miscounted header": (
        lambda f: _rewrite_json(f / "data/metadata.json", total_steps=3, total_episodes=1),
        [],
        None,  # the counts are rewritten from the kept episodes; nothing is damaged
    ),
    "missing header": (lambda f: (f / "data/metadata.json").unlink(), [], "data/metadata.json missing"),
    "a journal of the earlier layout": (
        lambda f: (f / "checksums.jsonl").write_text("{}\n"),
        ["checksums.jsonl"],
        "checksums.jsonl: not part of the dataset",
    ),
    "leftover temporaries": (
        lambda f: ((f / "data/.metadata.json.ab12.tmp").write_text("{"), (f / st.STAGING / "1").mkdir(parents=True)),
        [],
        None,  # this package's own leftovers: deleted, nothing to say
    ),
}


@pytest.mark.parametrize("damage", list(DAMAGES))
def test_resume_sets_aside_every_damaged_file_and_recollects(root, uninterrupted, damage):
    spoil, set_aside, words = DAMAGES[damage]
    _build()
    spoil(_unpublish(root))
    notes: list[str] = []
    ds = _build(resume=True, notes=notes)
    folder = _folder(root)
    assert _tree(folder) == uninterrupted[N]  # the uninterrupted dataset, every byte
    assert ds.total_episodes == N and len(list(ds.iterate_episodes())) == N
    assert not list(folder.rglob("*.tmp")) and not (folder / st.STAGING).exists()
    assert _siblings(root) == ["namespace_metadata.json", "rnd-wlk-v0"]
    if words is None:
        assert notes == [] and not (folder / "quarantine").exists()
        return
    assert len(notes) == 1 and "\n" not in notes[0] and words in notes[0], notes
    quarantine = folder / "quarantine" / "1"
    for rel in set_aside:
        assert (quarantine / rel).exists(), (rel, sorted(quarantine.rglob("*")))  # moved, not deleted
    if set_aside:
        assert str(_partial(root) / "quarantine" / "1") in notes[0]
    else:  # nothing was moved (a missing header is rebuilt): the note names no place and none is made
        assert "set aside" not in notes[0] and not (folder / "quarantine").exists(), notes


def test_the_command_says_what_it_set_aside_in_one_line(root, capsys):
    _build()
    _truncate(_unpublish(root) / "data/1/part-0.arrow")
    assert cli_main(["dataset", "--no-progress", "--agent", "rnd-wlk", "--episodes", str(N), "--resume"]) == 0
    err = [line for line in capsys.readouterr().err.splitlines() if "set aside" in line]
    assert len(err) == 1 and err[0].startswith("electroloc dataset: ") and "1 damaged episode" in err[0]


def test_resume_refuses_before_moving_anything(root):
    _build()
    folder = _unpublish(root)
    (folder / "data/9").mkdir()
    snapshot = sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))
    with pytest.raises(ValueError, match="holds episode 9; resume it with --episodes 10 or more"):
        _build(resume=True)
    (folder / "data/9").rmdir()
    with pytest.raises(ValueError, match="other settings"):
        _build(resume=True, seed=2)
    assert sorted(str(p.relative_to(folder)) for p in folder.rglob("*")) == [s for s in snapshot if s != "data/9"]


COMPLETE_DAMAGES = {
    "flipped arrow": (lambda f: _flip(f / "data/1/part-0.arrow"), "data/1"),
    "truncated arrow": (lambda f: _truncate(f / "data/0/part-0.arrow"), "data/0"),
    "deleted arrow": (lambda f: (f / "data/2/part-0.arrow").unlink(), "data/2"),
    "deleted episode": (lambda f: shutil.rmtree(f / "data/3"), None),
    "flipped episode metadata": (lambda f: _flip(f / "data/2/metadata.json", (0.5,)), "data/2"),
    "altered header": (lambda f: _rewrite_json(f / "data/metadata.json", env_spec="{}"), "data/metadata.json"),
}


@pytest.mark.parametrize("damage", list(COMPLETE_DAMAGES))
def test_resume_repairs_a_damaged_complete_dataset(root, uninterrupted, damage):
    spoil, set_aside = COMPLETE_DAMAGES[damage]
    _build()
    folder = _folder(root)
    spoil(folder)
    with pytest.raises(ValueError, match=r"exists \(a complete one.*or resume=True to check its episodes"):
        _build()
    notes: list[str] = []
    ds = _build(resume=True, notes=notes)
    assert _tree(folder) == uninterrupted[N] and ds.storage.metadata["electroloc"]["complete"]
    assert len(notes) == 1 and "\n" not in notes[0], notes
    if set_aside is not None:
        assert (folder / "quarantine" / "1" / set_aside).exists() and set_aside.split("/")[-1] in notes[0]


def test_resume_of_an_intact_complete_dataset_changes_no_episode(root, uninterrupted, capsys):
    _build()
    folder = _folder(root)
    header = st.header_path(folder).read_bytes()
    argv = ["dataset", "--no-progress", "--agent", "rnd-wlk", "--episodes", str(N), "--resume"]
    assert cli_main(argv) == 0
    err = capsys.readouterr().err
    assert "complete; all 4 episodes match their checksums and read back: nothing to collect" in err
    assert _tree(folder) == uninterrupted[N] and st.header_path(folder).read_bytes() == header
    assert not (folder / "quarantine").exists()


def test_resume_extends_a_complete_dataset_to_more_episodes(root, uninterrupted):
    _build(2)
    ds = _build(resume=True)  # the same seeds: the first two episodes kept, the rest collected
    assert ds.total_episodes == N and _tree(_folder(root)) == uninterrupted[N]


def test_resume_refuses_a_dataset_it_did_not_write(root, tmp_path):
    _build()
    env = minari.load_dataset(ID).recover_environment()
    buffer = minari.load_dataset(ID).storage.get_episodes([0])
    episode = next(iter(buffer))
    from minari.data_collector.episode_buffer import EpisodeBuffer

    minari.create_dataset_from_buffers(
        "other/plain-v0",
        [
            EpisodeBuffer(
                observations=list(episode["observations"]),
                actions=list(episode["actions"]),
                rewards=list(episode["rewards"]),
                terminations=list(episode["terminations"]),
                truncations=list(episode["truncations"]),
            )
        ],
        env=env.spec,
        data_format="arrow",
        eval_env=env.spec,
        algorithm_name="x",
        author="x",
        author_email="x",
        code_permalink="x",
        description="x",
    )
    with pytest.raises(ValueError, match="not written by electroloc dataset"):
        _build(resume=True, dataset_id="other/plain-v0")
    ds = _build(force=True, dataset_id="other/plain-v0")  # exactly a dataset: --force replaces it
    assert ds.total_episodes == N and ds.storage.metadata["electroloc"]["complete"]


# ---- --force ---------------------------------------------------------------------------------------------
def _two_datasets(root: Path) -> dict[str, dict[str, str]]:
    _build(2)
    build_dataset(DatasetRequest("ElectroLoc-v0", "min-var", 1), progress=False)
    ids = [ID, "electroloc/ElectroLoc-v0/min-var-v0"]
    return {i: _tree(_folder(root, i)) for i in ids}


@pytest.mark.parametrize(
    ("ds_id", "words"),
    [
        ("electroloc/ElectroLoc-v0", "names a namespace folder"),
        ("electroloc/ElectroLoc-v0/min-var-v0/data", "dataset id must be NAMESPACE/NAME-vN"),
        ("electroloc/ElectroLoc-v0/min-var-v0/data-v0", "lies inside the dataset 'electroloc/ElectroLoc-v0/min-var"),
        ("electroloc/ElectroLoc-v0/min-var-v0/data/0-v0", "lies inside the dataset"),
        ("electroloc-v0", "dataset id must be NAMESPACE/NAME-vN"),
    ],
)
def test_force_refuses_an_id_that_is_not_exactly_a_dataset(root, capsys, ds_id, words):
    before = _two_datasets(root)
    argv = ["dataset", "--no-progress", "--agent", "rnd-wlk", "--episodes", "1", "--id", ds_id, "--force"]
    assert cli_main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("electroloc dataset: error: ") and words in err[0], err
    assert {i: _tree(_folder(root, i)) for i in before} == before  # nothing deleted
    assert minari.load_dataset(ID).total_episodes == 2


def test_a_file_where_the_set_aside_folder_goes_is_refused_before_anything_moves(root):
    _build()
    folder = _folder(root)
    _flip(folder / "data/1/part-0.arrow")
    (folder / st.QUARANTINE).write_text("mine")
    before = sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))
    for options in ({"resume": True}, {"force": True}):
        with pytest.raises(ValueError, match="holds a file 'quarantine' where its set-aside folder goes"):
            _build(**options)
    assert sorted(str(p.relative_to(folder)) for p in folder.rglob("*")) == before


def test_an_id_a_case_insensitive_file_system_finds_under_another_spelling_is_refused(root, monkeypatch):
    _build(2, dataset_id="mine/keep-v0")
    before = _tree(_folder(root, "mine/keep-v0"))
    real = os.listdir
    # what a case-insensitive file system shows: the id's path exists, the listing spells it otherwise
    monkeypatch.setattr(st.os, "listdir", lambda p: [n.replace("keep", "KEEP") for n in real(p)])
    for options in ({"force": True}, {"resume": True}, {}):
        with pytest.raises(ValueError, match=r"does not tell upper from lower case, and 'mine/KEEP-v0' exists"):
            _build(dataset_id="mine/keep-v0", **options)
    monkeypatch.undo()
    assert _tree(_folder(root, "mine/keep-v0")) == before


def test_force_refuses_folders_that_hold_more_than_a_dataset(root):
    _build(1)
    folder = _folder(root)
    (folder / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match=r"holds \['notes.txt'\] besides the dataset"):
        _build(force=True)
    plain = root / "mine" / "plain-v0"
    plain.mkdir(parents=True)
    (plain / "keep.txt").write_text("mine")
    with pytest.raises(ValueError, match="names a folder"):
        _build(force=True, dataset_id="mine/plain-v0")
    (root / "file").write_text("mine")
    with pytest.raises(ValueError, match="is a file"):
        _build(force=True, dataset_id="file/x-v0")
    assert (folder / "notes.txt").read_text() == "mine" and (plain / "keep.txt").read_text() == "mine"
    assert (root / "file").read_text() == "mine" and minari.load_dataset(ID).total_episodes == 1


def test_force_replaces_a_linked_dataset_by_a_folder_and_leaves_the_link_target(root, tmp_path, uninterrupted):
    _build(2, seed=5)
    elsewhere = tmp_path / "elsewhere-v0"
    _folder(root).rename(elsewhere)
    _folder(root).symlink_to(elsewhere, target_is_directory=True)
    before = _tree(elsewhere)
    assert _build(2, resume=False, force=True).total_episodes == 2
    assert not _folder(root).is_symlink() and _tree(elsewhere) == before  # the link went, not what it named
    assert sorted(p.name for p in _folder(root).parent.iterdir()) == ["namespace_metadata.json", "rnd-wlk-v0"]


def test_deeply_nested_json_is_damage_not_a_crash(root, uninterrupted):
    _build()
    folder = _unpublish(root)
    (folder / "data/metadata.json").write_text("[" * 100_000 + "]" * 100_000)
    (folder / "data/1/metadata.json").write_text("[" * 100_000)
    notes: list[str] = []
    _build(resume=True, notes=notes)
    assert _tree(_folder(root)) == uninterrupted[N] and len(notes) == 1 and "1 damaged episode" in notes[0]


def test_force_replaces_exactly_the_dataset_it_names(root, uninterrupted):
    before = _two_datasets(root)
    ds = _build(force=True)
    assert ds.total_episodes == N and _tree(_folder(root)) == uninterrupted[N]
    other = "electroloc/ElectroLoc-v0/min-var-v0"
    assert _tree(_folder(root, other)) == before[other]
    siblings = sorted(p.name for p in _folder(root).parent.iterdir())
    assert siblings == ["min-var-v0", "namespace_metadata.json", "rnd-wlk-v0"]


@pytest.fixture()
def user_module(tmp_path, monkeypatch):
    (tmp_path / "ds_fault_agents.py").write_text(
        textwrap.dedent(
            """
            import numpy as np

            class Agent:
                name = "faulty"

                def __init__(self, where):
                    self.where = where
                    self.calls = 0

                def reset(self, env):
                    if self.where == "reset":
                        raise RuntimeError("no reset today")

                def predict(self, obs, state=None, episode_start=None, deterministic=True):
                    self.calls += 1
                    if self.where == "predict":
                        raise RuntimeError("boom")
                    if self.where == "nan":
                        return np.array([np.nan, 0.0]), state
                    return np.zeros(2, dtype=np.float32), state

            def make(where="predict"):
                return Agent(where)
            """
        )
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    return "ds_fault_agents"


def test_force_with_an_agent_that_fails_at_once_keeps_the_old_dataset(root, capsys, user_module):
    _build(2)
    before = _tree(_folder(root))
    argv = ["dataset", "--no-progress", "--agent", f"{user_module}:make", "--episodes", "2", "--id", ID, "--force"]
    assert cli_main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0] == (
        f"electroloc dataset: error: agent '{user_module}:make' in episode 0 of {ID}: its predict() raised "
        "RuntimeError: boom"
    )
    assert _tree(_folder(root)) == before and minari.load_dataset(ID).total_episodes == 2
    assert sorted(p.name for p in _folder(root).parent.iterdir()) == ["namespace_metadata.json", "rnd-wlk-v0"]


@pytest.mark.parametrize("moment", ["the partial's header", "the first episode staged", "episode 20 staged"])
def test_force_killed_before_the_swap_leaves_the_old_dataset(root, uninterrupted, moment):
    _build(2, seed=5)
    before = _tree(_folder(root))
    assert _kill_when(MOMENTS[moment][0], root, force=True)
    assert _tree(_folder(root)) == before and minari.load_dataset(ID).total_episodes == 2
    with pytest.raises(ValueError, match=r"has an unfinished replacement at .*; pass force=True to continue it"):
        _build(LONG, resume=True)  # a resume never replaces the dataset the id names
    _build(LONG, force=True)  # the replacement continued: what the killed run wrote is kept
    assert _tree(_folder(root)) == uninterrupted[LONG]
    assert _siblings(root) == ["namespace_metadata.json", "rnd-wlk-v0"]


def test_force_over_a_killed_replacement_of_other_settings_starts_again(root, uninterrupted):
    _build(2, seed=5)
    assert _kill_when(MOMENTS["episode 9 moved in"][0], root, force=True, seed=7)
    _build(force=True)  # another run's partial: discarded, the dataset built afresh
    assert _tree(_folder(root)) == uninterrupted[N]
    assert _siblings(root) == ["namespace_metadata.json", "rnd-wlk-v0"]


@pytest.mark.parametrize("between", ["the renames", "the last rename and the deletion"])
def test_force_killed_during_the_swap_is_finished_by_the_next_run(root, tmp_path, monkeypatch, uninterrupted, between):
    """The two states a kill inside the swap's few microseconds leaves, made on disk as it leaves them."""
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "new"))
    _build()
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root))
    _build(2, seed=5)
    paths = st.DatasetFolder(root, ID)
    shutil.copytree(_folder(tmp_path / "new"), paths.partial)  # the complete replacement
    paths.path.rename(paths.old)
    if between != "the renames":
        paths.partial.rename(paths.path)
    with pytest.raises(ValueError, match=r"exists \(a complete one"):
        _build()  # any run on the id finishes the swap first
    assert _tree(_folder(root)) == uninterrupted[N] and minari.load_dataset(ID).total_episodes == N
    assert _siblings(root) == ["namespace_metadata.json", "rnd-wlk-v0"]


# ---- one-line errors -------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["--id", "mine/noversion"], "dataset id must be NAMESPACE/NAME-vN"),
        (["--id", "mine/" + "x" * 300 + "-v0"], "dataset id must be at most 200 characters"),
        (["--id", "a/x-v0"], "a namespace of 2 or more characters"),
        (["--id", "mine/x-v\uff10"], "dataset id must be NAMESPACE/NAME-vN"),
        (["--id", "mine/../x-v0"], "dataset id must be NAMESPACE/NAME-vN"),
        (["--id", "/abs/x-v0"], "dataset id must be NAMESPACE/NAME-vN"),
        (["--id", "mine/x-v0", "--version", "1"], "--version sets the default id's version"),
        (["--seed", "\uff13"], "argument --seed: must be an integer in ASCII digits, got '３'"),
        (["--seed", "1_0"], "argument --seed: must be an integer in ASCII digits"),
        (["--seed", "0"], "evaluation seed"),
        (["--version", "\uff11"], "argument --version: must be an integer in ASCII digits"),
        (["--episodes", "\uff12"], "argument --episodes: must be an integer in ASCII digits"),
        (["--resume", "--force"], "--resume and --force exclude each other"),
        (["--agent", "{m}:make"], "agent '{m}:make' in episode 0 of electroloc/ElectroLoc-v0/"),
        (["--agent", "{m}:make[where='reset']"], "its reset() raised RuntimeError: no reset today"),
        (["--agent", "{m}:make[where='nan']"], "in episode 0 of electroloc/ElectroLoc-v0/{m}_make_where_nan-v0: "),
        (["--agent", "{m}:make[where='nan']"], "{m}:make[where='nan']\" in episode 0 of"),
        (["--agent", "{m}:make[where='nan']"], "action must be finite"),
    ],
)
def test_bad_input_is_one_line_before_anything_is_written(root, capsys, user_module, argv, words):
    argv = [a.format(m=user_module) for a in argv]
    words = words.format(m=user_module)
    if "--agent" not in argv:
        argv = ["--agent", "rnd-wlk", *argv]
    if "--episodes" not in argv:
        argv = [*argv, "--episodes", "2"]
    assert _cli(["dataset", "--no-progress", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("electroloc dataset: error: ") and words in err[0], err
    assert not [p for p in root.rglob("*") if p.name == "data"]  # no dataset, not even a partial one


def _cli(argv: list[str]) -> int:
    """``electroloc`` in this process: its return code, or argparse's exit code."""
    try:
        return cli_main(argv)
    except SystemExit as exc:
        return int(exc.code)


@pytest.mark.parametrize(
    ("setting", "words"),
    [
        ("", "MINARI_DATASETS_PATH is set but empty"),
        ("   ", "MINARI_DATASETS_PATH is set but empty"),
        ("{tmp}/a-file", "is not a folder"),
        ("{tmp}/no/such/place", "does not exist and neither does its parent folder"),
        ("{tmp}/a-file/below", "does not exist and neither does its parent folder"),
        ("~/no-such-place-xyz/datasets", "(a leading ~ is not expanded: give the full path)"),
        ("/proc", "is not writable"),
    ],
)
def test_an_unusable_datasets_path_is_one_line(tmp_path, monkeypatch, capsys, setting, words):
    (tmp_path / "a-file").write_text("mine")
    monkeypatch.setenv("MINARI_DATASETS_PATH", setting.format(tmp=tmp_path))
    assert cli_main(["dataset", "--no-progress", "--agent", "rnd-wlk", "--episodes", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("electroloc dataset: error: ") and words in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a-file"] and (tmp_path / "a-file").read_text() == "mine"


@pytest.mark.parametrize(
    ("make", "words"),
    [
        (lambda tmp: tmp / ("d" * 300), "is 300 bytes long; at most 255 bytes are allowed"),
        (lambda tmp: (tmp / "dangling").symlink_to(tmp / "nowhere") or tmp / "dangling", "a dangling link or a loop"),
    ],
)
def test_a_datasets_path_the_output_rule_refuses_is_one_line(tmp_path, monkeypatch, capsys, make, words):
    """A name the file system refuses and a link that leads nowhere: named by the output folders' one rule."""
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(make(tmp_path)))
    assert cli_main(["dataset", "--no-progress", "--agent", "rnd-wlk", "--episodes", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0], err
    assert err[0].startswith("electroloc dataset: error: MINARI_DATASETS_PATH"), err
    assert not (tmp_path / "nowhere").exists()


@pytest.mark.parametrize("setting", ["rel", "./rel/", "sub/../rel"])
def test_a_relative_datasets_path_holds_the_same_dataset(tmp_path, monkeypatch, uninterrupted, setting):
    (tmp_path / "sub").mkdir()
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MINARI_DATASETS_PATH", setting)
    ds = _build()  # the episodes were written to a doubled relative path before
    assert ds.total_episodes == N and _tree(_folder(tmp_path / "rel")) == uninterrupted[N]
    assert minari.load_dataset(ID).total_episodes == N


def test_a_missing_datasets_folder_is_created_when_its_parent_exists(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "new"))
    assert cli_main(["dataset", "--no-progress", "--agent", "rnd-wlk", "--episodes", "1"]) == 0
    assert minari.load_dataset(ID).total_episodes == 1 and (tmp_path / "new" / "electroloc").is_dir()


def test_a_dataset_without_reference_scores_says_so(root, capsys):
    assert cli_main(["dataset", "--no-progress", "--agent", "rnd-wlk", "--episodes", "1"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("electroloc dataset: note: no reference scores"), err
    assert "--reference" in err[0] and "ref_min_score" not in minari.load_dataset(ID).storage.metadata
    argv = ["dataset", "--no-progress", "--agent", "rnd-wlk", "--episodes", "1", "--reference", str(REFERENCE)]
    assert cli_main([*argv, "--force"]) == 0
    assert capsys.readouterr().err.strip() == ""
    assert minari.load_dataset(ID).storage.metadata["ref_min_score"] is not None


def test_a_resume_without_reference_keeps_the_one_it_started_with(root):
    first = _build(2, reference=REFERENCE).storage.metadata
    _unpublish(root)
    ds = _build(3, resume=True)
    meta = ds.storage.metadata
    assert meta["ref_min_score"] is not None and meta["ref_min_score"] == first["ref_min_score"]
    assert meta["electroloc"]["reference"] == first["electroloc"]["reference"] is not None


def test_a_second_writer_of_the_same_id_is_refused(root, capsys):
    root.mkdir(parents=True)
    with st.DatasetFolder(root, ID).lock():
        assert cli_main(["dataset", "--no-progress", "--agent", "rnd-wlk", "--episodes", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is being written by another process" in err[0], err
    assert not _folder(root).exists()
    with FolderLock(root / ".electroloc-locks", "other--x-v0.lock", "busy"):  # another id's lock: no effect
        _build(1)


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"reference": 5}, "reference must be None or a benchmark folder or trials.jsonl path, got 5"),
        ({"reference": ""}, "reference must be None or a benchmark folder"),
        ({"trust_pickle": "yes"}, "trust_pickle must be True or False, got 'yes'"),
        ({"episodes": np.float64(2.0)}, r"episodes must be an integer in \[1, 1000000\], got np.float64\(2.0\)"),
        ({"seed": np.bool_(True)}, r"seed must be an integer in \[1, "),
    ],
)
def test_request_arguments_of_the_wrong_type_are_one_error(kwargs, words):
    with pytest.raises(ValueError, match=words):
        _request(**kwargs)


@pytest.mark.parametrize(
    ("options", "words"),
    [
        ({"resume": "yes"}, "resume must be True or False, got 'yes'"),
        ({"force": 1}, "force must be True or False, got 1"),
        ({"notify": 5}, "notify must be None or a callable taking one line, got 5"),
    ],
)
def test_build_options_of_the_wrong_type_are_one_error_before_anything_is_written(root, options, words):
    with pytest.raises(ValueError, match=words):
        build_dataset(_request(), progress=False, **options)
    assert not root.exists() or not [p for p in root.rglob("*") if p.name == "data"]


def test_numpy_integers_are_taken_as_the_integers_they_are(root, uninterrupted):
    request = _request(np.int64(N), seed=np.uint32(1), version=np.int8(0))
    assert (type(request.episodes), type(request.seed), type(request.version)) == (int, int, int)
    build_dataset(request, progress=False)
    assert _tree(_folder(root)) == uninterrupted[N]


def test_dataset_ids_are_checked_in_python_too():
    for bad in ("mine/noversion", "mine/" + "x" * 300 + "-v0", "x-v0", "mine/x.y-v0", "mine//x-v0", 3):
        with pytest.raises(ValueError, match="dataset id must") as info:
            st.check_dataset_id(bad)
        assert "\n" not in str(info.value)
    assert st.check_dataset_id("mine/sub/x_y-z-v12") == "mine/sub/x_y-z-v12"
    with pytest.raises(ValueError, match="dataset id must be NAMESPACE"):
        DatasetRequest("ElectroLoc-v0", "rnd-wlk", 1, dataset_id="mine/noversion")
