"""What a session shows and reports: the observer and scripted prompter interfaces, the per-point and
session summaries (``summary.json``, the table) and the input-range suggestion.

Split from :mod:`acquisition.session` (which re-exports every public name here).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable

from modalab.core.errors import PlanError
from modalab.core.frf import FRF
from modalab.core.records import TimeRecord

__all__ = ["SessionObserver", "ScriptedPrompter", "PointSummary", "SessionSummary", "suggest_range",
           "STANDARD_RANGES"]

#: input ranges offered by :func:`suggest_range` (engineering units: N or m/s²)
STANDARD_RANGES = (1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000, 20000, 50000)


def suggest_range(peak: float, current: float) -> float | None:
    """A standard range when the peak uses the current one badly (above 90 % or below 5 %), else None.

    The suggestion is the smallest of :data:`STANDARD_RANGES` at least twice the peak.
    """
    if not (peak > 0 and math.isfinite(peak)):
        return None
    if 0.05 * current <= peak <= 0.9 * current:
        return None
    for r in STANDARD_RANGES:
        if r >= 2 * peak:
            return float(r)
    return float(STANDARD_RANGES[-1])


class SessionObserver:
    """Receives what a person would look at.  The CLI prints and plots; tests record.  All methods optional."""

    def point_started(self, index: int, point: str, n_points: int) -> None: ...

    def hit(self, index: int, point: str, rec: TimeRecord, report, running: FRF | None) -> None: ...

    def decided(self, index: int, point: str, hit_id: int | None, decision: str, reasons: list) -> None: ...

    def point_finished(self, index: int, point: str, summary: "PointSummary") -> None: ...

    def message(self, text: str) -> None: ...


class ScriptedPrompter:
    """Answers from a sequence (tests, batch runs): ``ScriptedPrompter('aarasb')``; ``q`` once exhausted."""

    def __init__(self, answers: Iterable[str]):
        self._it = iter(answers)
        self.asked: list[str] = []

    def __call__(self, prompt: str, choices: str) -> str:
        self.asked.append(prompt)
        try:
            a = next(self._it)
        except StopIteration:
            return "q"
        if a not in choices:
            raise PlanError(f"scripted answer {a!r} is not one of {choices!r} (prompt: {prompt!r}); fix the script")
        return a


@dataclass
class PointSummary:
    """What happened at one point: accepted hits, rejected hits with reasons, warnings, mean coherence."""

    point: str
    accepted: int = 0
    rejected: list = field(default_factory=list)     # reasons per rejected hit
    mean_coherence: float = float("nan")
    channel_coherence: dict = field(default_factory=dict)
    warnings: dict = field(default_factory=dict)     # warning -> count
    skipped: str = ""
    done: bool = False
    lost: int = 0                                    # accepted/candidate hits whose raw file was found damaged

    @property
    def taken(self) -> int:
        """Hits recorded at this point (accepted + rejected)."""
        return self.accepted + len(self.rejected)

    @property
    def rejected_reasons(self) -> dict:
        reasons: dict[str, int] = {}
        for r in self.rejected:
            for x in (r or ["rejected"]):
                reasons[x] = reasons.get(x, 0) + 1
        return reasons

    def to_dict(self) -> dict:
        nan = math.isnan(self.mean_coherence)
        return {"point": self.point, "taken": self.taken, "accepted": self.accepted, "rejected": len(self.rejected),
                "rejected_reasons": self.rejected_reasons, "warnings": dict(self.warnings),
                "mean_coherence": None if nan else round(self.mean_coherence, 4),
                "channel_coherence": {k: round(v, 4) for k, v in self.channel_coherence.items()},
                "skipped": self.skipped, "done": self.done, "lost": self.lost}


@dataclass
class SessionSummary:
    points: list
    complete: bool
    range_suggestions: dict = field(default_factory=dict)
    discarded: list = field(default_factory=list)
    stopped: str = ""
    resume: list = field(default_factory=list)       # what resuming recovered (AcquisitionSession._recovered)
    n_averages: int = 0                               # the plan's averages per point

    def to_dict(self) -> dict:
        return {"complete": self.complete, "stopped": self.stopped, "points": [p.to_dict() for p in self.points],
                "range_suggestions": self.range_suggestions, "discarded_on_resume": self.discarded,
                "resume": self.resume}

    def table(self) -> str:
        lines = [f"{'point':>8} {'taken':>5} {'acc':>4} {'rej':>4} {'coh':>6}  why rejected / warnings"]
        for p in self.points:
            d = p.to_dict()
            why = ", ".join(f"{k} x{v}" for k, v in d["rejected_reasons"].items())
            warn = ", ".join(f"{k} x{v}" for k, v in d["warnings"].items())
            if warn:
                why = f"{why}; warnings: {warn}" if why else f"warnings: {warn}"
            if p.lost:
                why = f"LOST {p.lost} hit(s) (raw file damaged)" + (f"; {why}" if why else "")
            if p.skipped:
                why = f"SKIPPED: {p.skipped}" + (f"; {why}" if why else "")
            elif not p.done and p.lost:
                why = f"re-opened, {p.accepted} of {self.n_averages} hits; {why}"
            elif not p.done:
                why = "not measured yet" + (f"; {why}" if why else "")
            coh = "" if d["mean_coherence"] is None else f"{d['mean_coherence']:.3f}"
            lines.append(f"{p.point:>8} {p.taken:>5} {p.accepted:>4} {len(p.rejected):>4} {coh:>6}  {why}")
        return "\n".join(lines)
