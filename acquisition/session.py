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
device disappears (:class:`modalab.errors.DeviceLostError`) the session calls
the backend's ``reconnect()`` (if it has one), reconfigures and retries, at most
``max_reconnects`` times per session; after that it stops cleanly (summary
written, ``complete=False``) so the run continues with ``--resume``.
"""
from __future__ import annotations

import json
import logging
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from modalab.dof import Dof
from modalab.errors import DaqError, DaqTimeoutError, DeviceLostError, ModalabError, PlanError
from modalab.frf import FRF, concat
from modalab.records import TimeRecord

from .plan import TestPlan
from .store import HitStore

log = logging.getLogger(__name__)
__all__ = ["AcquisitionSession", "SessionObserver", "ScriptedPrompter", "PointSummary", "SessionSummary",
           "suggest_range", "frf_from_hits", "session_frf", "export_session", "mean_coherence", "best_subset",
           "REJECT_FLAGS", "WARN_FLAGS", "STANDARD_RANGES"]

#: flags of :func:`acquisition.checks.check_hit` that reject a hit in auto mode (and warn interactively)
REJECT_FLAGS = ("double_hit", "double_hit_spectral", "overload", "weak_trigger", "missing_trigger",
                "pretrigger_force")
#: flags that are reported but never reject a hit
WARN_FLAGS = ("not_decayed", "pretrigger_response", "dead_channel")
#: input ranges offered by :func:`suggest_range` (engineering units: N or m/s²)
STANDARD_RANGES = (1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000, 20000, 50000)
#: a response whose peak is below this multiple of its pretrigger RMS reads only noise
DEAD_PEAK_RATIO = 8.0
#: a response channel whose mean coherence over the band is below this is reported
LOW_COHERENCE = 0.8


# ---------------------------------------------------------------------------- signal processing glue
def _windows(plan: TestPlan):
    from .windows import ForceWindow

    return ForceWindow(fraction=plan.force_fraction, taper=plan.force_taper), plan.exp_window()


def _averager(plan: TestPlan):
    from .spectral import SpectralAverager

    fw, ew = _windows(plan)
    return SpectralAverager(estimator="H1", force_window=fw, exp_window=ew)


def _band(frf: FRF, plan: TestPlan) -> FRF:
    return frf.band(0.0, plan.bandwidth_hz)


def frf_from_hits(records: list[TimeRecord], plan: TestPlan) -> FRF:
    """H1 FRF and coherence of one point's hits with the plan's windows, limited to the analysis band.

    The exponential window's decay rate is in ``metadata['exp_window_beta']`` (1/s): the FRF is the
    structure's at ``s = iω + β``.
    """
    avg = _averager(plan)
    for k, r in enumerate(records):
        if r.hit_id in avg.hit_ids or r.hit_id is None:
            r = TimeRecord(sample_rate_hz=r.sample_rate_hz, data=r.data, dofs=r.dofs, roles=r.roles, units=r.units,
                           sensitivity=r.sensitivity, trigger_index=r.trigger_index, overload=r.overload,
                           hit_id=-(k + 1), metadata=r.metadata)
        avg.add(r)
    return _band(avg.frf(), plan)


def mean_coherence(frf: FRF, per_response: bool = False):
    """Mean ordinary coherence over the lines above 0 Hz (per response row with ``per_response``)."""
    if frf.coherence is None:
        return np.full(frf.n_out, np.nan) if per_response else float("nan")
    c = frf.coherence[..., frf.freq_hz > 0]
    if per_response:
        return np.array([float(np.nanmean(c[i])) if c[i].size else np.nan for i in range(c.shape[0])])
    return float(np.nanmean(c)) if c.size else float("nan")


def best_subset(records: dict, n_keep: int, plan: TestPlan, fixed: Iterable[TimeRecord] = ()) -> list[int]:
    """Hit ids of the ``n_keep`` candidates whose average (with the ``fixed`` hits) has the highest mean coherence.

    Greedy leave-one-out: drop, one at a time, the candidate whose removal raises the mean coherence
    most.  ``records`` maps hit id → record.  Uses one running average (remove/add), so each trial
    costs no FFT.
    """
    ids = list(records)
    if len(ids) <= n_keep:
        return ids
    avg = _averager(plan)
    for r in fixed:
        avg.add(r)
    for h in ids:
        avg.add(records[h])
    while len(ids) > max(n_keep, 1):
        scores = []
        for h in ids:
            avg.remove(h)
            scores.append(mean_coherence(_band(avg.frf(), plan)) if avg.n_averages > 1 else 0.0)
            avg.add(records[h])
        drop = ids[int(np.nanargmax(scores))]
        avg.remove(drop)
        ids.remove(drop)
    return ids


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


# ---------------------------------------------------------------------------- observers / prompters
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


# ---------------------------------------------------------------------------- summaries
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


# ---------------------------------------------------------------------------- the session
class _Stop(Exception):
    """Leave the session cleanly (device gone for good)."""


class AcquisitionSession:
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
        self.store = HitStore(self.out_dir, plan=plan.raw, resume=resume)
        self.resume_report: list[str] = []
        if resume:
            self._check_same_plan()
            self.resume_report = self._recovered()
        self.peaks: dict[str, float] = {}
        self.stopped = ""
        self._armed = False
        self._point_dof: Dof | None = None

    #: plan sections that must not change when a session is resumed ([sim], [hammer], [geometry] may)
    RESUME_SECTIONS = ("acquisition", "trigger", "windows", "channels", "roving")

    def _check_same_plan(self) -> None:
        stored = self.store.plan        # from session.json, or rebuilt from the journal (acquisition.store)
        if not stored:
            return
        for key in self.RESUME_SECTIONS:
            now = json.loads(json.dumps(self.plan.raw.get(key), default=str))
            if stored.get(key) != now:
                raise PlanError(f"the plan's [{key}] differs from the one the session in {str(self.out_dir)!r} was "
                                f"started with ({stored.get(key)!r} then, {now!r} now); resume with the original plan "
                                "or start a new session directory")

    def _point_finished(self, st) -> bool:
        """A point is finished when skipped, or done with all its averages (never when a hit was lost since)."""
        return st is not None and st.done and (bool(st.skipped) or len(st.accepted) >= self.plan.averages)

    def _recovered(self) -> list[str]:
        """What a resumed session found: points complete, hits kept, hits discarded and why (one line each)."""
        states = self.store.points()
        n = len(self.plan.points)
        done = sum(self._point_finished(states.get(k)) for k in range(n))
        acc = sum(len(states[k].accepted) for k in range(n) if k in states)
        cand = sum(len(states[k].candidates) for k in range(n) if k in states)
        rej = sum(len(states[k].rejected) for k in range(n) if k in states)
        lines = [f"recovered {done} of {n} points complete, {acc + cand} hits kept ({acc} accepted, {cand} awaiting "
                 f"selection), {rej} rejected before"]
        lines += list(self.store.discarded)
        for k in range(n):
            st = states.get(k)
            if st is not None and st.reopened:
                lines.append(f"point {self.plan.points[k]} re-opened: {len(st.accepted)} of {self.plan.averages} "
                             "accepted hits left after a lost hit; it is measured again")
        return lines

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

    def _device_lost(self, point: str, err: Exception) -> None:
        """Reconnect and reconfigure, or raise _Stop."""
        self._armed = False
        self.observer.message(f"point {point}: the DAQ was lost ({err})")
        rc = getattr(self.backend, "reconnect", None)
        while self.reconnects < self.max_reconnects and rc is not None:
            self.reconnects += 1
            try:
                rc()
                self._configure(point)
                self.observer.message(f"reconnected to the DAQ (attempt {self.reconnects}); repeating the hit")
                return
            except (DaqError, ModalabError) as e:
                self.observer.message(f"reconnect attempt {self.reconnects} failed: {e}")
        self.stopped = (f"the DAQ was lost at point {point} ({err}); reconnect it and continue with --resume "
                        "(every accepted hit is stored)")
        raise _Stop(self.stopped)

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
        from .checks import check_hit

        report = check_hit(rec, self.check_config, ranges=[c.range for c in self.plan.channels],
                           trigger_level=self.plan.acq.trigger_level)
        reasons = [f for f in report.flags if f in REJECT_FLAGS]
        warns = [f for f in report.flags if f not in REJECT_FLAGS]
        for i in _dead_channels(rec):
            warns.append(f"dead_channel:{self.plan.channels[i].name}")
        return report, reasons, warns

    # ------------------------------------------------------------------ one point
    def _run_point(self, k: int, point: str) -> str:
        """Measure one point; returns 'done', 'skip', 'back' or 'quit'."""
        plan = self.plan
        st = self.store.points().get(k)
        kept = {h: self.store.load(h) for h in (st.accepted if st else [])}
        cands = {h: self.store.load(h) for h in (st.candidates if st else [])}
        avg = _averager(plan)
        for r in list(kept.values()) + list(cands.values()):
            avg.add(r)
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
                self.observer.message(f"point {point}: no hit within {plan.acq.timeout_s:g} s ({e})")
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
                continue
            attempts += 1
            timeouts = 0
            rec.metadata = {**(rec.metadata or {}), "point": point, "point_index": k}
            rec.hit_id = self.store.next_hit_id            # the id the store will give it
            self._note_peaks(rec)
            report, reasons, warns = self._check(rec)
            running = None
            if not reasons:
                avg.add(rec)
            if avg.n_averages:
                running = _band(avg.frf(), plan)
            self.observer.hit(k, point, rec, report, running)
            extra = {"warnings": warns} if warns else None
            if self.mode == "auto":
                if reasons:
                    hid = self.store.add(rec, point=k, status="rejected", reasons=reasons, extra=extra)
                    self.observer.decided(k, point, hid, "rejected", reasons)
                    continue
                hid = self.store.add(rec, point=k, status="candidate", extra=extra)
                cands[hid] = rec
                self.observer.decided(k, point, hid, "candidate", warns)
                continue
            # interactive
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
                continue
            if not reasons:
                avg.remove(rec.hit_id)
            if a == "r":
                hid = self.store.add(rec, point=k, status="rejected", reasons=reasons + ["operator"], extra=extra)
                self.observer.decided(k, point, hid, "rejected", reasons + ["operator"])
            elif a == "s":
                self.store.skip_point(k, "skipped by the operator")
                return "skip"
            elif a == "b":
                return "back"
            else:
                return "quit"
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
        """Measure every unfinished point; returns the summary (also written to ``summary.json``)."""
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
        (self.out_dir / "summary.json").write_text(json.dumps(summ.to_dict(), indent=1))
        return summ

    # ------------------------------------------------------------------ export
    def frf(self) -> FRF:
        """FRFs of all measured points; roving-hammer data reordered by reciprocity (accelerometers as references)."""
        return session_frf(self.store, self.plan)

    def export(self, path=None) -> Path:
        """Write geometry, raw records, H1 FRFs and coherence to one UFF file (default ``session.uff``)."""
        return export_session(self.store, self.plan, path or self.out_dir / "session.uff")


def session_frf(store: HitStore, plan: TestPlan, *, reciprocity: bool = True) -> FRF:
    """FRF matrix of a session's accepted hits (points without accepted hits are left out).

    Roving hammer: one column per hit point (responses = fixed accelerometers); with ``reciprocity``
    the matrix is transposed so the accelerometers become the references and the hit points the
    responses (thesis section 5.3).  Roving accelerometer: one row per roving point, the hammer as
    reference (fixed response channels, if any, are left out).  All points share one exponential-window
    β (same record length and pretrigger), kept in ``metadata['exp_window_beta']``.
    """
    per_point = store.accepted_records()
    parts = []
    for k, point in enumerate(plan.points):
        recs = per_point.get(k)
        if not recs:
            continue
        f = frf_from_hits(recs, plan)
        if plan.pattern == "accelerometer":
            f = f.select(responses=[point])
        parts.append(f)
    if not parts:
        raise PlanError(f"the session in {str(store.dir)!r} has no accepted hits yet; acquire first")
    meta = dict(parts[0].metadata)
    if plan.pattern == "hammer":
        frf = concat(parts, axis="references") if len(parts) > 1 else parts[0]
        if reciprocity:
            from .reciprocity import reorder_by_reciprocity

            frf = reorder_by_reciprocity(frf)
    else:
        frf = concat(parts, axis="responses") if len(parts) > 1 else parts[0]
    frf.metadata.setdefault("exp_window_beta", meta.get("exp_window_beta", 0.0))
    frf.metadata["n_averages"] = min(len(v) for v in per_point.values())
    return frf


def export_session(store: HitStore, plan: TestPlan, path) -> Path:
    """One UFF with geometry (2411), raw records (58, func 1), H1 FRFs (58, func 4) and coherence (func 6).

    Written to a temporary file and renamed, so a crash during export never leaves a half file in place.
    """
    from modalab import uff

    path = Path(path)
    tmp = path.with_name(path.name + ".part")
    if tmp.exists():
        tmp.unlink()
    first = True
    if plan.geometry:
        uff.write_geometry(tmp, plan.geometry, append=False)
        first = False
    recs = []
    for rs in store.accepted_records().values():
        for r in rs:      # the raw record keeps only short metadata (UFF ID lines are 80 characters)
            recs.append(TimeRecord(sample_rate_hz=r.sample_rate_hz, data=r.data, dofs=r.dofs, roles=r.roles,
                                   units=r.units, sensitivity=r.sensitivity, trigger_index=r.trigger_index,
                                   overload=r.overload, hit_id=r.hit_id,
                                   metadata={"point": (r.metadata or {}).get("point")}))
    if recs:
        uff.write_records(tmp, recs, append=not first)
        first = False
    frf = session_frf(store, plan)
    frf.metadata = {k: frf.metadata[k] for k in ("estimator", "n_averages", "exp_window_beta", "sample_rate_hz")
                    if k in frf.metadata}
    uff.write_frf(tmp, frf, append=not first)
    tmp.replace(path)
    return path
