"""The ``electroloc`` command run inside the test's process: its exit status, standard output and standard error,
as ``subprocess.run`` returns them.

A subprocess costs a test two to four seconds of imports (numpy, numba's cache, matplotlib, torch where the
command loads it); in-process, a refusal or a small run costs milliseconds. The console script itself, a real
process with its own interpreter, is covered by tests/test_cli.py's subprocess smoke tests; the tests that use
this runner check what a command does and says.
"""

from __future__ import annotations

import contextlib
import io
import subprocess

from electroloc_gym.cli import main


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    """``electroloc ARGS`` in this process (``electroloc_gym.cli.main``); argparse's exits give their status."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(list(args))
        except SystemExit as exc:  # argparse: --help (0) or a usage error (2)
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    return subprocess.CompletedProcess(["electroloc", *args], int(code or 0), out.getvalue(), err.getvalue())
