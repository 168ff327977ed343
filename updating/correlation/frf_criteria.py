"""FRF correlation criteria: FRAC, CSAC, CSF and :func:`frf_correlation` (analysis FRF aligned on the test
DOFs, :class:`FrfCorrelation`).

Split out of :mod:`updating.correlation.metrics` (which re-exports these names: import them from there).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from modalab.core.errors import ModalabValueError, ShapeError
from modalab.core.frf import FRF
from modalab.core.structure import Structure
from updating.correlation.dofmap import as_dofmap
from updating.correlation.shape_criteria import _TINY

log = logging.getLogger(__name__)


# ------------------------------------------------------------------ FRF criteria
def _frf_arrays(a, x):
    Ha = a.H if isinstance(a, FRF) else np.asarray(a)
    Hx = x.H if isinstance(x, FRF) else np.asarray(x)
    if Ha.shape != Hx.shape:
        raise ShapeError(f"FRF arrays have shapes {Ha.shape} and {Hx.shape}; expected equal shapes "
                         "(n_out, n_in, n_freq). Align them with frf_correlation")
    if Ha.ndim == 1:
        Ha, Hx = Ha[None, None], Hx[None, None]
    elif Ha.ndim == 2:
        Ha, Hx = Ha[:, None], Hx[:, None]
    if Ha.ndim != 3:
        raise ShapeError(f"FRF arrays have {Ha.ndim} dimensions; expected (n_out, n_in, n_freq)")
    return Ha, Hx


def frac(analysis, test) -> np.ndarray:
    """Frequency Response Assurance Criterion per FRF, over the frequency lines.

    ``FRAC_ij = |Σ_ω H_x,ij H_a,ij*|² / (Σ_ω |H_x,ij|² Σ_ω |H_a,ij|²)`` — shape
    (n_out, n_in), values in [0, 1], 1 when the two FRFs are proportional.
    """
    Ha, Hx = _frf_arrays(analysis, test)
    num = np.abs(np.sum(Hx * Ha.conj(), axis=2)) ** 2
    den = np.sum(np.abs(Hx) ** 2, axis=2) * np.sum(np.abs(Ha) ** 2, axis=2)
    return np.clip(np.where(den > _TINY, num / np.where(den > _TINY, den, 1.0), 0.0), 0, 1)


def csac(analysis, test) -> np.ndarray:
    """Cross-Signature Assurance Criterion per frequency line (a MAC between the response vectors).

    ``CSAC(ω) = |H_x(ω)ᴴ H_a(ω)|² / ((H_xᴴH_x)(H_aᴴH_a))`` with all FRFs at ω
    stacked into one vector; shape (n_freq,), values in [0, 1].
    """
    Ha, Hx = _frf_arrays(analysis, test)
    a = Ha.reshape(-1, Ha.shape[2])
    x = Hx.reshape(-1, Hx.shape[2])
    num = np.abs(np.sum(x.conj() * a, axis=0)) ** 2
    den = np.sum(np.abs(x) ** 2, axis=0) * np.sum(np.abs(a) ** 2, axis=0)
    return np.clip(np.where(den > _TINY, num / np.where(den > _TINY, den, 1.0), 0.0), 0, 1)


def csf(analysis, test) -> np.ndarray:
    """Cross-Signature Scale Factor per frequency line: ``2|H_xᴴH_a| / (H_xᴴH_x + H_aᴴH_a)``.

    Sensitive to amplitude as well as shape; 1 only when the FRFs are equal in modulus and shape.
    """
    Ha, Hx = _frf_arrays(analysis, test)
    a = Ha.reshape(-1, Ha.shape[2])
    x = Hx.reshape(-1, Hx.shape[2])
    num = 2 * np.abs(np.sum(x.conj() * a, axis=0))
    den = np.sum(np.abs(x) ** 2, axis=0) + np.sum(np.abs(a) ** 2, axis=0)
    return np.clip(np.where(den > _TINY, num / np.where(den > _TINY, den, 1.0), 0.0), 0, 1)


def _warn_if_beta_differs(analysis: FRF, test: FRF) -> None:
    """Log a warning when the two FRFs were taken at different ``s = iω + β`` (exponential windows)."""
    ba, bt = analysis.window_beta_per_s, test.window_beta_per_s
    if not np.isclose(ba, bt, rtol=1e-9, atol=1e-12):
        log.warning("frf_correlation: the analysis FRF is at s = iω + %.6g 1/s but the test FRF at s = iω + %.6g "
                    "1/s (its exponential window's window_beta_per_s): the two are compared at different s and "
                    "differ by the window's decay alone; pass the Structure, or synthesise the analysis with "
                    "window_beta_per_s=test.window_beta_per_s", ba, bt)


@dataclass
class FrfCorrelation:
    """FRF correlation on the test labels: aligned FRFs, FRAC per FRF, CSAC and CSF per line."""

    analysis: FRF
    test: FRF
    frac: np.ndarray
    csac: np.ndarray
    csf: np.ndarray

    def to_dict(self) -> dict:
        return {"responses": [str(d) for d in self.test.responses],
                "references": [str(d) for d in self.test.references],
                "frac": self.frac.tolist(), "freq_hz": self.test.freq_hz.tolist(),
                "csac": self.csac.tolist(), "csf": self.csf.tolist(),
                "mean_frac": float(np.mean(self.frac)) if self.frac.size else None}


def frf_correlation(analysis, test: FRF, *, dofmap=None, rtol: float = 1e-9) -> FrfCorrelation:
    """Correlate analytical FRFs with measured ones on the test labels.

    Parameters
    ----------
    analysis : :class:`~modalab.core.frf.FRF` on model labels (same frequency lines as the test),
        or a :class:`~modalab.core.structure.Structure` whose exact FRFs are synthesised at the test lines, at
        the test's ``s = iω + β`` (its exponential window's ``window_beta_per_s``).
    test : measured FRF.
    dofmap : maps test labels onto model DOFs (oblique sensors allowed: ``H_t = C_o H_a C_iᵀ``).

    A ready analysis FRF whose ``window_beta_per_s`` differs from the test's was evaluated at another
    ``s = iω + β`` than the test was measured at: the comparison goes on (the criteria are defined for any
    two FRFs) with a logged warning naming both β; pass the Structure, or synthesise the analysis with
    ``window_beta_per_s=test.window_beta_per_s``.
    """
    if not isinstance(test, FRF):
        raise ModalabValueError(f"test: got {type(test).__name__}; expected a modalab.core.frf.FRF")
    dm = as_dofmap(dofmap)
    if isinstance(analysis, Structure):
        Co_full = dm.matrix(test.responses, analysis.dofs)
        Ci_full = dm.matrix(test.references, analysis.dofs)
        ro = np.unique(sp.csr_matrix(Co_full).indices)
        ri = np.unique(sp.csr_matrix(Ci_full).indices)
        # at the test's s = iω + β: an exponentially windowed test FRF is the transfer function there
        analysis = analysis.frf(test.freq_hz, responses=[analysis.dofs[i] for i in ro],
                                references=[analysis.dofs[i] for i in ri], quantity=test.quantity,
                                window_beta_per_s=test.window_beta_per_s)
    if not isinstance(analysis, FRF):
        raise ModalabValueError(f"analysis: got {type(analysis).__name__}; expected an FRF or a Structure")
    _warn_if_beta_differs(analysis, test)
    if analysis.freq_hz.shape != test.freq_hz.shape or not np.allclose(analysis.freq_hz, test.freq_hz, rtol=rtol,
                                                                        atol=0):
        raise ShapeError(f"the analysis FRF has {analysis.n_freq} lines ({analysis.freq_hz[:1]}..) but the test "
                         f"has {test.n_freq}; synthesise the analysis at the test lines "
                         "(Structure.frf(test.freq_hz, ...)) or pass the Structure itself")
    if analysis.quantity != test.quantity:
        analysis = analysis.to(test.quantity)
    Co = sp.csr_matrix(dm.matrix(test.responses, analysis.responses))
    Ci = sp.csr_matrix(dm.matrix(test.references, analysis.references))
    H = np.einsum("oa,abf,ib->oif", Co.toarray(), analysis.H, Ci.toarray(), optimize=True)
    aligned = FRF(freq_hz=test.freq_hz, H=H, responses=test.responses, references=test.references,
                  quantity=test.quantity, metadata={"source": "analysis on test DOFs"},
                  window_beta_per_s=analysis.window_beta_per_s)
    return FrfCorrelation(analysis=aligned, test=test, frac=frac(aligned, test), csac=csac(aligned, test),
                          csf=csf(aligned, test))
