"""The impact-test session: arm, wait for a hit, check it, accept or reject, never lose it.

For every roving point of the plan the session configures the backend, arms
it (then fires the automatic hammer when one is configured), waits for the
triggered record, runs the quality checks (double hit, overload, weak or
missing trigger, response not decayed) and shows the force, its spectrum and
the running FRF/coherence through an *observer*.  Then it decides:

* ``mode='auto'``: hits failing a check are rejected; valid hits are stored as
  candidates until ``max_hits`` (M) of them exist, and the best ``averages``
  (N) by coherence are kept (greedy leave-one-out on the mean coherence over
  the analysis band).
* ``mode='interactive'``: a key per choice from the prompter — ``a`` accept,
  ``r`` reject and repeat, ``s`` skip the point, ``b`` back to the previous
  point (its hits are superseded), ``q`` quit (resume later).

Every accepted (or candidate) hit is written and fsync-ed by
:class:`acquisition.store.HitStore` *before the next arm*.  ``resume=True``
continues at the first unfinished point with all stored hits intact.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from modalab.dof import Dof
from modalab.errors import DaqError, DaqTimeoutError, ModalabError, PlanError
from modalab.frf import FRF, concat
from modalab.records import TimeRecord

from .plan import TestPlan
from .store import HitStore

log = logging.getLogger(__name__)
__all__ = ["AcquisitionSession", "SessionObserver", "ScriptedPrompter", "PointSummary", "SessionSummary",
           "suggest_range", "frf_from_hits"]

STANDARD_RANGES = (1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000, 20000, 50000)


# ---------------------------------------------------------------------------- signal processing glue
def _windows(plan: TestPlan):
    from .windows import ExponentialWindow, ForceWindow

    fw = ForceWindow(fraction=plan.force_fraction, taper=plan.force_taper)
    ew = None
    if plan.exp_beta is not None:
        ew = ExponentialWindow(beta=plan.exp_beta)
    elif plan.exp_end_level > 0:
        ew = ExponentialWindow(end_level=plan.exp_end_level)
    return fw, ew


def frf_from_hits(records: list[TimeRecord], plan: TestPlan) -> FRF:
    """H1 FRF and coherence of a point's hits with the plan's windows, limited to the analysis band."""
    from .spectral import estimate_frf

    fw, ew = _windows(plan)
    frf = estimate_frf(records, estimator="H1", force_window=fw, exp_window=ew)
    return frf.band(0.0, plan.bandwidth_hz)


def _check(rec: TimeRecord, plan: TestPlan):
    from .checks import check_hit

    return check_hit(rec, ranges=[c.range for c in plan.channels], trigger_level=plan.acq.trigger_level)


def mean_coherence(frf: FRF) -> float:
    if frf.coherence is None:
        return float("nan")
    c = frf.coherence[..., frf.freq_hz > 0]
    return float(np.nanmean(c)) if c.size else float("nan")


def best_subset(records: list[TimeRecord], n_keep: int, plan: TestPlan) -> list[int]:
    """Indices of the ``n_keep`` hits whose average has the highest mean coherence (greedy leave-one-out)."""
    idx = list(range(len(records)))
    while len(idx) > max(n_keep, 1):
        if len(idx) == 1:
            break
        scores = []
        for k in idx:
            rest = [records[i] for i in idx if i != k]
            scores.append(mean_coherence(frf_from_hits(rest, plan)) if len(rest) > 1 else 0.0)
        idx.pop(int(np.nanargmax(scores)))
    return idx


def suggest_range(peak: float, current: float) -> float | None:
    """A standard range when the peak uses the current one badly (> 90 % or < 5 %), else None."""
    if peak <= 0 or not math.isfinite(peak):
        return None
    if 0.05 * current <= peak <= 0.9 * current:
        return None
    for r in STANDARD_RANGES:
        if r >= 2 * peak:
            return float(r)
    return float(STANDARD_RANGES[-1])


# ---------------------------------------------------------------------------- observers / prompters
class SessionObserver:
    """Receives what a person would look at.  The CLI prints and plots; tests record."""

    def point_started(self, index: int, point: str, n_points: int) -> None: ...

    def hit(self, index: int, point: str, rec: TimeRecord, report, running: FRF | None) -> None: ...

    def decided(self, index: int, point: str, hit_id: int | None, decision: str, reasons: list) -> None: ...

    def point_finished(self, index: int, point: str, summary: "PointSummary") -> None: ...

    def message(self, text: str) -> None: ...


class ScriptedPrompter:
    """Answers from a list (tests, batch runs): ``ScriptedPrompter('aarasb...')``."""

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
            raise PlanError(f"scripted answer {a!r} is not one of {choices!r}")
        return a


# ---------------------------------------------------------------------------- summaries
@dataclass
class PointSummary:
    point: str
    accepted: int = 0
    rejected: list = field(default_factory=list)   # reasons per rejected hit
    mean_coherence: float = float("nan")
    skipped: str = ""

    def to_dict(self) -> dict:
        reasons: dict[str, int] = {}
        for r in self.rejected:
            for x in (r or ["rejected"]):
                reasons[x] = reasons.get(x, 0) + 1
        return {"point": self.point, "accepted": self.accepted, "rejected": len(self.rejected),
                "rejected_reasons": reasons, "mean_coherence": None if math.isnan(self.mean_coherence)
                else round(self.mean_coherence, 4), "skipped": self.skipped}


@dataclass
class SessionSummary:
    points: list
    complete: bool
    range_suggestions: dict = field(default_factory=dict)
    discarded: list = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"complete": self.complete, "points": [p.to_dict() for p in self.points],
                "range_suggestions": self.range_suggestions, "discarded_on_resume": self.discarded}

    def table(self) -> str:
        lines = [f"{'point':>8} {'hits':>5} {'rej':>4} {'coh':>6}  why rejected / skipped"]
        for p in self.points:
            d = p.to_dict()
            why = ", ".join(f"{k} x{v}" for k, v in d["rejected_reasons"].items()) or ""
            if p.skipped:
                why = f"SKIPPED: {p.skipped}" + (f"; {why}" if why else "")
            coh = "" if d["mean_coherence"] is None else f"{d['mean_coherence']:.3f}"
            lines.append(f"{p.point:>8} {p.accepted:>5} {len(p.rejected):>4} {coh:>6}  {why}")
        return "\n".join(lines)


# ---------------------------------------------------------------------------- the session
class AcquisitionSession:
    """Run a test plan on a backend into a session directory.

    Parameters
    ----------
    plan : the validated :class:`~acquisition.plan.TestPlan`.
    backend : a :class:`~acquisition.backend.DaqBackend`.
    out_dir : session directory (created; must be new unless ``resume``).
    mode : 'auto' or 'interactive'.
    prompter : ``callable(prompt, choices) -> key`` for interactive mode.
    hammer : optional :class:`~acquisition.instruments.AutoHammer` (armed DAQ first, then fired).
    observer : :class:`SessionObserver`.
    max_timeouts : consecutive 'no hit' timeouts before a point is skipped in auto mode.
    """

    def __init__(self, plan: TestPlan, backend, out_dir, *, mode: str = "auto", prompter: Callable | None = None,
                 hammer=None, observer: SessionObserver | None = None, resume: bool = False,
                 max_timeouts: int = 3, max_attempts_factor: int = 4):
        if mode not in ("auto", "interactive"):
            raise PlanError(f"mode {mode!r}; expected 'auto' or 'interactive'")
        if mode == "interactive" and prompter is None:
            raise PlanError("interactive mode needs a prompter (the terminal or a ScriptedPrompter)")
        self.plan = plan
        self.backend = backend
        self.out_dir = Path(out_dir)
        self.mode = mode
        self.prompter = prompter
        self.hammer = hammer
        self.observer = observer or SessionObserver()
        self.max_timeouts = max_timeouts
        self.max_attempts = max_attempts_factor * plan.max_hits
        self.store = HitStore(self.out_dir, plan=plan.raw, resume=resume)
        self.peaks: dict[str, float] = {}

    # ------------------------------------------------------------------ one hit
    def _acquire_one(self, point: str):
        self.backend.arm()
        if self.hammer is not None:
            self.hammer.arm()
            self.hammer.fire(float(self.plan.hammer.get("force_n", 100.0)))
        return self.backend.wait(self.plan.acq.timeout_s)

    def _note_peaks(self, rec: TimeRecord):
        for ch, x in zip(self.plan.channels, rec.data):
            self.peaks[ch.name] = max(self.peaks.get(ch.name, 0.0), float(np.max(np.abs(x))))

    def range_suggestions(self) -> dict:
        out = {}
        for ch in self.plan.channels:
            s = suggest_range(self.peaks.get(ch.name, 0.0), ch.range)
            if s is not None:
                out[ch.name] = {"peak": round(self.peaks[ch.name], 4), "range": ch.range, "suggested": s}
        return out

    # ------------------------------------------------------------------ one point
    def _run_point(self, k: int, point: str) -> str:
        """Measure one point; returns 'done', 'skip', 'back' or 'quit'."""
        plan = self.plan
        st = self.store.points().get(k)
        kept = [self.store.load(h) for h in (st.accepted if st else [])]
        cands = [self.store.load(h) for h in (st.candidates if st else [])]
        cand_ids = list(st.candidates) if st else []
        self.backend.configure(plan.channel_configs(point), plan.acq)
        role = "force" if plan.pattern == "hammer" else "response"
        self.backend.notify_point(Dof.parse(point), role)
        timeouts = 0
        attempts = 0
        while True:
            if self.mode == "interactive" and len(kept) >= plan.averages:
                return "done"
            if self.mode == "auto" and len(cands) + len(kept) >= plan.max_hits:
                break
            if attempts >= self.max_attempts:
                if self.mode == "auto" and len(kept) + len(cands) >= plan.averages:
                    break
                self.store.skip_point(k, f"only {len(kept) + len(cands)} valid hits in {attempts} attempts")
                return "skip"
            try:
                rec = self._acquire_one(point)
            except DaqTimeoutError as e:
                timeouts += 1
                self.observer.message(f"point {point}: no hit within {plan.acq.timeout_s:g} s ({e})")
                if self.mode == "auto" and timeouts >= self.max_timeouts:
                    self.store.skip_point(k, f"no trigger in {timeouts} waits")
                    return "skip"
                if self.mode == "interactive":
                    a = self.prompter(f"No hit at {point}. [w]ait again, [s]kip point, [q]uit?", "wsq")
                    if a == "s":
                        self.store.skip_point(k, "skipped by operator after no trigger")
                        return "skip"
                    if a == "q":
                        return "quit"
                continue
            attempts += 1
            timeouts = 0
            rec.metadata.update({"point": point, "point_index": k})
            self._note_peaks(rec)
            report = _check(rec, plan)
            reasons = list(report.reasons)
            trial = kept + cands + ([rec] if report.ok else [])
            running = frf_from_hits(trial, plan) if trial else None
            self.observer.hit(k, point, rec, report, running)
            if self.mode == "auto":
                if not report.ok:
                    hid = self.store.add(rec, point=k, status="rejected", reasons=reasons)
                    self.observer.decided(k, point, hid, "rejected", reasons)
                    continue
                hid = self.store.add(rec, point=k, status="candidate")
                cands.append(rec)
                cand_ids.append(hid)
                self.observer.decided(k, point, hid, "candidate", [])
                continue
            # interactive
            warn = f" WARNING: {', '.join(reasons)}." if reasons else ""
            coh = mean_coherence(running) if running is not None else float("nan")
            a = self.prompter(f"Hit {len(kept) + 1}/{plan.averages} at {point}: mean coherence {coh:.3f}.{warn} "
                              "[a]ccept, [r]eject/repeat, [s]kip point, [b]ack, [q]uit?", "arsbq")
            if a == "a":
                hid = self.store.add(rec, point=k, status="accepted", reasons=reasons)
                kept.append(rec)
                self.observer.decided(k, point, hid, "accepted", reasons)
            elif a == "r":
                hid = self.store.add(rec, point=k, status="rejected", reasons=reasons + ["operator"])
                self.observer.decided(k, point, hid, "rejected", reasons + ["operator"])
            elif a == "s":
                self.store.skip_point(k, "skipped by operator")
                return "skip"
            elif a == "b":
                return "back"
            else:
                return "quit"
        # auto: choose the best N of the candidates (kept hits stay)
        need = plan.averages - len(kept)
        if need > 0 and cands:
            if len(cands) > need:
                keep_idx = best_subset(cands, need, plan)
            else:
                keep_idx = list(range(len(cands)))
            self.store.select(k, [cand_ids[i] for i in keep_idx])
        elif cands:
            self.store.select(k, [])
        return "done"

    # ------------------------------------------------------------------ run
    def summary(self) -> SessionSummary:
        states = self.store.points()
        pts = []
        for k, point in enumerate(self.plan.points):
            st = states.get(k)
            ps = PointSummary(point=point)
            if st:
                ps.accepted = len(st.accepted)
                ps.rejected = [r for _, r in st.rejected]
                ps.skipped = st.skipped
                if len(st.accepted) >= 2:
                    ps.mean_coherence = mean_coherence(frf_from_hits([self.store.load(h) for h in st.accepted],
                                                                     self.plan))
            pts.append(ps)
        complete = all(states.get(k) is not None and states[k].done for k in range(len(self.plan.points)))
        return SessionSummary(points=pts, complete=complete, range_suggestions=self.range_suggestions(),
                              discarded=list(self.store.discarded))

    def run(self) -> SessionSummary:
        plan = self.plan
        n = len(plan.points)
        k = 0
        try:
            while k < n:
                point = plan.points[k]
                st = self.store.points().get(k)
                if st is not None and st.done:
                    k += 1
                    continue
                self.observer.point_started(k, point, n)
                result = self._run_point(k, point)
                if result == "quit":
                    self.observer.message("session stopped; continue later with --resume")
                    break
                if result == "back":
                    if k > 0:
                        self.store.reset_point(k - 1)
                        k -= 1
                    continue
                if result == "done":
                    self.store.point_done(k)
                summary = self.summary().points[k]
                self.observer.point_finished(k, point, summary)
                if k == 0:
                    sugg = self.range_suggestions()
                    for name, s in sugg.items():
                        self.observer.message(f"range of {name}: peak {s['peak']:g} against range {s['range']:g}; "
                                              f"consider range {s['suggested']:g}")
                k += 1
        finally:
            try:
                self.backend.abort()
            except (DaqError, ModalabError) as e:  # pragma: no cover - best effort
                log.warning("abort failed: %s", e)
        summ = self.summary()
        (self.out_dir / "summary.json").write_text(__import__("json").dumps(summ.to_dict(), indent=1))
        return summ

    # ------------------------------------------------------------------ export
    def frf(self) -> FRF:
        """FRFs of all finished points; roving hammer data reordered by reciprocity (accelerometers as references)."""
        return session_frf(self.store, self.plan)

    def export(self, path=None) -> Path:
        """Write geometry, raw records, H1 FRFs and coherence to one UFF file (default ``session.uff``)."""
        return export_session(self.store, self.plan, path or self.out_dir / "session.uff")


def session_frf(store: HitStore, plan: TestPlan, *, reciprocity: bool = True) -> FRF:
    """FRF matrix of a session's accepted hits.

    Roving hammer: one column per hit point (responses = fixed accelerometers);
    with ``reciprocity`` the matrix is transposed so the accelerometers become
    the references and the hit points the responses (thesis section 5.3).
    Roving accelerometer: one row per roving point, the hammer as reference.
    """
    per_point = store.accepted_records()
    cols = []
    for k, point in enumerate(plan.points):
        recs = per_point.get(k)
        if not recs:
            continue
        cols.append(frf_from_hits(recs, plan))
    if not cols:
        raise PlanError(f"the session in {str(store.dir)!r} has no accepted hits yet; acquire first")
    if plan.pattern == "hammer":
        frf = concat(cols, axis="references")
        if reciprocity:
            from .reciprocity import reorder_by_reciprocity

            frf = reorder_by_reciprocity(frf)
    else:
        rov = plan.roving_channel
        parts = []
        for k, c in zip([k for k in range(len(plan.points)) if per_point.get(k)], cols):
            parts.append(c.select(responses=[plan.points[k]]))
        frf = concat(parts, axis="responses")
        del rov
    return frf


def export_session(store: HitStore, plan: TestPlan, path) -> Path:
    """One UFF with geometry (2411), raw records (58, func 1), FRFs (58, func 4) and coherence (func 6)."""
    from modalab import uff

    path = Path(path)
    if path.exists():
        path.unlink()
    first = True
    if plan.geometry:
        uff.write_geometry(path, plan.geometry, append=False)
        first = False
    recs = [r for rs in store.accepted_records().values() for r in rs]
    if recs:
        uff.write_records(path, recs, append=not first)
        first = False
    uff.write_frf(path, session_frf(store, plan), append=not first)
    return path
