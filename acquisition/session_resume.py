"""Resuming and recovering an acquisition session: the plan must be the one the session began with, what a
resumed session found in its store, when a point counts as finished, and reconnecting a lost DAQ.

Split from :mod:`acquisition.session`; :class:`_Recovery` is a base of
:class:`~acquisition.session.AcquisitionSession` and uses its ``plan``, ``store``, ``backend``, ``observer``,
``out_dir``, ``reconnects``/``max_reconnects`` and ``_configure``.  The hits themselves are kept safe by
:class:`acquisition.store.HitStore` (written and ``fsync``-ed before the next arm); nothing here writes a hit.
"""
from __future__ import annotations

import json

from modalab.core.errors import DaqError, ModalabError, PlanError

__all__: list[str] = []


def _text(v) -> str:
    """A plan value as the user wrote it in TOML (no Python reprs)."""
    if v is None:
        return "(not set)"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, list):
        return "[" + ", ".join(_text(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {_text(x)}" for k, x in v.items()) + "}"
    return f"{v:g}" if isinstance(v, float) else str(v)


def _changes(where: str, old, new) -> list[str]:
    """The keys that differ between two plan values, one ``acquisition.averages 3 -> 4`` each."""
    if isinstance(old, dict) and isinstance(new, dict):
        out = []
        for k in list(old) + [k for k in new if k not in old]:
            if old.get(k) != new.get(k):
                out += _changes(f"{where}.{k}", old.get(k), new.get(k))
        return out
    if isinstance(old, list) and isinstance(new, list) and len(old) == len(new) and \
            all(isinstance(x, dict) for x in old + new):
        out = []
        for i, (x, y) in enumerate(zip(old, new)):
            out += _changes(f"{where}[{i + 1}]", x, y)
        return out
    return [f"{where} {_text(old)} -> {_text(new)}"]


class _Stop(Exception):
    """Leave the session cleanly (device gone for good)."""


class _Recovery:
    """Resume checks and device-lost recovery of :class:`~acquisition.session.AcquisitionSession`."""

    #: plan sections that must not change when a session is resumed ([sim], [hammer], [geometry] may)
    RESUME_SECTIONS = ("acquisition", "trigger", "windows", "channels", "roving")

    def _check_same_plan(self) -> None:
        stored = self.store.plan        # from session.json, or rebuilt from the journal (acquisition.store)
        if not stored:
            return
        for key in self.RESUME_SECTIONS:
            now = json.loads(json.dumps(self.plan.raw.get(key), default=str))
            if stored.get(key) != now:
                changes = "; ".join(_changes(key, stored.get(key), now))
                raise PlanError(f"the plan's [{key}] differs from the one the session in {str(self.out_dir)!r} was "
                                f"started with: {changes}; resume with the original plan or start a new session "
                                "directory")

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
