"""The impact-test session: arm, wait for a hit, check it, accept or reject, never lose it.

For every roving point of the plan the session configures the backend, arms
it (and only then fires the automatic hammer when one is configured), waits
for the triggered record, runs the quality checks of :mod:`acquisition.checks`
(double hit, overload, weak or missing trigger, response not decayed) plus a
dead-channel check, updates the point's running average
(:class:`acquisition.spectral.SpectralAverager`) and shows the force, its
spectrum and the running FRF/coherence through an *observer*.  Then it decides:

* ``mode='auto'`` (``--auto``): hits with a *rejecting* flag (:data:`REJECT_FLAGS`:
  double hits, overloads, weak or missing triggers, force before the pulse) are
  rejected; valid hits are stored as candidates until ``max_hits`` (M) of them
  exist, and the best ``averages`` (N) by mean coherence over the analysis band
  are kept (greedy leave-one-out).
* ``mode='interactive'``: a key per choice from the prompter — ``a`` accept,
  ``r`` reject and repeat, ``s`` skip the point, ``b`` back to the previous
  point (its hits are superseded and it is measured again), ``q`` quit (resume
  later).  After a timeout: ``w`` wait again, ``s`` skip, ``q`` quit.

Warnings (:data:`WARN_FLAGS`: response not decayed — the exponential window
handles it —, a structure still moving before the trigger, a dead channel)
never reject a hit; they are counted in the per-point summary.  After each
point every response channel's mean coherence is checked (a noisy or dead
sensor shows as low coherence).

Before each new hit the session calls the backend's optional ``seed_hit(point index, hit number at the
point)``: the simulator then draws that hit from (seed, point, hit), so an interrupted and resumed
session records exactly the hits of an uninterrupted one.

Nothing is lost: every accepted (or candidate) hit is written and ``fsync``-ed
by :class:`acquisition.store.HitStore` *before the next arm*.  ``resume=True``
continues at the first unfinished point with all stored hits intact.  When the
device disappears (:class:`modalab.core.errors.DeviceLostError`) the session calls
the backend's ``reconnect()`` (if it has one), reconfigures and retries, at most
``max_reconnects`` times per session; after that it stops cleanly (summary
written, ``complete=False``) so the run continues with ``--resume``.
"""
from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Callable

import numpy as np

from modalab.core._output import write_json
from modalab.core.dof import Dof
from modalab.core.errors import DaqError, DaqTimeoutError, DeviceLostError, ModalabError, PlanError
from modalab.core.frf import FRF
from modalab.core.records import TimeRecord

from .plan import TestPlan
from .session_results import _averager, _band, best_subset, export_session, frf_from_hits, mean_coherence, session_frf
from .session_resume import _Recovery, _Stop
from .session_summary import (STANDARD_RANGES, PointSummary, ScriptedPrompter, SessionObserver, SessionSummary,
                              suggest_range)
from .store import HitStore
from .checks import check_hit

log = logging.getLogger(__name__)
__all__ = ["AcquisitionSession", "SessionObserver", "ScriptedPrompter", "PointSummary", "SessionSummary",
           "suggest_range", "frf_from_hits", "session_frf", "export_session", "mean_coherence", "best_subset",
           "REJECT_FLAGS", "WARN_FLAGS", "STANDARD_RANGES"]

#: flags of :func:`acquisition.checks.check_hit` that reject a hit in auto mode (and warn interactively)
REJECT_FLAGS = ("double_hit", "double_hit_spectral", "overload", "weak_trigger", "missing_trigger",
                "pretrigger_force")
#: flags that are reported but never reject a hit
WARN_FLAGS = ("not_decayed", "pretrigger_response", "dead_channel")
#: a response whose peak is below this multiple of its pretrigger RMS reads only noise
DEAD_PEAK_RATIO = 8.0
#: a response channel whose mean coherence over the band is below this is reported
LOW_COHERENCE = 0.8


# ---------------------------------------------------------------------------- checks glue
def _dead_channels(rec: TimeRecord) -> list[int]:
    """Response channels whose peak is within the noise of their own pretrigger (a dead sensor or cable)."""
    ti = rec.trigger_index
    out = []
    if ti < 16:
        return out
    for i in rec.response_channels:
        x = rec.data[i]
        rms = float(np.sqrt(np.mean(x[:ti] ** 2)))
        if float(np.abs(x).max()) < DEAD_PEAK_RATIO * rms or rms == 0.0 and not np.any(x):
            out.append(i)
    return out


# ---------------------------------------------------------------------------- the session

def backend_kind(backend) -> str:
    """What a DAQ backend is, for the record: its ``kind`` ('sim' for the simulated lab, 'nidaqmx' for NI
    hardware), else its class name (a test double or a third-party backend)."""
    return str(getattr(backend, "kind", None) or type(backend).__name__)

class AcquisitionSession(_Recovery):
    """Run a test plan on a backend into a session directory.

    Parameters
    ----------
    plan : the validated :class:`~acquisition.plan.TestPlan`.
    backend : a :class:`~acquisition.backend.DaqBackend`.
    out_dir : session directory (created; must be new unless ``resume``).
    mode : 'auto' or 'interactive'.
    prompter : ``callable(prompt, choices) -> key`` for interactive mode (the terminal or a
        :class:`ScriptedPrompter`).
    hammer : optional :class:`~acquisition.instruments.AutoHammer`: the DAQ is armed first, then the hammer
        is armed and fired with ``plan.hammer['force_n']``.
    observer : :class:`SessionObserver`.
    resume : continue the session stored in ``out_dir``.
    max_timeouts : consecutive 'no hit' timeouts before a point is skipped in auto mode.
    waits_per_arm : timeouts on one arm before the DAQ is re-armed (a real task stays armed; an injected
        'trigger never comes' fault needs a new arm).
    max_attempts_factor : auto mode gives up on a point after this many × ``max_hits`` hits (keeping the best
        ``averages`` when enough were valid, else skipping the point).
    max_reconnects : device-lost recoveries (``backend.reconnect()``) per session before it stops cleanly.
    check_config : :class:`~acquisition.checks.HitCheckConfig` thresholds (default ones).
    """

    def __init__(self, plan: TestPlan, backend, out_dir, *, mode: str = "auto", prompter: Callable | None = None,
                 hammer=None, observer: SessionObserver | None = None, resume: bool = False,
                 max_timeouts: int = 6, waits_per_arm: int = 2, max_attempts_factor: int = 4,
                 max_reconnects: int = 2, check_config=None):
        if mode not in ("auto", "interactive"):
            raise PlanError(f"mode {mode!r}; expected 'auto' or 'interactive'")
        if mode == "interactive" and prompter is None:
            raise PlanError("interactive mode needs a prompter (the terminal or a ScriptedPrompter); or use --auto")
        self.plan = plan
        self.backend = backend
        self.out_dir = Path(out_dir)
        self.mode = mode
        self.prompter = prompter
        self.hammer = hammer
        self.observer = observer or SessionObserver()
        self.max_timeouts = int(max_timeouts)
        self.waits_per_arm = max(1, int(waits_per_arm))
        self.max_attempts = int(max_attempts_factor) * plan.max_hits
        self.max_reconnects = int(max_reconnects)
        self.check_config = check_config
        self.reconnects = 0
        #: which DAQ took the data: 'sim' (the simulated lab), 'nidaqmx' (NI hardware) or the backend's class name;
        #: in session.json, in every hit's metadata and in the exported UFF's ID lines
        self.backend_kind = backend_kind(backend)
        self.store = HitStore(self.out_dir, plan=plan.raw, resume=resume, backend=self.backend_kind)
        self.resume_report: list[str] = []
        if resume:
            self._check_same_plan()
            self.resume_report = self._recovered()
        self.peaks: dict[str, float] = {}
        self.stopped = ""
        self._armed = False
        self._point_dof: Dof | None = None

    # ------------------------------------------------------------------ backend
    def _configure(self, point: str) -> None:
        self.backend.configure(self.plan.channel_configs(point), self.plan.acq)
        role = "force" if self.plan.pattern == "hammer" else "response"
        self.backend.notify_point(Dof.parse(point), role)
        self._armed = False

    def _arm_and_fire(self) -> None:
        self.backend.arm()
        self._armed = True
        if self.hammer is not None:           # the DAQ is armed first, so the hit cannot come too early
            self.hammer.arm()
            self.hammer.fire(float(self.plan.hammer.get("force_n", 100.0)))

    def _hits_at(self, k: int) -> int:
        """Hits journalled at point ``k`` so far (any status): the number of the next hit there."""
        return sum(1 for ev in self.store.events if ev["event"] == "hit" and int(ev.get("point", -1)) == k)

    def _seed_hit(self, key) -> None:
        """Tell a backend that can (the simulator's ``seed_hit``) which hit comes next; hardware ignores it."""
        seed_hit = getattr(self.backend, "seed_hit", None)
        if seed_hit is not None:
            seed_hit(*key)

    def _acquire_one(self, point: str, timeouts: int) -> TimeRecord:
        if not self._armed or (timeouts and timeouts % self.waits_per_arm == 0):
            if self._armed:
                self.backend.abort()
            self._arm_and_fire()
        rec = self.backend.wait(self.plan.acq.timeout_s)
        self._armed = False
        return rec

    # ------------------------------------------------------------------ one hit
    def _note_peaks(self, rec: TimeRecord) -> None:
        for ch, x in zip(self.plan.channels, rec.data):
            self.peaks[ch.name] = max(self.peaks.get(ch.name, 0.0), float(np.max(np.abs(x))))

    def range_suggestions(self) -> dict:
        """Per channel whose range is used badly: ``{'peak', 'range', 'suggested'}`` (engineering units)."""
        out = {}
        for ch in self.plan.channels:
            s = suggest_range(self.peaks.get(ch.name, 0.0), ch.range)
            if s is not None:
                out[ch.name] = {"peak": round(self.peaks[ch.name], 4), "range": ch.range, "suggested": s}
        return out

    def _check(self, rec: TimeRecord):
        """Quality report and (rejecting reasons, warnings)."""

        report = check_hit(rec, self.check_config, ranges=[c.range for c in self.plan.channels],
                           trigger_level=self.plan.acq.trigger_level)
        reasons = [f for f in report.flags if f in REJECT_FLAGS]
        warns = [f for f in report.flags if f not in REJECT_FLAGS]
        for i in _dead_channels(rec):
            warns.append(f"dead_channel:{self.plan.channels[i].name}")
        return report, reasons, warns

    # ------------------------------------------------------------------ one point
    def _point_state(self, k: int):
        """(accepted hits, candidate hits, running average of both) stored for point ``k`` so far."""
        st = self.store.points().get(k)
        kept = {h: self.store.load(h) for h in (st.accepted if st else [])}
        cands = {h: self.store.load(h) for h in (st.candidates if st else [])}
        avg = _averager(self.plan)
        for r in list(kept.values()) + list(cands.values()):
            avg.add(r)
        return kept, cands, avg

    def _no_hit(self, k: int, point: str, timeouts: int, err: Exception) -> str | None:
        """After a timeout: 'skip' or 'quit' the point, or None to wait again."""
        self.observer.message(f"point {point}: no hit within {self.plan.acq.timeout_s:g} s ({err})")
        if self.mode == "auto" and timeouts >= self.max_timeouts:
            self.backend.abort()
            self._armed = False
            self.store.skip_point(k, f"no trigger in {timeouts} waits")
            return "skip"
        if self.mode == "interactive":
            a = self.prompter(f"No hit at {point}. [w]ait again, [s]kip point, [q]uit?", "wsq")
            if a == "s":
                self.backend.abort()
                self._armed = False
                self.store.skip_point(k, "skipped by the operator after no trigger")
                return "skip"
            if a == "q":
                return "quit"
        return None

    def _take_hit(self, k: int, point: str, rec: TimeRecord, avg):
        """Label and check a new hit, add it to the running average unless a flag rejects it, and show it.
        Returns (rejecting reasons, warnings, running band-limited FRF or None)."""
        rec.metadata = {**(rec.metadata or {}), "point": point, "point_index": k, "backend": self.backend_kind}
        rec.hit_id = self.store.next_hit_id            # the id the store will give it
        self._note_peaks(rec)
        report, reasons, warns = self._check(rec)
        running = None
        if not reasons:
            avg.add(rec)
        if avg.n_averages:
            running = _band(avg.frf(), self.plan)
        self.observer.hit(k, point, rec, report, running)
        return reasons, warns, running

    def _decide_auto(self, k: int, point: str, rec: TimeRecord, reasons: list, warns: list, cands: dict) -> None:
        """Auto mode: journal a flagged hit as rejected, any other as a candidate (the best are chosen later)."""
        extra = {"warnings": warns} if warns else None
        if reasons:
            hid = self.store.add(rec, point=k, status="rejected", reasons=reasons, extra=extra)
            self.observer.decided(k, point, hid, "rejected", reasons)
            return
        hid = self.store.add(rec, point=k, status="candidate", extra=extra)
        cands[hid] = rec
        self.observer.decided(k, point, hid, "candidate", warns)

    def _decide_interactive(self, k: int, point: str, rec: TimeRecord, reasons: list, warns: list, kept: dict,
                            avg, running) -> str | None:
        """Interactive mode: ask the operator; journal an accepted or rejected hit.  Returns 'skip', 'back' or
        'quit' to leave the point, None to go on."""
        plan = self.plan
        extra = {"warnings": warns} if warns else None
        flags = reasons + warns
        warn = f" WARNING: {', '.join(flags)}." if flags else ""
        coh = mean_coherence(running) if running is not None and avg.n_averages > 1 else float("nan")
        cs = "" if math.isnan(coh) else f" running mean coherence {coh:.3f}."
        a = self.prompter(f"Hit {len(kept) + 1}/{plan.averages} at {point}:{cs}{warn} "
                          "[a]ccept, [r]eject/repeat, [s]kip point, [b]ack, [q]uit?", "arsbq")
        if a == "a":
            if reasons:                       # the operator overrides a flag: it enters the average now
                avg.add(rec)
            hid = self.store.add(rec, point=k, status="accepted", reasons=reasons, extra=extra)
            kept[hid] = rec
            self.observer.decided(k, point, hid, "accepted", flags)
            return None
        if not reasons:
            avg.remove(rec.hit_id)
        if a == "r":
            hid = self.store.add(rec, point=k, status="rejected", reasons=reasons + ["operator"], extra=extra)
            self.observer.decided(k, point, hid, "rejected", reasons + ["operator"])
            return None
        if a == "s":
            self.store.skip_point(k, "skipped by the operator")
            return "skip"
        return "back" if a == "b" else "quit"

    def _run_point(self, k: int, point: str) -> str:
        """Measure one point; returns 'done', 'skip', 'back' or 'quit'."""
        plan = self.plan
        kept, cands, avg = self._point_state(k)
        try:
            self._configure(point)
        except DeviceLostError as e:
            self._device_lost(point, e)
        timeouts = attempts = 0
        seeded = None
        while True:
            if self.mode == "interactive" and len(kept) >= plan.averages:
                return "done"
            if self.mode == "auto" and len(cands) + len(kept) >= plan.max_hits:
                break
            if self.mode == "auto" and attempts >= self.max_attempts:     # the operator decides interactively
                if len(kept) + len(cands) >= plan.averages:
                    break
                self.store.skip_point(k, f"only {len(kept) + len(cands)} valid hits in {attempts} hits")
                return "skip"
            key = (k, self._hits_at(k))
            if key != seeded:                  # a new hit: a simulator draws it from (seed, point, hit)
                self._seed_hit(key)
                seeded = key
            try:
                rec = self._acquire_one(point, timeouts)
            except DeviceLostError as e:
                self._device_lost(point, e)
                timeouts = 0
                continue
            except DaqTimeoutError as e:
                timeouts += 1
                left = self._no_hit(k, point, timeouts, e)
                if left is not None:
                    return left
                continue
            attempts += 1
            timeouts = 0
            reasons, warns, running = self._take_hit(k, point, rec, avg)
            if self.mode == "auto":
                self._decide_auto(k, point, rec, reasons, warns, cands)
                continue
            left = self._decide_interactive(k, point, rec, reasons, warns, kept, avg, running)
            if left is not None:
                return left
        # auto: choose the best N of the candidates (kept hits stay)
        need = plan.averages - len(kept)
        keep = best_subset(cands, max(need, 0), plan, fixed=kept.values()) if need > 0 else []
        self.store.select(k, keep)
        return "done"

    # ------------------------------------------------------------------ summaries
    def point_summary(self, k: int, states=None) -> PointSummary:
        """Summary of point ``k`` from the journal (accepted, rejected with reasons, warnings, coherence)."""
        states = self.store.points() if states is None else states
        st = states.get(k)
        ps = PointSummary(point=self.plan.points[k])
        if st is None:
            return ps
        ps.accepted = len(st.accepted)
        ps.rejected = [r for _, r in st.rejected]
        ps.skipped = st.skipped
        ps.done = st.done
        ps.lost = len(st.lost)
        warns: dict[str, int] = {}
        for ev in self.store.events:
            if ev["event"] == "hit" and int(ev.get("point", -1)) == k and ev["hit"] in st.accepted:
                for w in ev.get("warnings", []):
                    warns[w] = warns.get(w, 0) + 1
        if len(st.accepted) >= 2:
            frf = frf_from_hits([self.store.load(h) for h in st.accepted], self.plan)
            ps.mean_coherence = mean_coherence(frf)
            per = mean_coherence(frf, per_response=True)
            resp_names = [c.name for c in self.plan.channels if c.role == "response"]
            ps.channel_coherence = {n: float(v) for n, v in zip(resp_names, per)}
            for n, v in ps.channel_coherence.items():
                if v < LOW_COHERENCE:
                    warns[f"low_coherence:{n}"] = 1
        ps.warnings = warns
        return ps

    def summary(self) -> SessionSummary:
        states = self.store.points()
        pts = [self.point_summary(k, states) for k in range(len(self.plan.points))]
        for k, p in enumerate(pts):       # done in the journal but short of averages (a lost hit): not finished
            p.done = self._point_finished(states.get(k))
        complete = all(p.done for p in pts)
        return SessionSummary(points=pts, complete=complete, range_suggestions=self.range_suggestions(),
                              discarded=list(self.store.discarded), stopped=self.stopped,
                              resume=list(self.resume_report), n_averages=self.plan.averages)

    # ------------------------------------------------------------------ run
    def run(self) -> SessionSummary:
        """Measure every unfinished point; returns the summary (also written to ``summary.json``, its one writer:
        schema ``modalab/app/schemas/session_summary.schema.json``, checked by the tests)."""
        plan = self.plan
        n = len(plan.points)
        k = 0
        suggested = False
        for line in self.resume_report:
            self.observer.message(f"on resume: {line}")
        try:
            while k < n:
                point = plan.points[k]
                st = self.store.points().get(k)
                if self._point_finished(st):
                    k += 1
                    continue
                self.observer.point_started(k, point, n)
                result = self._run_point(k, point)
                if result == "quit":
                    self.stopped = "stopped by the operator; continue later with --resume"
                    self.observer.message(self.stopped)
                    break
                if result == "back":
                    if k > 0:
                        self.store.reset_point(k - 1)
                        k -= 1
                    continue
                if result == "done":
                    self.store.point_done(k)
                self.observer.point_finished(k, point, self.point_summary(k))
                if not suggested and self.peaks:
                    suggested = True
                    for name, s in self.range_suggestions().items():
                        self.observer.message(f"range of {name}: peak {s['peak']:g} against range {s['range']:g}; "
                                              f"consider range {s['suggested']:g}")
                k += 1
        except _Stop as e:
            self.observer.message(str(e))
        finally:
            try:
                self.backend.abort()
            except (DaqError, ModalabError) as e:
                log.warning("abort failed: %s", e)
        summ = self.summary()
        write_json(self.out_dir / "summary.json", summ.to_dict())     # atomic: a crash leaves no half file
        return summ

    # ------------------------------------------------------------------ export
    def frf(self) -> FRF:
        """FRFs of all measured points; roving-hammer data reordered by reciprocity (accelerometers as references)."""
        return session_frf(self.store, self.plan)

    def export(self, path=None) -> Path:
        """Write geometry, raw records, H1 FRFs and coherence to one UFF file (default ``session.uff``)."""
        return export_session(self.store, self.plan, path or self.out_dir / "session.uff")
