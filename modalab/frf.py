"""The labelled FRF container.

``H`` has shape ``(n_out, n_in, n_freq)``: responses along axis 0, references
(inputs, forces) along axis 1, frequency lines along axis 2.  The container
carries the frequency axis in Hz, the DOF labels of both axes, optional
ordinary coherence of the same shape, the physical quantity and free-form
metadata that later stages read:

``metadata`` keys used by modalab
    ``estimator`` ('H1', 'H2', 'Hv', 'exact'), ``n_averages`` (int),
    ``force_window`` (dict), ``exp_window_beta`` (added decay rate β in 1/s of
    the exponential window; identification subtracts it: σ_true = σ_meas − β),
    ``H_variance`` (array of H's shape: the complex variance E|Ĥ − H|² per line,
    e.g. across averages; :meth:`FRF.select` and :meth:`FRF.band` slice it with the
    data), ``source`` (free text).
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from .dof import Dof, locate, parse_dofs
from .errors import ShapeError, ModalabValueError
from .units import QUANTITY_UNITS, check_quantity, quantity_factor

__all__ = ["FRF", "concat"]


class FRF:
    """Frequency-response functions with labels.

    Build with keywords or :meth:`from_arrays`; read files with :meth:`from_uff`.

    >>> import numpy as np
    >>> f = FRF(freq_hz=np.arange(4.0), H=np.ones((2, 1, 4)), responses=["1+Z", "2+Z"], references=["1+Z"])
    >>> f.select(responses=["2-Z"]).H[0, 0, 0]
    (-1+0j)
    """

    def __init__(self, *, freq_hz, H, responses, references, coherence=None,
                 quantity: str = "accelerance", units: str | None = None, metadata: dict | None = None):
        freq = np.asarray(freq_hz, dtype=float)
        if freq.ndim != 1:
            raise ShapeError(f"freq_hz must be 1-D; got shape {freq.shape}. Pass the frequency lines in Hz")
        if freq.size > 1 and np.any(np.diff(freq) <= 0):
            raise ModalabValueError("freq_hz must increase strictly; sort the lines (np.argsort) before building an FRF")
        Hc = np.asarray(H)
        if not np.iscomplexobj(Hc):
            Hc = Hc.astype(complex)
        if Hc.ndim != 3:
            raise ShapeError(f"H must have shape (n_out, n_in, n_freq); got {Hc.shape}. "
                             "Use H[:, None, :] for a single reference")
        resp, ref = parse_dofs(responses), parse_dofs(references)
        want = (len(resp), len(ref), freq.size)
        if Hc.shape != want:
            raise ShapeError(f"H has shape {Hc.shape} but the labels and freq_hz call for {want} "
                             "(n_responses, n_references, n_freq)")
        coh = None
        if coherence is not None:
            coh = np.asarray(coherence, dtype=float)
            if coh.shape != want:
                raise ShapeError(f"coherence has shape {coh.shape}; expected {want} like H")
        for name, labels in (("responses", resp), ("references", ref)):
            if len({(d.node, d.axis) for d in labels}) != len(labels):
                raise ModalabValueError(f"duplicate DOF labels in {name}: {[str(d) for d in labels]}; "
                                        "each DOF may appear once per axis")
        self.freq_hz = freq
        self.H = Hc
        self.responses: list[Dof] = resp
        self.references: list[Dof] = ref
        self.coherence = coh
        self.quantity = check_quantity(quantity)
        self.units = units or QUANTITY_UNITS[self.quantity]
        self.metadata = dict(metadata or {})

    # ------------------------------------------------------------ construction
    @classmethod
    def from_arrays(cls, freq_hz, H, responses, references, coherence=None, **kw) -> "FRF":
        """Build from arrays; a 2-D ``H`` (n_out, n_freq) is taken as a single reference."""
        Ha = np.asarray(H)
        if Ha.ndim == 2:
            Ha = Ha[:, None, :]
            if coherence is not None and np.ndim(coherence) == 2:
                coherence = np.asarray(coherence)[:, None, :]
        elif Ha.ndim == 1:
            Ha = Ha[None, None, :]
            if coherence is not None and np.ndim(coherence) == 1:
                coherence = np.asarray(coherence)[None, None, :]
        return cls(freq_hz=freq_hz, H=Ha, responses=responses, references=references,
                   coherence=coherence, **kw)

    @classmethod
    def from_uff(cls, path, **kw) -> "FRF":
        """Read FRFs (dataset 58/58b, func_type 4) and coherence (func_type 6) from a universal file."""
        from .uff import read_frf

        return read_frf(path, **kw)

    def to_uff(self, path, **kw) -> None:
        """Write FRFs and coherence as dataset 58 (binary 58b by default)."""
        from .uff import write_frf

        write_frf(path, self, **kw)

    def copy(self) -> "FRF":
        return copy.deepcopy(self)

    def _replace(self, **kw) -> "FRF":
        args = dict(freq_hz=self.freq_hz, H=self.H, responses=self.responses, references=self.references,
                    coherence=self.coherence, quantity=self.quantity, units=self.units,
                    metadata=copy.deepcopy(self.metadata))
        args.update(kw)
        return FRF(**args)

    # ------------------------------------------------------------ properties
    @property
    def shape(self) -> tuple[int, int, int]:
        return self.H.shape

    @property
    def n_out(self) -> int:
        return self.H.shape[0]

    @property
    def n_in(self) -> int:
        return self.H.shape[1]

    @property
    def n_freq(self) -> int:
        return self.H.shape[2]

    @property
    def omega(self) -> np.ndarray:
        """Frequency lines in rad/s."""
        return 2 * np.pi * self.freq_hz

    def __repr__(self) -> str:
        fr = f"{self.freq_hz[0]:.4g}-{self.freq_hz[-1]:.4g} Hz" if self.n_freq else "empty"
        return (f"FRF({self.n_out} responses x {self.n_in} references x {self.n_freq} lines, {fr}, "
                f"{self.quantity} [{self.units}], coherence={'yes' if self.coherence is not None else 'no'})")

    # ------------------------------------------------------------ selection
    def get(self, response, reference) -> np.ndarray:
        """One FRF as a 1-D complex array; a label of opposite sign negates it."""
        (i,), (si,) = locate(self.responses, [response], "response DOF")
        (j,), (sj,) = locate(self.references, [reference], "reference DOF")
        return si * sj * self.H[i, j]

    def select(self, responses=None, references=None) -> "FRF":
        """Sub-set by DOF labels, in the order given; opposite signs negate the data."""
        ii, si = (list(range(self.n_out)), [1] * self.n_out) if responses is None else \
            locate(self.responses, responses, "response DOF")
        jj, sj = (list(range(self.n_in)), [1] * self.n_in) if references is None else \
            locate(self.references, references, "reference DOF")
        sign = np.outer(si, sj)[:, :, None]
        H = self.H[np.ix_(ii, jj)] * sign
        coh = None if self.coherence is None else self.coherence[np.ix_(ii, jj)]
        rl = list(self.responses) if responses is None else parse_dofs(responses)
        rf = list(self.references) if references is None else parse_dofs(references)
        out = self._replace(H=H, coherence=coh, responses=rl, references=rf)
        var = self._variance()
        if var is not None:
            out.metadata["H_variance"] = var[np.ix_(ii, jj)]
        return out

    def _variance(self):
        """``metadata['H_variance']`` when it has H's shape (else None: left as it is)."""
        v = self.metadata.get("H_variance")
        if v is None:
            return None
        v = np.asarray(v)
        return v if v.shape == self.H.shape else None

    def band(self, lo_hz: float | None = None, hi_hz: float | None = None) -> "FRF":
        """Lines with ``lo_hz <= f <= hi_hz``."""
        lo = -np.inf if lo_hz is None else float(lo_hz)
        hi = np.inf if hi_hz is None else float(hi_hz)
        if lo >= hi:
            raise ModalabValueError(f"band {lo_hz}..{hi_hz} Hz is empty; give LO < HI")
        m = (self.freq_hz >= lo) & (self.freq_hz <= hi)
        if not m.any():
            raise ModalabValueError(f"no frequency lines in {lo_hz}..{hi_hz} Hz; the data spans "
                                    f"{self.freq_hz[0]:.4g}..{self.freq_hz[-1]:.4g} Hz")
        coh = None if self.coherence is None else self.coherence[..., m]
        out = self._replace(freq_hz=self.freq_hz[m], H=self.H[..., m], coherence=coh)
        var = self._variance()
        if var is not None:
            out.metadata["H_variance"] = var[..., m]
        return out

    def transpose(self) -> "FRF":
        """Swap responses and references: H_ij -> H_ji (Maxwell reciprocity)."""
        coh = None if self.coherence is None else self.coherence.transpose(1, 0, 2)
        return self._replace(H=self.H.transpose(1, 0, 2), coherence=coh,
                             responses=self.references, references=self.responses)

    def to(self, quantity: str) -> "FRF":
        """Convert to receptance, mobility or accelerance exactly (H·(iω)^k); NaN where undefined (ω = 0)."""
        q = check_quantity(quantity)
        if q == self.quantity:
            return self.copy()
        fac = quantity_factor(self.quantity, q, self.omega)
        return self._replace(H=self.H * fac, quantity=q, units=QUANTITY_UNITS[q])

    def real_part_sum(self) -> np.ndarray:
        """Sum of |H| over all FRFs (a quick mode indicator)."""
        return np.abs(self.H).reshape(-1, self.n_freq).sum(axis=0)

    def cmif(self, k: int | None = None) -> np.ndarray:
        """Complex mode indicator function: singular values of H(ω), shape (min(n_out, n_in), n_freq)."""
        s = np.linalg.svd(self.H.transpose(2, 0, 1), compute_uv=False)
        return s.T if k is None else s.T[:k]


def concat(frfs: Sequence[FRF], axis: str = "responses") -> FRF:
    """Concatenate FRFs along ``'responses'`` or ``'references'``; frequency axes must agree."""
    if not frfs:
        raise ModalabValueError("concat needs at least one FRF")
    first = frfs[0]
    ax = {"responses": 0, "references": 1}.get(axis)
    if ax is None:
        raise ModalabValueError(f"axis {axis!r} unknown; use 'responses' or 'references'")
    for f in frfs[1:]:
        if f.freq_hz.shape != first.freq_hz.shape or not np.allclose(f.freq_hz, first.freq_hz, rtol=1e-9, atol=1e-12):
            raise ShapeError("frequency axes differ; resample or band-select to common lines before concatenating")
        if f.quantity != first.quantity:
            f = f.to(first.quantity)
        other = f.references if ax == 0 else f.responses
        mine = first.references if ax == 0 else first.responses
        if [(d.node, d.axis) for d in other] != [(d.node, d.axis) for d in mine]:
            raise ShapeError(f"the {'references' if ax == 0 else 'responses'} differ between the FRFs; "
                             "select common DOFs first")
    conv = [f if f.quantity == first.quantity else f.to(first.quantity) for f in frfs]
    # align signs of the shared axis with the first FRF
    aligned = []
    for f in conv:
        if ax == 0:
            aligned.append(f.select(references=first.references))
        else:
            aligned.append(f.select(responses=first.responses))
    H = np.concatenate([f.H for f in aligned], axis=ax)
    coh = None
    if all(f.coherence is not None for f in aligned):
        coh = np.concatenate([f.coherence for f in aligned], axis=ax)
    labels = sum([(f.responses if ax == 0 else f.references) for f in aligned], [])
    kw = {"responses": labels} if ax == 0 else {"references": labels}
    return first._replace(H=H, coherence=coh, **kw)
