"""What a session's hits give: per-point H1 FRFs and coherence, the choice of the best hits, the session's FRF
matrix (reciprocity applied) and its UFF export.

Split from :mod:`acquisition.session` (which re-exports every public name here); the functions read the
hits of a :class:`~acquisition.store.HitStore` and never write to it.
"""
from __future__ import annotations

from pathlib import Path
from typing import Iterable

import numpy as np

from modalab.core.errors import PlanError
from modalab.core.frf import FRF, concat
from modalab.core.records import TimeRecord

from .plan import TestPlan
from .reciprocity import reorder_by_reciprocity
from .store import HitStore
from .windows import ForceWindow
from .spectral import SpectralAverager
from modalab.core import uff

__all__ = ["frf_from_hits", "mean_coherence", "best_subset", "session_frf", "export_session"]


def _windows(plan: TestPlan):

    return ForceWindow(fraction=plan.force_fraction, taper=plan.force_taper), plan.exp_window()


def _averager(plan: TestPlan):

    fw, ew = _windows(plan)
    return SpectralAverager(estimator="H1", force_window=fw, exp_window=ew)


def _band(frf: FRF, plan: TestPlan) -> FRF:
    return frf.band(0.0, plan.bandwidth_hz)


def frf_from_hits(records: list[TimeRecord], plan: TestPlan) -> FRF:
    """H1 FRF and coherence of one point's hits with the plan's windows, limited to the analysis band.

    The exponential window's decay rate is :attr:`FRF.window_beta_per_s` (1/s): the FRF is the
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


def session_frf(store: HitStore, plan: TestPlan, *, reciprocity: bool = True) -> FRF:
    """FRF matrix of a session's accepted hits (points without accepted hits are left out).

    Roving hammer: one column per hit point (responses = fixed accelerometers); with ``reciprocity``
    the matrix is transposed so the accelerometers become the references and the hit points the
    responses (thesis section 5.3).  Roving accelerometer: one row per roving point, the hammer as
    reference (fixed response channels, if any, are left out).  All points share one exponential-window
    β (same record length and pretrigger), kept in :attr:`FRF.window_beta_per_s`.
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
    if plan.pattern == "hammer":
        frf = concat(parts, axis="references") if len(parts) > 1 else parts[0]
        if reciprocity:
            frf = reorder_by_reciprocity(frf)
    else:
        frf = concat(parts, axis="responses") if len(parts) > 1 else parts[0]
    frf.metadata["n_averages"] = min(len(v) for v in per_point.values())
    return frf


def export_session(store: HitStore, plan: TestPlan, path) -> Path:
    """One UFF with geometry (2411), raw records (58, func 1), H1 FRFs (58, func 4) and coherence (func 6).

    Written to a temporary file and renamed, so a crash during export never leaves a half file in place.
    """

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
                                   metadata={k: (r.metadata or {}).get(k) for k in ("point", "backend")
                                             if (r.metadata or {}).get(k) is not None}))
    if recs:
        uff.write_records(tmp, recs, append=not first)
        first = False
    frf = session_frf(store, plan)
    frf.metadata = {k: frf.metadata[k] for k in ("estimator", "n_averages", "sample_rate_hz")
                    if k in frf.metadata}     # beta travels as the typed field FRF.window_beta_per_s
    if store.backend:
        frf.metadata["backend"] = store.backend      # sim or nidaqmx, in the FRF datasets' ID lines
    uff.write_frf(tmp, frf, append=not first)
    tmp.replace(path)
    return path
