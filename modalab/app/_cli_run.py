"""``modalab run PROJECT.toml``: the whole chain with per-stage progress (registered by :mod:`modalab.app.cli`)."""
from __future__ import annotations

import json
from pathlib import Path

from modalab.app.project import STAGES
from modalab.app.run import run_project


class _StageProgress:
    """Stage progress of ``modalab run``/``demo``: on a terminal a bar over the stages with the running stage's
    latest message; otherwise one line per stage with its time (``[3/7] identify  done in 3.1 s``)."""

    def __init__(self, quiet: bool = False, console=None):
        from rich.console import Console  # lazy: rich, only when drawing (start-up time)

        self.quiet = quiet
        self.console = console or Console(highlight=False)
        self.current = None
        self._bar = None
        self._task = None
        self._done = 0

    def _line(self, text, style=None):
        if not self.quiet:
            self.console.print(text, style=style, highlight=False)

    def _start_bar(self):
        if self._bar is None and not self.quiet and self.console.is_terminal:
            from rich.progress import (  # lazy: rich, only when drawing (start-up time)
                BarColumn, MofNCompleteColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn)

            self._bar = Progress(SpinnerColumn(), TextColumn("[bold]stages"), BarColumn(), MofNCompleteColumn(),
                                 TimeElapsedColumn(), TextColumn("{task.description}"), console=self.console,
                                 transient=True)
            self._bar.start()
            self._task = self._bar.add_task("", total=len(STAGES))

    def __call__(self, stage, event, text):
        n = f"[{STAGES.index(stage) + 1}/{len(STAGES)}] {stage:<9}"
        self._start_bar()
        if event == "start":
            self.current = stage
            if self._bar:
                self._bar.update(self._task, description=f"{stage} running")
        elif event == "info":
            if self._bar:
                self._bar.update(self._task, description=f"{stage}: {text}")
        elif event in ("skip", "done"):
            self.current = None
            self._done += 1
            if self._bar:
                self._bar.update(self._task, completed=self._done, description="")
            if event == "skip":
                self._line(f"{n} up to date (skipped)", "dim")
            else:
                self._line(f"{n} done in {text}", "green")

    def close(self):
        if self._bar:
            self._bar.stop()
            self._bar = None


def run_with_progress(run, again: str, *, quiet: bool = False) -> int:
    """Call ``run(progress)`` (a :func:`modalab.app.run.run_project`-like call) with stage progress, print what it did
    and, last, the report's path; on Ctrl-C say what is kept and how to continue (``again``: the command)."""
    prog = _StageProgress(quiet=quiet)
    try:
        res = run(prog)
    except KeyboardInterrupt:
        prog.close()
        where = f" during the {prog.current} stage" if prog.current else ""
        print(f"interrupted{where}. Completed stages are kept (manifest.json) and an interrupted acquisition keeps "
              f"every accepted hit. Continue with: {again}", flush=True)
        return 130
    finally:
        prog.close()
    ran = [s for s, v in res.status.items() if v == "ran"]
    skipped = [s for s, v in res.status.items() if v == "skipped"]
    print(f"ran: {', '.join(ran) or 'nothing'}; up to date: {', '.join(skipped) or 'nothing'}", flush=True)
    d = res.summaries.get("diagnose")
    if d:
        print(f"diagnosis: {d.get('statement')}", flush=True)
    summary = Path(res.report).with_name("summary.json")
    if summary.is_file():
        s = json.loads(summary.read_text())
        if s.get("simulated"):
            print("data: simulated (backend sim: the simulated lab, not hardware)", flush=True)
        if s.get("model_to_use"):
            print(f"model to use: {Path(res.out_dir) / s['model_to_use']['file']}", flush=True)
    print(f"manifest: {Path(res.out_dir) / 'manifest.json'}", flush=True)
    if res.report.is_file():
        print(f"report: {res.report}", flush=True)
    return 0


def cmd_run(a):

    again = f"modalab run {a.project} -o {a.output}" + (f" --backend {a.backend}" if a.backend else "")
    return run_with_progress(lambda progress: run_project(a.project, a.output, backend=a.backend,
                                                          from_stage=a.from_stage, until_stage=a.until_stage,
                                                          progress=progress, force=a.force), again, quiet=a.quiet)


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
