"""FRF estimation from averaged hammer hits: H1, H2, Hv and coherence, SIMO and MIMO.

By task
-------
Arrays (scipy.signal style, ``axis=`` is the time axis)
    :func:`cross_spectra` → :class:`CrossSpectra`; :func:`h1`, :func:`h2`, :func:`hv`,
    :func:`coherence`, :func:`multiple_coherence` return ``(freq_hz, values)``.
Hits (:class:`modalab.core.records.TimeRecord`) → labelled :class:`modalab.core.frf.FRF`
    :func:`estimate_frf` (one channel layout, SIMO or MIMO), :func:`estimate_frf_roving`
    (hits grouped by hammer DOF, concatenated along the references),
    :class:`SpectralAverager` (running average: ``add(record)`` / ``remove(hit_id)`` / ``frf()``).

Conventions
-----------
Every hit is one average (no segmentation: an impact record is a transient).  The spectral densities,
the estimators and their handling of lines without energy are those of :mod:`acquisition.estimators`
(array level; its names are re-exported here).

For several force channels (MIMO) the FRF container's coherence holds the *multiple* coherence of
each response (repeated along the references) and ``metadata['coherence_kind'] == 'multiple'``.

References
----------
J. S. Bendat, A. G. Piersol, *Random Data*, 4th ed., Wiley 2010, ch. 6 (single input), ch. 7 (multiple
inputs), ch. 9 (statistical errors of the estimates).
D. J. Ewins, *Modal Testing: Theory, Practice and Application*, 2nd ed., 2000, ch. 3 (mobility
measurement: impact excitation, H1/H2).
H. Vold, J. Crowley, G. T. Rocklin, "New ways of estimating frequency response functions",
Sound and Vibration 18(11), 1984 (the Hv estimator).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from modalab.core.dof import Dof
from modalab.core.errors import ModalabValueError
from modalab.core.frf import FRF, concat
from modalab.core.records import TimeRecord
from modalab.core.units import to_si

from .estimators import (ESTIMATORS, CrossSpectra, _check_estimator, _one_sided_factor, _spectra_sums, coherence,
                         cross_spectra, h1, h2, hv, multiple_coherence)
from .windows import ExponentialWindow, ForceWindow, windowed_force

__all__ = [
    "CrossSpectra",
    "cross_spectra",
    "h1",
    "h2",
    "hv",
    "coherence",
    "multiple_coherence",
    "SpectralAverager",
    "estimate_frf",
    "estimate_frf_roving",
    "group_by_reference",
    "quantity_from_unit",
    "ESTIMATORS",
]

log = logging.getLogger(__name__)


_QUANTITY_OF_UNIT = {
    "m/s^2": "accelerance", "m/s2": "accelerance", "m/s**2": "accelerance", "m/s²": "accelerance",
    "g": "accelerance", "mm/s^2": "accelerance", "in/s^2": "accelerance",
    "m/s": "mobility", "mm/s": "mobility", "in/s": "mobility",
    "m": "receptance", "mm": "receptance", "um": "receptance", "in": "receptance",
}
_FORCE_UNITS = ("N", "kN", "lbf")


def quantity_from_unit(unit: str) -> str:
    """FRF quantity measured by a response channel in ``unit``: m/s² → accelerance, m/s → mobility, m → receptance."""
    u = str(unit).strip()
    q = _QUANTITY_OF_UNIT.get(u)
    if q is None:
        raise ModalabValueError(
            f"response unit {unit!r} is not a motion unit; expected one of {', '.join(sorted(_QUANTITY_OF_UNIT))}. "
            "Give the response channels' units in SI (m/s^2 for accelerometers)")
    return q


# ============================================================================ hits -> FRF
def _as_force_window(fw):
    if fw is None or isinstance(fw, ForceWindow):
        return fw
    if isinstance(fw, dict):
        return ForceWindow(**{k: v for k, v in fw.items() if k != "type"})
    raise ModalabValueError(f"force_window={fw!r}; pass acquisition.windows.ForceWindow(...) or None")


def _as_exp_window(ew):
    if ew is None or isinstance(ew, ExponentialWindow):
        return ew
    if isinstance(ew, dict):
        return ExponentialWindow(**{k: v for k, v in ew.items() if k != "type"})
    raise ModalabValueError(f"exp_window={ew!r}; pass acquisition.windows.ExponentialWindow(beta=... or "
                            "end_level=...) or None")


@dataclass(frozen=True)
class _Layout:
    fs: float
    n_samples: int
    force_idx: tuple
    resp_idx: tuple
    references: tuple
    responses: tuple
    force_scale: np.ndarray
    resp_scale: np.ndarray
    quantity: str

    @classmethod
    def of(cls, rec: TimeRecord) -> "_Layout":
        if not isinstance(rec, TimeRecord):
            raise ModalabValueError(f"expected a modalab.core.records.TimeRecord; got {type(rec).__name__}")
        fi, ri = tuple(rec.force_channels), tuple(rec.response_channels)
        if not fi:
            raise ModalabValueError(f"hit {rec.hit_id} has no force channel (roles {rec.roles}); mark the hammer "
                                    "channel with role 'force'")
        if not ri:
            raise ModalabValueError(f"hit {rec.hit_id} has no response channel (roles {rec.roles}); mark the "
                                    "accelerometers with role 'response'")
        fscale = []
        for i in fi:
            u = rec.units[i]
            if u not in _FORCE_UNITS:
                raise ModalabValueError(f"force channel {rec.dofs[i]} of hit {rec.hit_id} has unit {u!r}; expected "
                                        f"one of {', '.join(_FORCE_UNITS)}")
            fscale.append(float(to_si(1.0, u)))
        qs, rscale = [], []
        for i in ri:
            u = rec.units[i]
            qs.append(quantity_from_unit(u))
            rscale.append(float(to_si(1.0, u.replace("²", "^2"))))
        if len(set(qs)) != 1:
            raise ModalabValueError(
                f"hit {rec.hit_id} mixes response quantities {sorted(set(qs))} (units "
                f"{[rec.units[i] for i in ri]}); an FRF holds one quantity. Estimate each sensor type separately")
        return cls(fs=rec.sample_rate_hz, n_samples=rec.n_samples, force_idx=fi, resp_idx=ri,
                   references=tuple(rec.dofs[i] for i in fi), responses=tuple(rec.dofs[i] for i in ri),
                   force_scale=np.asarray(fscale), resp_scale=np.asarray(rscale), quantity=qs[0])

    def check(self, rec: TimeRecord, first_id) -> None:
        other = _Layout.of(rec)
        if other.fs != self.fs:
            raise ModalabValueError(f"hit {rec.hit_id} is sampled at {other.fs:g} Hz but hit {first_id} at "
                                    f"{self.fs:g} Hz; average hits of one sampling rate only")
        if other.n_samples != self.n_samples:
            raise ModalabValueError(f"hit {rec.hit_id} has {other.n_samples} samples but hit {first_id} has "
                                    f"{self.n_samples}; records must have the same length")
        if other.references != self.references:
            raise ModalabValueError(
                f"hit {rec.hit_id} has force at {[str(d) for d in other.references]} but hit {first_id} at "
                f"{[str(d) for d in self.references]}; only hits at the same point are averaged. "
                "For roving-hammer data use estimate_frf_roving")
        if other.responses != self.responses or other.quantity != self.quantity:
            raise ModalabValueError(
                f"hit {rec.hit_id} has responses {[str(d) for d in other.responses]} ({other.quantity}) but hit "
                f"{first_id} has {[str(d) for d in self.responses]} ({self.quantity}); use one channel setup")


def _force_highpass(rec: TimeRecord, force_idx) -> list:
    """AC-coupling corners (Hz) of the force channels of ``rec`` from ``metadata['highpass_hz']`` (one per
    channel, 0 = DC coupled); zeros when the record does not say (the force window then cuts whatever
    follows the pulse, as before)."""
    v = rec.highpass_hz()
    if v is None:
        return [0.0] * len(force_idx)
    return [v[i] for i in force_idx]


class SpectralAverager:
    """Running average of hammer hits into auto/cross spectra, for a live FRF.

    Parameters (keyword-only; ``__init__`` only stores them)
    ----------
    estimator : 'H1' (default), 'H2' or 'Hv' — what :meth:`frf` returns.
    force_window : :class:`~acquisition.windows.ForceWindow` applied to the force channels, or None.
    exp_window : :class:`~acquisition.windows.ExponentialWindow` applied to all channels, or None.
        With ``end_level`` the decay rate β is fixed by the first hit (its length and trigger) and
        used for all hits, so every average carries the same added damping.
    nfft : FFT length (default the record length).

    ``add(record)`` costs one FFT per channel plus O(n_channels · n_in · n_freq) products;
    ``remove(hit_id)`` subtracts a hit's stored contribution in the same time; ``frf()`` solves the
    estimator.  Each hit's windowed spectra are kept (n_channels · n_freq complex numbers per hit) so
    a hit can be removed exactly.  Windows start at each hit's own ``trigger_index``.
    """

    def __init__(self, *, estimator: str = "H1", force_window: ForceWindow | None = None,
                 exp_window: ExponentialWindow | None = None, nfft: int | None = None):
        self.estimator = estimator
        self.force_window = force_window
        self.exp_window = exp_window
        self.nfft = nfft
        self._layout: _Layout | None = None
        self._first_id = None
        self._beta = 0.0
        self._hits: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._sums = None

    # ------------------------------------------------------------------ state
    @property
    def n_averages(self) -> int:
        return len(self._hits)

    @property
    def hit_ids(self) -> list[int]:
        return list(self._hits)

    @property
    def beta(self) -> float:
        """Decay rate β (1/s) of the exponential window in use (0 without one)."""
        return self._beta

    def reset(self) -> "SpectralAverager":
        """Forget every hit (the parameters stay)."""
        self._layout, self._first_id, self._beta, self._hits, self._sums = None, None, 0.0, {}, None
        return self

    def _spectra(self, rec: TimeRecord):
        L = self._layout
        n, fs, ti = L.n_samples, L.fs, rec.trigger_index
        x = rec.data[list(L.force_idx)] * L.force_scale[:, None]
        y = rec.data[list(L.resp_idx)] * L.resp_scale[:, None]
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
            raise ModalabValueError(f"hit {rec.hit_id} contains NaN or infinite samples; discard it")
        if self.force_window is not None:
            # before the exponential window: the coupling's undershoot is put back on the windowed force
            fw = self.force_window.array(n, fs, ti)
            hp = _force_highpass(rec, L.force_idx)
            x = np.stack([windowed_force(x[k], fw, fs, hp[k]) for k in range(x.shape[0])])
        if self.exp_window is not None:
            ew = np.exp(-self._beta * ((np.arange(n) - ti) / fs if self.exp_window.before_trigger == "extend"
                                       else np.maximum((np.arange(n) - ti) / fs, 0.0)))
            x = x * ew
            y = y * ew
        nfft = n if self.nfft is None else int(self.nfft)
        return np.fft.rfft(x, n=nfft, axis=-1) / fs, np.fft.rfft(y, n=nfft, axis=-1) / fs

    def _contribution(self, X, Y):
        return _spectra_sums(X[None], Y[None], self._fac)

    def add(self, record: TimeRecord) -> "SpectralAverager":
        """Add one hit; returns self.  Raises if its layout differs from the first hit's."""
        _check_estimator(self.estimator)
        fw, ew = _as_force_window(self.force_window), _as_exp_window(self.exp_window)
        self.force_window, self.exp_window = fw, ew
        if self._layout is None:
            layout = _Layout.of(record)
            nfft = layout.n_samples if self.nfft is None else int(self.nfft)
            if nfft < layout.n_samples:
                raise ModalabValueError(f"nfft={nfft} is shorter than the record ({layout.n_samples} samples)")
            self._layout, self._first_id = layout, record.hit_id
            self._beta = 0.0 if ew is None else ew.resolve_beta(layout.n_samples, layout.fs, record.trigger_index)
            self._fac = _one_sided_factor(nfft, nfft // 2 + 1)
            self._freq = np.fft.rfftfreq(nfft, 1.0 / layout.fs)
        else:
            self._layout.check(record, self._first_id)
        if record.hit_id in self._hits:
            raise ModalabValueError(f"hit {record.hit_id} is already in the average; hit ids must be unique "
                                    "(remove it first to replace it)")
        X, Y = self._spectra(record)
        c = self._contribution(X, Y)
        self._sums = list(c) if self._sums is None else [s + d for s, d in zip(self._sums, c)]
        self._hits[record.hit_id] = (X, Y)
        log.debug("added hit %s (%d averages)", record.hit_id, self.n_averages)
        return self

    def remove(self, hit) -> "SpectralAverager":
        """Remove a hit (its ``hit_id`` or the record) from the average; returns self."""
        hid = hit.hit_id if isinstance(hit, TimeRecord) else int(hit)
        if hid not in self._hits:
            raise ModalabValueError(f"hit {hid} is not in the average (hits: {self.hit_ids}); nothing removed")
        X, Y = self._hits.pop(hid)
        c = self._contribution(X, Y)
        self._sums = [s - d for s, d in zip(self._sums, c)]
        if not self._hits:
            self.reset()
        return self

    def spectra(self) -> CrossSpectra:
        """The averaged :class:`CrossSpectra` of the hits added so far."""
        if not self._hits:
            raise ModalabValueError("no hits in the average yet; call add(record) first")
        m = self.n_averages
        Gxx, Gyx, Gyy = self._sums
        return CrossSpectra(freq_hz=self._freq, Gxx=Gxx / m, Gyx=Gyx / m, Gyy=np.maximum(Gyy / m, 0.0),
                            n_averages=m)

    def frf(self, estimator: str | None = None) -> FRF:
        """The labelled FRF (responses × force channels) with coherence and window metadata."""
        est = _check_estimator(self.estimator if estimator is None else estimator)
        cs = self.spectra()
        H = cs.estimate(est)
        L = self._layout
        if cs.n_in == 1:
            coh, kind = cs.coherence(), "ordinary"
        else:
            coh, kind = np.repeat(cs.multiple_coherence()[:, None, :], cs.n_in, axis=1), "multiple"
        meta = {
            "estimator": est,
            "n_averages": cs.n_averages,
            "hit_ids": self.hit_ids,
            "force_window": None if self.force_window is None else self.force_window.to_dict(),
            "exp_window": None if self.exp_window is None else self.exp_window.to_dict(),
            "window_origin": "trigger",
            "coherence_kind": kind,
            "sample_rate_hz": L.fs,
            "n_samples": L.n_samples,
        }
        return FRF(freq_hz=cs.freq_hz, H=H, responses=list(L.responses), references=list(L.references),
                   coherence=coh, quantity=L.quantity, metadata=meta, window_beta_per_s=float(self._beta))


def _records_list(records) -> list[TimeRecord]:
    if isinstance(records, TimeRecord):
        return [records]
    recs = list(records)
    if not recs:
        raise ModalabValueError("no hits given; pass a list of TimeRecord")
    return recs


def estimate_frf(records: Sequence[TimeRecord] | TimeRecord, *, estimator: str = "H1",
                 force_window: ForceWindow | None = None, exp_window: ExponentialWindow | None = None,
                 nfft: int | None = None) -> FRF:
    """FRF from a set of averaged hits with one channel layout (SIMO or MIMO).

    Parameters
    ----------
    records : hits (:class:`~modalab.core.records.TimeRecord`), all with the same sampling rate, length,
        force DOFs and response DOFs.  Data in engineering units (N; m/s², m/s or m, or g etc.,
        converted to SI).
    estimator : 'H1', 'H2' (one force channel) or 'Hv'.
    force_window : :class:`~acquisition.windows.ForceWindow` for the force channels, or None.
    exp_window : :class:`~acquisition.windows.ExponentialWindow` for all channels, or None.
    nfft : FFT length (default the record length).

    Returns
    -------
    FRF with ``responses`` = response-channel DOFs, ``references`` = force-channel DOFs, quantity
    from the response unit (m/s² → accelerance, m/s → mobility, m → receptance), coherence, and
    metadata ``estimator``, ``n_averages``, ``force_window``; ``FRF.window_beta_per_s`` (1/s; remove it
    with :func:`acquisition.windows.correct_damping`), ``hit_ids``, ``coherence_kind``.
    """
    avg = SpectralAverager(estimator=estimator, force_window=force_window, exp_window=exp_window, nfft=nfft)
    for r in _records_list(records):
        avg.add(r)
    return avg.frf()


def group_by_reference(records: Sequence[TimeRecord]) -> dict[tuple[Dof, ...], list[TimeRecord]]:
    """Hits grouped by their force-channel DOFs, in order of first appearance."""
    out: dict[tuple[Dof, ...], list[TimeRecord]] = {}
    for r in _records_list(records):
        if not isinstance(r, TimeRecord):
            raise ModalabValueError(f"expected TimeRecord items; got {type(r).__name__}")
        out.setdefault(tuple(r.force_dofs), []).append(r)
    return out


def estimate_frf_roving(records: Sequence[TimeRecord], **kw) -> FRF:
    """Roving-hammer FRFs: hits grouped by hammer DOF, each group averaged, concatenated along references.

    Every group must measure the same response DOFs.  Keywords as :func:`estimate_frf`; an
    exponential window given by ``end_level`` is resolved to one β from the first hit and used for
    every hit point, so all columns carry the same added damping.
    ``metadata['n_averages']`` is the smallest group's count; ``n_averages_per_reference`` lists all.
    """
    groups = group_by_reference(records)
    ew = _as_exp_window(kw.get("exp_window"))
    if ew is not None and ew.beta is None:
        first = next(iter(groups.values()))[0]
        kw["exp_window"] = ExponentialWindow(
            beta=ew.resolve_beta(first.n_samples, first.sample_rate_hz, first.trigger_index),
            before_trigger=ew.before_trigger)
    frfs = []
    for refs, recs in groups.items():
        if not refs:
            raise ModalabValueError(f"hit {recs[0].hit_id} has no force channel; mark the hammer channel 'force'")
        frfs.append(estimate_frf(recs, **kw))
    resp0 = [(d.node, d.axis) for d in frfs[0].responses]
    for f in frfs[1:]:
        if [(d.node, d.axis) for d in f.responses] != resp0:
            raise ModalabValueError(
                f"hits at {[str(d) for d in f.references]} measured responses {[str(d) for d in f.responses]} but "
                f"the first group measured {[str(d) for d in frfs[0].responses]}; roving-hammer hits must share "
                "the fixed sensors")
    out = concat(frfs, axis="references") if len(frfs) > 1 else frfs[0]
    per = {",".join(str(d) for d in refs): len(recs) for refs, recs in groups.items()}
    out.metadata["n_averages"] = min(per.values())
    out.metadata["n_averages_per_reference"] = per
    out.metadata["hit_ids"] = [r.hit_id for recs in groups.values() for r in recs]
    return out
