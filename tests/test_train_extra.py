"""``electroloc train`` without rl-zoo3 (the ``train`` extra alone): one line naming the ``zoo`` extra, exit 2.

rl-zoo3 is made missing for the test by a ``None`` entry in ``sys.modules`` (what Python's import system reads as
"not importable"), not by uninstalling it; at the lowest versions it is missing for real.
"""

from __future__ import annotations

import sys

import pytest

HINT = 'electroloc train: error: training needs the zoo extra: pip install -c constraints.txt "electroloc-gym[zoo]"'


@pytest.fixture
def no_rl_zoo3(monkeypatch):
    monkeypatch.setitem(sys.modules, "rl_zoo3", None)


def test_train_names_the_zoo_extra_in_one_line(no_rl_zoo3, capsys, tmp_path) -> None:
    from electroloc_gym.cli import main

    logs = tmp_path / "logs"
    code = main(["train", "--algo", "ppo", "--seed", "1", "--log-folder", str(logs)])
    out, err = capsys.readouterr()
    assert code == 2
    assert err.strip().splitlines() == [f"{HINT} (missing: rl_zoo3)"]
    assert not out and not logs.exists()  # no command printed, nothing started or written


def test_the_python_call_raises_the_same_line(no_rl_zoo3, tmp_path) -> None:
    from electroloc_gym.train.run import ZOO_EXTRA_HINT, train

    with pytest.raises(ModuleNotFoundError, match="zoo extra") as info:
        train("ppo", "ElectroLoc-v0", 1, log_folder=tmp_path / "logs")
    assert str(info.value).startswith(ZOO_EXTRA_HINT) and info.value.name == "rl_zoo3"
    assert not (tmp_path / "logs").exists()


def test_the_command_is_still_printed_without_rl_zoo3(no_rl_zoo3, capsys) -> None:
    from electroloc_gym.cli import main

    assert main(["train", "--algo", "ppo", "--seed", "1", "--print-command"]) == 0
    assert capsys.readouterr().out.startswith("python -m rl_zoo3.train --algo ppo")
