"""Crash-safe storage of an acquisition session: nothing accepted is ever lost.

Layout of a session directory::

    session.json          plan and creation time (written once, atomically)
    hits/hit_000012.npz   one raw record per stored hit
    journal.jsonl         append-only event log, one JSON object per line; its first line
                          repeats session.json (so a lost session.json is rebuilt from it)
    corrupt/              hit files found damaged on reopen, kept aside as evidence

Write order guarantees durability: session.json is written atomically before the
journal exists.  A hit's ``.npz`` is written to a temporary file, flushed and
``fsync``-ed, renamed into place and the directory ``fsync``-ed; only then is its
journal line appended and ``fsync``-ed.  So when :meth:`HitStore.add` returns the
hit is on disk, and a crash at any instant (Ctrl-C, kill -9, power loss) leaves either

* no journal line: the hit was never accepted; a stray file is deleted on reopen, or
* a journal line whose file exists with the recorded SHA-256: the hit is kept.

A torn last journal line (a partial write) fails to parse and is cut off on
reopen; a damaged line *before* the last one is not a crash's mark, and the store
refuses to open rather than guess.  A journalled hit whose file is missing or whose
checksum differs (disk damage, a stray edit) is a **lost hit**: a ``hit_lost`` event
is journalled, the file moved to ``corrupt/``, and its point re-opened (an accepted
hit lost means the point no longer has its averages; :meth:`HitStore.points` then
reports it unfinished).  Hit ids are never reused, so after any number of
interruptions every accepted hit is present exactly once.

``session.json`` missing or unreadable is rebuilt from the journal's first line; a
journal without that line (an older session) cannot be checked against the plan,
and the store refuses to resume it.  :attr:`HitStore.discarded` lists what reopening
found and did, one sentence each.
"""
from __future__ import annotations

import hashlib
import io
import json
import logging
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from modalab.core.errors import StoreError
from modalab.core.records import TimeRecord

log = logging.getLogger(__name__)
__all__ = ["HitStore", "PointState"]


def _fsync_dir(path: Path) -> None:
    try:
        fd = os.open(str(path), os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _atomic_write(path: Path, payload: bytes) -> None:
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as fh:
        fh.write(payload)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)
    _fsync_dir(path.parent)


def _record_bytes(rec: TimeRecord) -> bytes:
    meta = {"dofs": [str(d) for d in rec.dofs], "roles": rec.roles, "units": rec.units,
            "trigger_index": rec.trigger_index, "hit_id": rec.hit_id, "metadata": rec.metadata}
    buf = io.BytesIO()
    np.savez(buf, data=rec.data, sample_rate_hz=rec.sample_rate_hz, sensitivity=rec.sensitivity,
             overload=rec.overload, meta=np.frombuffer(json.dumps(meta, default=str).encode(), dtype=np.uint8))
    return buf.getvalue()


def _record_from_bytes(raw: bytes) -> TimeRecord:
    with np.load(io.BytesIO(raw), allow_pickle=False) as z:
        meta = json.loads(bytes(z["meta"]).decode())
        return TimeRecord(sample_rate_hz=float(z["sample_rate_hz"]), data=z["data"], dofs=meta["dofs"],
                          roles=meta["roles"], units=meta["units"], sensitivity=z["sensitivity"],
                          trigger_index=meta["trigger_index"], overload=z["overload"], hit_id=meta["hit_id"],
                          metadata=meta["metadata"])


@dataclass
class PointState:
    """What the journal says about one roving point."""

    accepted: list = field(default_factory=list)      # hit ids
    candidates: list = field(default_factory=list)    # hit ids awaiting best-N-of-M selection
    rejected: list = field(default_factory=list)      # (hit id, reasons)
    done: bool = False
    skipped: str = ""
    lost: list = field(default_factory=list)          # hit ids whose raw file was found damaged or missing
    reopened: bool = False                            # done once, re-opened because an accepted hit was lost


class HitStore:
    """Append-only, fsync-ed store of hits for one session directory."""

    def __init__(self, directory, *, plan: dict | None = None, resume: bool = False, backend: str | None = None):
        self.dir = Path(directory)
        self.hits_dir = self.dir / "hits"
        self.journal_path = self.dir / "journal.jsonl"
        self.session_path = self.dir / "session.json"
        if self.dir.exists() and not self.dir.is_dir():
            raise StoreError(f"session folder {str(self.dir)!r} is a file; give -o a new or existing folder")
        exists = self.journal_path.exists() or self.session_path.exists()
        if exists and not resume:
            raise StoreError(f"session directory {str(self.dir)!r} already holds a session; pass --resume to continue "
                             "it or choose another -o directory")
        if resume and not exists:
            raise StoreError(f"nothing to resume in {str(self.dir)!r} (no session.json/journal.jsonl); start without "
                             "--resume")
        try:
            self.hits_dir.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise StoreError(f"cannot create the session folder {str(self.dir)!r}: {e.strerror}") from None
        self.discarded: list[str] = []
        self.plan: dict = {}
        self.backend: str | None = backend     # 'sim', 'nidaqmx' or a backend's class name (session.json)
        self.events: list[dict] = []
        self._files: dict[int, tuple[str, str]] = {}
        if not exists:
            header = {"version": 2, "created": time.time(), "backend": backend, "plan": plan or {}}
            _atomic_write(self.session_path, json.dumps(header, indent=1, default=str).encode())
            self.journal_path.touch()
            _fsync_dir(self.dir)
            self._append({"event": "session", **json.loads(json.dumps(header, default=str))})
        self._load()

    # ----------------------------------------------------------------- journal
    def _load(self) -> None:
        self.events = []
        raw = self.journal_path.read_bytes() if self.journal_path.exists() else b""
        good_len = 0
        pos = 0
        lines = raw.splitlines(keepends=True)
        for i, line in enumerate(lines):
            pos += len(line)
            last = i == len(lines) - 1
            try:
                ev = json.loads(line) if line.endswith(b"\n") else None
                if not isinstance(ev, dict) or "event" not in ev:
                    raise ValueError
            except ValueError:
                if not last:
                    raise StoreError(f"{self.journal_path}: line {i + 1} is damaged and is not the last line (a crash "
                                     "only tears the last one); the session cannot be resumed safely. Restore the "
                                     "journal from a backup, or start a new session folder") from None
                self.discarded.append("torn last journal line (partial write) discarded" if not line.endswith(b"\n")
                                      else f"unreadable last journal line at byte {pos - len(line)} discarded")
                break
            self.events.append(ev)
            good_len = pos
        if good_len != len(raw):
            with open(self.journal_path, "r+b") as fh:
                fh.truncate(good_len)
                fh.flush()
                os.fsync(fh.fileno())
        self._load_header()
        # verify hit files named by the journal; a damaged or missing one is a lost hit
        already_lost = {int(ev["hit"]) for ev in self.events if ev["event"] == "hit_lost"}
        for ev in list(self.events):
            if ev["event"] != "hit" or not ev.get("file"):
                continue
            h = int(ev["hit"])
            if h in already_lost:
                continue
            p = self.hits_dir / ev["file"]
            if not p.exists():
                why = "missing"
            elif hashlib.sha256(p.read_bytes()).hexdigest() != ev.get("sha256"):
                why = "corrupt (checksum differs from the one journalled)"
            else:
                self._files[h] = (ev["file"], ev["sha256"])
                continue
            self._lose(ev, why)
        known = {f for f, _ in self._files.values()}
        lost_files = {ev["file"] for ev in self.events
                      if ev["event"] == "hit" and ev.get("file") and int(ev["hit"]) in already_lost}
        for p in self.hits_dir.iterdir():
            if p.name in lost_files:          # journalled as lost; a crash came before it was moved aside
                (self.dir / "corrupt").mkdir(exist_ok=True)
                os.replace(p, self.dir / "corrupt" / p.name)
            elif p.name not in known:
                self.discarded.append(f"stray file {p.name} (written but never journalled, a crash between the two) "
                                      "removed")
                p.unlink()
        for msg in self.discarded:
            log.warning("session store %s: %s", self.dir, msg)

    def _load_header(self) -> None:
        """The plan from session.json, or from the journal's first line (rebuilding session.json)."""
        header = None
        try:
            header = json.loads(self.session_path.read_text())
            if not isinstance(header, dict):
                header = None
        except (OSError, ValueError, UnicodeDecodeError):
            header = None
        if header is not None:
            self.plan = header.get("plan") or {}
            self.backend = header.get("backend")
            return
        first = next((ev for ev in self.events if ev["event"] == "session"), None)
        state = "missing" if not self.session_path.exists() else "unreadable"
        if first is None:
            raise StoreError(f"{str(self.session_path)!r} is {state} and the journal does not hold the session's plan "
                             "(a session from an older modalab, or a damaged folder), so the plan cannot be checked: "
                             "restore session.json, or start a new session folder")
        header = {k: v for k, v in first.items() if k != "event"}
        _atomic_write(self.session_path, json.dumps(header, indent=1, default=str).encode())
        self.plan = header.get("plan") or {}
        self.backend = header.get("backend")
        self.discarded.append(f"session.json was {state}; rebuilt from the journal (the plan is checked against it)")

    def _lose(self, ev: dict, why: str) -> None:
        """Journal a lost hit (file then journal order does not matter here: both steps are idempotent)."""
        h, k = int(ev["hit"]), int(ev.get("point", -1))
        was = ev.get("status")
        picks = [e for e in self.events if e["event"] == "select" and int(e.get("point", -2)) == k]
        if was == "candidate" and picks and h in picks[-1].get("accepted", ()):
            was = "accepted"              # an --auto candidate that the point's selection kept
        self._append({"event": "hit_lost", "hit": h, "point": k, "reason": f"raw file {ev['file']} {why}"})
        src = self.hits_dir / ev["file"]
        kept = ""
        if src.exists():
            dest = self.dir / "corrupt"
            dest.mkdir(exist_ok=True)
            os.replace(src, dest / ev["file"])
            _fsync_dir(self.hits_dir)
            kept = f"; the file is kept in corrupt/{ev['file']}"
        self.discarded.append(f"LOST hit {h} ({was}, point index {k}): raw file {ev['file']} {why}{kept}; "
                              "the point is re-opened if it no longer has its averages")

    def _append(self, ev: dict) -> None:
        line = (json.dumps(ev, default=str) + "\n").encode()
        with open(self.journal_path, "ab") as fh:
            fh.write(line)
            fh.flush()
            os.fsync(fh.fileno())
        self.events.append(ev)

    # ----------------------------------------------------------------- queries
    @property
    def next_hit_id(self) -> int:
        ids = [int(ev["hit"]) for ev in self.events if ev["event"] == "hit"]
        return max(ids, default=0) + 1

    def points(self) -> dict[int, PointState]:
        """Replay the journal into per-point state."""
        out: dict[int, PointState] = {}
        for ev in self.events:
            e = ev["event"]
            if e == "session":
                continue
            k = int(ev.get("point", -1))
            st = out.setdefault(k, PointState())
            if e == "hit":
                h = int(ev["hit"])
                if ev["status"] == "accepted":
                    st.accepted.append(h)
                elif ev["status"] == "candidate":
                    st.candidates.append(h)
                else:
                    st.rejected.append((h, ev.get("reasons", [])))
            elif e == "select":
                keep = set(ev["accepted"])
                st.accepted.extend(h for h in st.candidates if h in keep)
                st.rejected.extend((h, ["lower coherence than the kept hits"]) for h in st.candidates if h not in keep)
                st.candidates = []
            elif e == "point_done":
                st.done, st.reopened = True, False
            elif e == "point_skipped":
                st.done, st.skipped = True, ev.get("reason", "skipped")
            elif e == "point_reset":
                st.rejected.extend((h, ["superseded (operator went back)"]) for h in st.accepted + st.candidates)
                st.accepted, st.candidates, st.done, st.skipped = [], [], False, ""
            elif e == "hit_lost":
                h = int(ev["hit"])
                st.lost.append(h)
                if h in st.accepted or h in st.candidates:
                    st.rejected.append((h, [f"lost: {ev.get('reason', 'raw file damaged')}"]))
                if h in st.candidates:
                    st.candidates.remove(h)
                if h in st.accepted:
                    st.accepted.remove(h)
                    if st.done and not st.skipped:
                        st.done, st.reopened = False, True
        return out

    def load(self, hit_id: int) -> TimeRecord:
        if hit_id not in self._files:
            raise StoreError(f"hit {hit_id} is not in the store {str(self.dir)!r}")
        name, digest = self._files[hit_id]
        raw = (self.hits_dir / name).read_bytes()
        if hashlib.sha256(raw).hexdigest() != digest:
            raise StoreError(f"hit {hit_id}: file {name} changed on disk since it was stored (checksum mismatch); "
                             "resume the session to re-measure it")
        return _record_from_bytes(raw)

    def accepted_records(self) -> dict[int, list[TimeRecord]]:
        """Accepted records per point index."""
        return {k: [self.load(h) for h in st.accepted] for k, st in self.points().items() if k >= 0 and st.accepted}

    # ----------------------------------------------------------------- writes
    def add(self, rec: TimeRecord, *, point: int, status: str, reasons=(), extra: dict | None = None) -> int:
        """Store a hit durably (file then journal).  ``status``: 'accepted', 'candidate' or 'rejected'.

        Rejected hits are journalled without their raw data.
        """
        if status not in ("accepted", "candidate", "rejected"):
            raise StoreError(f"status {status!r}; expected accepted, candidate or rejected")
        hid = self.next_hit_id
        rec.hit_id = hid
        ev = {"event": "hit", "hit": hid, "point": int(point), "status": status, "reasons": list(reasons),
              "time": time.time()}
        if extra:
            ev.update(extra)
        if status != "rejected":
            name = f"hit_{hid:06d}.npz"
            payload = _record_bytes(rec)
            _atomic_write(self.hits_dir / name, payload)
            ev["file"], ev["sha256"] = name, hashlib.sha256(payload).hexdigest()
            self._files[hid] = (name, ev["sha256"])
        self._append(ev)
        return hid

    def select(self, point: int, keep) -> None:
        self._append({"event": "select", "point": int(point), "accepted": [int(h) for h in keep]})

    def point_done(self, point: int) -> None:
        self._append({"event": "point_done", "point": int(point)})

    def skip_point(self, point: int, reason: str) -> None:
        self._append({"event": "point_skipped", "point": int(point), "reason": reason})

    def reset_point(self, point: int) -> None:
        self._append({"event": "point_reset", "point": int(point)})
