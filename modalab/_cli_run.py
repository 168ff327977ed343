"""``modalab run PROJECT.toml``: the whole chain with per-stage progress (registered by :mod:`modalab.cli`)."""
from __future__ import annotations

import time
from pathlib import Path

from .project import STAGES


class _StageProgress:
    """One line per stage (rich when available): started, skipped (up to date) or done in N s."""

    def __init__(self, quiet: bool = False):
        self.quiet = quiet
        self.console = None
        self._status = None
        self._t0 = {}
        if not quiet:
            try:
                from rich.console import Console

                self.console = Console(highlight=False)
            except ImportError:  # pragma: no cover
                self.console = None

    def _print(self, text, style=""):
        if self.quiet:
            return
        if self.console is not None:
            self.console.print(text, style=style or None)
        else:  # pragma: no cover
            print(text, flush=True)

    def __call__(self, stage, event, text):
        n = f"[{STAGES.index(stage) + 1}/{len(STAGES)}] {stage:<9}"
        if event == "start":
            self._t0[stage] = time.perf_counter()
            if self.console is not None and not self.quiet:
                self._stop()
                self._status = self.console.status(f"{n} running ...")
                self._status.start()
            else:
                self._print(f"{n} running ...")
        elif event == "info":
            if self._status is not None:
                self._status.update(f"{n} {text}")
        elif event == "skip":
            self._stop()
            self._print(f"{n} up to date (skipped)", "dim")
        elif event == "done":
            self._stop()
            self._print(f"{n} done in {text}", "green")

    def _stop(self):
        if self._status is not None:
            self._status.stop()
            self._status = None

    def close(self):
        self._stop()


def cmd_run(a):
    from .run import run_project

    prog = _StageProgress(quiet=a.quiet)
    try:
        res = run_project(a.project, a.output, backend=a.backend, from_stage=a.from_stage, until_stage=a.until_stage,
                          progress=prog, force=a.force)
    finally:
        prog.close()
    ran = [s for s, v in res.status.items() if v == "ran"]
    skipped = [s for s, v in res.status.items() if v == "skipped"]
    print(f"ran: {', '.join(ran) or 'nothing'}; up to date: {', '.join(skipped) or 'nothing'}", flush=True)
    d = res.summaries.get("diagnose")
    if d:
        print(f"diagnosis: {d.get('statement')}", flush=True)
    if res.report.is_file():
        print(f"report: {res.report}", flush=True)
    print(f"manifest: {Path(res.out_dir) / 'manifest.json'}", flush=True)
    return 0


def register(subparsers):
    s = subparsers.add_parser("run", help="the whole chain from a project file: acquire, FRFs, identify, correlate, "
                                          "update, diagnose, report")
    s.add_argument("project", help="project file (TOML: test plan, FE model as bulk data, parameters, options)")
    s.add_argument("-o", "--output", default="modalab-run", help="output folder (default: modalab-run); a rerun "
                   "into the same folder skips the stages whose inputs and options did not change")
    s.add_argument("--backend", choices=["sim", "nidaqmx"], help="DAQ backend (default: the project's, usually sim)")
    s.add_argument("--from", dest="from_stage", choices=STAGES, help="rerun this stage and the stages that depend on it, even if up to date")
    s.add_argument("--until", dest="until_stage", choices=STAGES, help="stop after this stage")
    s.add_argument("--force", action="store_true", help="rerun every stage")
    s.add_argument("--quiet", action="store_true", help="no progress output")
    s.set_defaults(func=cmd_run)
