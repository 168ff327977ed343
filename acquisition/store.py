"""Crash-safe storage of an acquisition session: nothing accepted is ever lost.

Layout of a session directory::

    session.json          plan and creation time (written once, atomically)
    hits/hit_000012.npz   one raw record per stored hit
    journal.jsonl         append-only event log, one JSON object per line

Write order guarantees durability: a hit's ``.npz`` is written to a temporary
file, flushed and ``fsync``-ed, renamed into place and the directory
``fsync``-ed; only then is its journal line appended and ``fsync``-ed.  So
when :meth:`HitStore.add` returns the hit is on disk, and a crash at any
instant (Ctrl-C, kill -9, power loss) leaves either

* no journal line: the hit was never accepted; a stray file is deleted on reopen, or
* a journal line whose file exists with the recorded SHA-256: the hit is kept.

A torn last journal line (a partial write) fails to parse and is cut off on
reopen; a journal line whose file is missing or whose checksum differs is
reported and discarded, never silently used.  Hit ids are never reused, so
after any number of interruptions every accepted hit is present exactly once.
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

from modalab.errors import StoreError
from modalab.records import TimeRecord

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


class HitStore:
    """Append-only, fsync-ed store of hits for one session directory."""

    def __init__(self, directory, *, plan: dict | None = None, resume: bool = False):
        self.dir = Path(directory)
        self.hits_dir = self.dir / "hits"
        self.journal_path = self.dir / "journal.jsonl"
        exists = self.journal_path.exists() or (self.dir / "session.json").exists()
        if exists and not resume:
            raise StoreError(f"session directory {str(self.dir)!r} already holds a session; pass --resume to continue "
                             "it or choose another -o directory")
        if resume and not exists:
            raise StoreError(f"nothing to resume in {str(self.dir)!r} (no session.json/journal.jsonl); start without "
                             "--resume")
        self.hits_dir.mkdir(parents=True, exist_ok=True)
        self.discarded: list[str] = []
        if not exists:
            _atomic_write(self.dir / "session.json",
                          json.dumps({"version": 1, "created": time.time(), "plan": plan or {}}, indent=1,
                                     default=str).encode())
            self.journal_path.touch()
            _fsync_dir(self.dir)
        self.events: list[dict] = []
        self._files: dict[int, tuple[str, str]] = {}
        self._load()

    # ----------------------------------------------------------------- journal
    def _load(self) -> None:
        raw = self.journal_path.read_bytes() if self.journal_path.exists() else b""
        good_len = 0
        pos = 0
        for line in raw.splitlines(keepends=True):
            pos += len(line)
            if not line.endswith(b"\n"):
                self.discarded.append("torn last journal line (partial write) discarded")
                break
            try:
                ev = json.loads(line)
                if not isinstance(ev, dict) or "event" not in ev:
                    raise ValueError
            except ValueError:
                self.discarded.append(f"unreadable journal line at byte {pos - len(line)} discarded")
                break
            self.events.append(ev)
            good_len = pos
        if good_len != len(raw):
            with open(self.journal_path, "r+b") as fh:
                fh.truncate(good_len)
                fh.flush()
                os.fsync(fh.fileno())
        # verify hit files named by the journal
        valid = []
        for ev in self.events:
            if ev["event"] == "hit" and ev.get("file"):
                p = self.hits_dir / ev["file"]
                ok = p.exists() and hashlib.sha256(p.read_bytes()).hexdigest() == ev.get("sha256")
                if not ok:
                    self.discarded.append(f"hit {ev['hit']}: file {ev['file']} missing or corrupt, discarded")
                    ev = {**ev, "status": "rejected", "file": None,
                          "reasons": ["raw file missing or corrupt on disk (discarded)"]}
                    valid.append(ev)
                    continue
                self._files[int(ev["hit"])] = (ev["file"], ev["sha256"])
            valid.append(ev)
        self.events = valid
        known = {f for f, _ in self._files.values()}
        for p in self.hits_dir.iterdir():
            if p.name not in known:
                self.discarded.append(f"stray file {p.name} (written but never journalled) removed")
                p.unlink()
        for msg in self.discarded:
            log.warning("session store %s: %s", self.dir, msg)

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
            k = int(ev.get("point", -1))
            st = out.setdefault(k, PointState())
            e = ev["event"]
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
                st.done = True
            elif e == "point_skipped":
                st.done, st.skipped = True, ev.get("reason", "skipped")
            elif e == "point_reset":
                st.rejected.extend((h, ["superseded (operator went back)"]) for h in st.accepted + st.candidates)
                st.accepted, st.candidates, st.done, st.skipped = [], [], False, ""
        return out

    def load(self, hit_id: int) -> TimeRecord:
        if hit_id not in self._files:
            raise StoreError(f"hit {hit_id} is not in the store {str(self.dir)!r}")
        name, digest = self._files[hit_id]
        raw = (self.hits_dir / name).read_bytes()
        if hashlib.sha256(raw).hexdigest() != digest:
            raise StoreError(f"hit {hit_id}: file {name} changed on disk since it was stored (checksum mismatch)")
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
