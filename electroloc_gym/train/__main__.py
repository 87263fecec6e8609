"""``electroloc train`` / ``python -m electroloc_gym.train``: the front door to the rl-zoo3 path.

Builds the ``python -m rl_zoo3.train`` command of :func:`electroloc_gym.train.run.zoo_argv`, prints
it, runs it (or finds the finished run with the same command) and exports the chosen checkpoint with
``--out``. Its options are the run's settings, declared once with the Python API's
(:data:`~electroloc_gym.train.settings.TRAIN_OPTIONS`), and ``--print-command``. Everything else —
hyper-parameters, run folders, checkpoints, resuming with ``--trained-agent`` — is rl-zoo3's; run its
command directly for any option not listed here.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from collections.abc import Sequence
from typing import Any

from electroloc_gym.options import add_options, pairs_value
from electroloc_gym.registry import resolve_env_name
from electroloc_gym.train.run import check_zoo_installed, train, zoo_argv
from electroloc_gym.train.settings import TRAIN_OPTIONS, check_train_settings
from electroloc_gym.utils.fileio import os_error_line
from electroloc_gym.utils.runtime import add_threads_argument, pin_threads

EPILOG = """examples:
  electroloc train --algo ppo --env ElectroLoc-v0 --seed 3000 --out electroloc_gym/models/ppo-belief
  electroloc train --algo qrdqn --env ElectroLoc-v0 --seed 1 --timesteps 300000 --print-command
"""


class _Parser(argparse.ArgumentParser):
    """One-line usage errors (``electroloc train: error: …``, exit 2), as the other subcommands print."""

    def error(self, message: str) -> Any:
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    """The command's parser: the run's settings (declared once, :data:`TRAIN_OPTIONS`), ``--print-command``
    and the process's ``--threads``.
    """
    p = _Parser(
        prog="electroloc train",
        description=__doc__,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_options(p, TRAIN_OPTIONS)
    p.add_argument("--print-command", action="store_true", help="print the rl-zoo3 command and exit")
    add_threads_argument(p)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status (2 with one line on stderr for a bad argument)."""
    a = build_parser().parse_args(argv)
    try:
        values = {o.name: getattr(a, o.name) for o in TRAIN_OPTIONS}
        for opt in TRAIN_OPTIONS:
            if opt.kind == "pairs":
                values[opt.name] = pairs_value(opt, values[opt.name])
        check_train_settings(values, lambda o: o.option)  # named by their flags, before training
        values["env_id"] = resolve_env_name(values["env_id"], "--env")  # MODULE:ENV_ID imports MODULE
        kw: dict[str, Any] = {k: v for k, v in values.items() if k not in ("algo", "env_id", "seed", "out")}
        kw["threads"] = pin_threads(a.threads)  # zoo_argv adds the MODULE:ENV_ID modules to --gym-packages
        args = zoo_argv(a.algo, values["env_id"], a.seed, **kw)
        if not a.print_command:
            check_zoo_installed()
        print(shlex.join(["python", *args]), flush=True)
        if a.print_command:
            return 0
        run = train(a.algo, values["env_id"], a.seed, out=a.out, **kw)
    except (ValueError, ModuleNotFoundError) as exc:
        print(f"electroloc train: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # the file system's refusal, in the words of every command (``python -m`` too)
        print(os_error_line("train", exc, a), file=sys.stderr)
        return 2
    print(f"run folder: {run}" + (f"; exported to {a.out}" if a.out else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
