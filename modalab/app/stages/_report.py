"""The report stage: the self-contained HTML report of a run folder."""
from __future__ import annotations

from modalab.app.stages._common import StageResult
from modalab.app.report import build_report


def report(run_dir, report_dir=None, *, project=None, title: str | None = None) -> StageResult:
    """The self-contained HTML report of a run folder and its ``summary.json`` (:mod:`modalab.app.report`)."""

    html, summary = build_report(run_dir, report_dir, project=project, title=title)
    return StageResult(html, (html, summary), {"report": str(html)})
