"""``modalab report``: the HTML report of the outputs of commands run one by one (or of a run folder)."""
from __future__ import annotations

import tempfile
from pathlib import Path

from modalab.app._cli_console import _print
from modalab.app.stages import ReportOptions, report
from modalab.app.stages._report import collect_outputs, model_files
from modalab.core.errors import PlanError

#: the sub-folders of a ``modalab run`` output folder
_RUN_STAGES = ("frf", "identify", "correlate", "update", "diagnose")


def cmd_report(a):
    folder = Path(a.folder)
    if not folder.is_dir():
        raise PlanError(f"report folder '{folder}' is not a folder; give the folder where frf, identify, correlate, "
                        "update and diagnose wrote their outputs (or a 'modalab run' output folder)")
    out = Path(a.output) if a.output else folder / "report"
    if any((folder / s).is_dir() and (folder / "manifest.json").is_file() for s in _RUN_STAGES):
        r = report(folder, out, ReportOptions(title=a.title))      # a 'modalab run' folder as it is
        _print(f"report of the run folder {folder}: {r.result}")
        return 0
    with tempfile.TemporaryDirectory(prefix="modalab-report-") as staging:
        found = collect_outputs(folder, staging)
        if not found:
            raise PlanError(f"'{folder}' holds no output of modalab identify, correlate, update or diagnose (their "
                            "JSON files and figures); run them with their outputs in this folder, or give that folder")
        r = report(staging, out, ReportOptions(title=a.title or folder.resolve().name,
                                               model_files=model_files(folder, found)))
    for stage, srcs in found.items():
        _print(f"{stage}: {', '.join(srcs)}")
    _print(f"wrote {r.result}")
    return 0


def register(sub):
    s = sub.add_parser("report", help="one self-contained HTML report from the outputs of the commands in a folder")
    s.add_argument("folder", help="folder holding the outputs of identify, correlate, update, diagnose (their JSON "
                                  "and figures, in it or one sub-folder down), or a 'modalab run' output folder")
    s.add_argument("-o", "--output", help="folder for report.html and summary.json (default: FOLDER/report)")
    s.add_argument("--title", help="the report's title (default: the folder's name)")
    s.set_defaults(func=cmd_report)
