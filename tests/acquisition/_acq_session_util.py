"""Helpers shared by the acquisition session tests (not a test module)."""
from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import tomli_w

from acquisition.session import SessionObserver
from modalab.core.dof import locate

ROOT = Path(__file__).resolve().parents[2]
PLANS = ROOT / "examples" / "plans"


def small_plan(tmp_path, base: str = "demo_roving_hammer", *, points=("1+Z", "14+Z", "19+Z"), averages: int = 2,
               max_hits: int = 3, record_s: float = 1.0, sim: dict | None = None, name: str = "plan.toml",
               hammer_range: float | None = None, edit=None) -> Path:
    """A small copy of an example plan (1 s records, few points) written to ``tmp_path``."""
    d = tomllib.loads((PLANS / f"{base}.toml").read_text())
    if hammer_range is not None:
        next(c for c in d["channels"] if c["role"] == "force")["range"] = hammer_range
    d["acquisition"].update(record_s=record_s, pretrigger_s=0.03125, averages=averages, max_hits=max_hits)
    d["roving"]["points"] = list(points)
    d["sim"].update({"placement_scatter_m": 0.0, **(sim or {})})
    if edit is not None:
        edit(d)
    p = Path(tmp_path) / name
    p.write_text(tomli_w.dumps(d))
    return p


def exact_at_s(model, frf, beta: float) -> np.ndarray:
    """The structure's exact accelerance at s = iω + β (what an exponential window of rate β measures)."""
    io, so = locate(model.dofs, frf.responses, "response DOF")
    ii, si = locate(model.dofs, frf.references, "reference DOF")
    R = model.right[io] * np.asarray(so)[:, None]
    L = model.left[:, ii] * np.asarray(si)[None, :]
    s = 2j * np.pi * np.asarray(frf.freq_hz) + beta
    return np.einsum("ok,ki,kf->oif", R, L, s[None, :] ** 2 / (s[None, :] - model.poles[:, None]))


def rel_errors(frf, model, beta: float, *, rows=None, min_coherence: float = 0.99, f_min: float = 5.0):
    """|H − H_exact(iω+β)| / |H_exact| at lines with coherence above ``min_coherence`` and above ``f_min``."""
    E = exact_at_s(model, frf, beta)
    H, C = frf.H, frf.coherence
    if rows is not None:
        H, C, E = H[rows], C[rows], E[rows]
    good = (C > min_coherence) & (np.asarray(frf.freq_hz) > f_min)
    return np.abs(H - E)[good] / np.abs(E)[good], good


def journal(session_dir) -> list[dict]:
    """Complete journal lines of a session directory, read without touching it."""
    out = []
    raw = (Path(session_dir) / "journal.jsonl").read_bytes()
    for line in raw.splitlines(keepends=True):
        if not line.endswith(b"\n"):
            break
        try:
            out.append(json.loads(line))
        except ValueError:
            break
    return out


def accepted_hits(events) -> dict[int, tuple[int, str]]:
    """hit id -> (point index, sha256) of every hit the journal holds as accepted (after selections/resets)."""
    status: dict[int, tuple[int, str, str]] = {}
    for ev in events:
        if ev["event"] == "hit":
            status[ev["hit"]] = (ev["point"], ev["status"], ev.get("sha256"))
        elif ev["event"] == "select":
            keep = set(ev["accepted"])
            for h, (p, s, d) in list(status.items()):
                if p == ev["point"] and s == "candidate":
                    status[h] = (p, "accepted" if h in keep else "rejected", d)
        elif ev["event"] == "point_reset":
            for h, (p, s, d) in list(status.items()):
                if p == ev["point"] and s in ("accepted", "candidate"):
                    status[h] = (p, "superseded", d)
    return {h: (p, d) for h, (p, s, d) in status.items() if s == "accepted"}


class Recorder(SessionObserver):
    """Records what the session shows."""

    def __init__(self):
        self.hits, self.decisions, self.messages, self.finished, self.started = [], [], [], [], []

    def point_started(self, index, point, n_points):
        self.started.append(point)

    def hit(self, index, point, rec, report, running):
        self.hits.append((point, rec, report, running))

    def decided(self, index, point, hit_id, decision, reasons):
        self.decisions.append((point, hit_id, decision, list(reasons)))

    def point_finished(self, index, point, summary):
        self.finished.append((point, summary))

    def message(self, text):
        self.messages.append(text)
