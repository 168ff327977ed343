"""Run a check in a fresh Python process, for what depends on the process's state.

``modalab.core.parallel.fork_map`` computes serially while other threads run in the calling process (a fork
copies the calling thread alone).  A pytest worker may hold threads another test left running (CI's did;
which test left them was not traced), so a test that must see the calls go to forked workers
runs its check with :func:`run_fresh`: ``python -c`` in a new interpreter, the repository on its path, the
check's exit status and its output the test's.
"""
from __future__ import annotations

import logging
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def run_fresh(module: str, function: str, timeout: float = 600.0) -> str:
    """Call ``module.function()`` in a new interpreter; fail the test with its output if it raises."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    code = f"import importlib; importlib.import_module({module!r}).{function}()"
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=timeout)
    if proc.returncode:
        pytest.fail(f"{module}.{function} in a fresh process exited {proc.returncode}:\n"
                    f"{proc.stdout[-3000:]}\n{proc.stderr[-6000:]}", pytrace=False)
    return proc.stdout


def workers_of(records) -> set[int]:
    """The processes other than this one that made these log records."""
    return {r.process for r in records} - {os.getpid()}


class Keep(list):
    """A logging handler that keeps the records it is passed (``Keep.handler``)."""

    def __init__(self):
        super().__init__()
        self.handler = logging.Handler(logging.DEBUG)
        self.handler.emit = self.append
