"""``electroloc train`` / ``python -m electroloc_gym.train``: the front door to the rl-zoo3 path.

Builds the ``python -m rl_zoo3.train`` command of :func:`electroloc_gym.train.run.zoo_argv`, prints
it, runs it (or finds the finished run with the same command) and exports the chosen checkpoint with
``--out``. Everything else — hyper-parameters, run folders, checkpoints, resuming with
``--trained-agent`` — is rl-zoo3's; run its command directly for any option not listed here.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from collections.abc import Sequence
from typing import Any

from electroloc_gym.registry import PAPER_ENV_ID, plugin_modules, resolve_env_name
from electroloc_gym.train.run import ALGO_FILES, check_zoo_installed, train, zoo_argv
from electroloc_gym.utils.agentspec import parse_options
from electroloc_gym.utils.fileio import check_output_folder
from electroloc_gym.utils.runtime import add_threads_argument, pin_threads

EPILOG = """examples:
  electroloc train --algo ppo --env ElectroLoc-v0 --seed 3000 --out electroloc_gym/models/ppo-belief
  electroloc train --algo qrdqn --env ElectroLoc-v0 --seed 1 --timesteps 300000 --print-command
"""


class _Parser(argparse.ArgumentParser):
    """One-line usage errors (``electroloc train: error: …``, exit 2), as the other subcommands print."""

    def error(self, message: str) -> Any:
        self.exit(2, f"{self.prog}: error: {message}\n")


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status (2 with one line on stderr for a bad argument)."""
    p = _Parser(
        prog="electroloc train",
        description=__doc__,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--algo", required=True, choices=sorted(ALGO_FILES), help="rl-zoo3 algorithm")
    p.add_argument(
        "--env",
        default=PAPER_ENV_ID,
        help="env id (a section of the algorithm's file, or of --conf-file), or package.module:ENV_ID, an env "
        "your own module registers (a task of your own, electroloc_gym.tasks): imported like any module, it "
        "runs your code, here and in the rl-zoo3 run (--gym-packages)",
    )
    p.add_argument(
        "--conf-file",
        default=None,
        help="another hyper-parameter file in rl-zoo3's format (default: the algorithm's shipped file)",
    )
    p.add_argument("--seed", type=int, required=True, help="the run's seed")
    p.add_argument("--timesteps", type=int, default=None, help="env-step budget (default: the file's)")
    p.add_argument("--log-folder", default="logs", help="rl-zoo3's log folder (default logs)")
    p.add_argument("--out", default=None, help="export the chosen checkpoint to this policy folder")
    p.add_argument(
        "--env-kwargs",
        nargs="*",
        default=[],
        metavar="KEY=VALUE",
        help="replace the file's env_kwargs (rl-zoo3's rule)",
    )
    p.add_argument("--hyperparams", nargs="*", default=[], metavar="KEY=VALUE", help="override hyper-parameters")
    p.add_argument("--dummy", action="store_true", help="rl-zoo3's default DummyVecEnv instead of the native env")
    p.add_argument("--print-command", action="store_true", help="print the rl-zoo3 command and exit")
    add_threads_argument(p)
    a = p.parse_args(argv)
    try:
        for option, folder in (("--log-folder", a.log_folder), ("--out", a.out)):  # before training
            if folder is not None:
                check_output_folder(option, folder)
        env_id = resolve_env_name(a.env, "--env")  # MODULE:ENV_ID imports MODULE (registering ENV_ID)
        kw: dict[str, Any] = dict(
            threads=pin_threads(a.threads),
            conf_file=a.conf_file,
            gym_packages=plugin_modules(),
            timesteps=a.timesteps,
            log_folder=a.log_folder,
            native=not a.dummy,
            env_kwargs=parse_options(a.env_kwargs, "--env-kwargs"),
            hyperparams=parse_options(a.hyperparams, "--hyperparams"),
        )
        args = zoo_argv(a.algo, env_id, a.seed, **kw)
        if not a.print_command:
            check_zoo_installed()
        print(shlex.join(["python", *args]), flush=True)
        if a.print_command:
            return 0
        run = train(a.algo, env_id, a.seed, out=a.out, **kw)
    except (ValueError, ModuleNotFoundError) as exc:
        print(f"electroloc train: error: {exc}", file=sys.stderr)
        return 2
    print(f"run folder: {run}" + (f"; exported to {a.out}" if a.out else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
