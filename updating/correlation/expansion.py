"""Expansion of measured mode shapes onto all model DOFs — thesis section 2.1.2.

* :func:`kidder` — Kidder's dynamic expansion, the inverse of Guyan reduction at
  each mode's own frequency (eqs. 2.45–2.48):
  ``φ_s = -(K_ss - ω_r² M_ss)⁻¹ (K_sp - ω_r² M_sp) φ_p``; measured DOFs keep
  the measured values.  ``static=True`` uses ω = 0 (plain inverse Guyan).
* :func:`serep_expand` — SEREP expansion (eqs. 2.57–2.61):
  ``x = Φ Φ_p⁺ x_p``; every DOF, measured ones included, comes out of the fit
  (a smoothed version of the measurement when there are more sensors than modes).
* :func:`modal_expand` — expansion as a linear combination of chosen analytical
  modes (eqs. 2.49–2.56): ``ν = Φ₁₁⁺ φ₁`` (2.53), unmeasured part ``Φ₂₁ ν``
  (2.52, 2.56); by default the measured DOFs keep the measured values.  Pick the
  analytical modes that pair with the test modes (see
  :func:`updating.correlation.metrics.correlate`), as the thesis recommends.

Test modes are :class:`~modalab.core.modes.ModeSet` objects on the test labels;
a :class:`~updating.correlation.dofmap.DofMap` (or None for the same node numbers) maps them
onto the model DOFs.  SEREP and modal expansion accept oblique sensors (a test
DOF reading several model DOFs); Kidder needs each test DOF on one model DOF.
The expanded modes come back on the model labels, with the test frequencies,
damping and scaling.
"""
from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp

from modalab.core.dof import parse_dofs
from modalab.core.errors import ModalabValueError, ShapeError
from modalab.core.modes import ModeSet
from modalab.core.structure import Structure

from updating.correlation.dofmap import as_dofmap
from updating.correlation.reduction import _Factor, _sub, _dense, _square

__all__ = ["kidder", "serep_expand", "modal_expand"]

log = logging.getLogger(__name__)


def _model(model):
    if isinstance(model, Structure):
        return model.K, model.M, list(model.dofs)
    if isinstance(model, tuple) and len(model) == 3:
        K, M, dofs = model
        K = _square(K, "K")
        M = _square(M, "M", K.shape[0])
        dl = parse_dofs(dofs)
        if len(dl) != K.shape[0]:
            raise ShapeError(f"{len(dl)} DOF labels for a {K.shape[0]}x{K.shape[0]} model; give one per row")
        return K, M, dl
    raise ModalabValueError(f"model: got {type(model).__name__}; expected a Structure or a tuple (K, M, dofs)")


def _check_modes(test, what="test"):
    if not isinstance(test, ModeSet):
        raise ModalabValueError(f"{what} modes: got {type(test).__name__}; expected a modalab.core.modes.ModeSet")
    if test.n_modes == 0:
        raise ModalabValueError(f"the {what} mode set is empty; nothing to expand")


def _result(test: ModeSet, shapes, dofs, method: str, **meta) -> ModeSet:
    out = ModeSet(freq_hz=test.freq_hz, damping=test.damping, shapes=shapes, dofs=dofs,
                  participation=test.participation, references=test.references,
                  scaling=test.scaling if test.scaling != "unit_max" else "arbitrary",
                  indicators=test.indicators, metadata=dict(test.metadata))
    out.metadata["expansion"] = {"method": method, "measured_dofs": [str(d) for d in test.dofs], **meta}
    return out


def kidder(model, test: ModeSet, *, dofmap=None, static: bool = False) -> ModeSet:
    """Kidder's dynamic expansion (inverse Guyan reduction at each test frequency), eq. 2.48.

    Parameters
    ----------
    model : :class:`~modalab.core.structure.Structure` or ``(K, M, dofs)`` with dense or sparse matrices.
    test : measured modes on test labels (real or complex shapes).
    dofmap : :class:`~updating.correlation.dofmap.DofMap`, dict, file path or None (same node numbers).
    static : use ω = 0 for every mode (Guyan's static expansion, eq. 2.5).

    Returns the expanded modes on the model DOFs; measured DOFs hold the
    measured values (divided by the map factor, so ``C x = x_test``).
    """
    _check_modes(test)
    K, M, dofs = _model(model)
    n = K.shape[0]
    idx, fac = as_dofmap(dofmap).selection(test.dofs, dofs)
    if np.unique(idx).size != idx.size:
        raise ModalabValueError("two test DOFs map onto the same model DOF; Kidder expansion needs distinct "
                                "measured DOFs. Drop the duplicate or average it first")
    if idx.size >= n:
        raise ModalabValueError(f"{idx.size} measured DOFs for a {n}-DOF model: nothing to expand")
    mask = np.ones(n, bool)
    mask[idx] = False
    s = np.flatnonzero(mask)
    phi_p = np.asarray(test.shapes) / fac[:, None]
    Kss, Ksp = _sub(K, s, s), _dense(_sub(K, s, idx))
    Mss, Msp = _sub(M, s, s), _dense(_sub(M, s, idx))
    out = np.zeros((n, test.n_modes), dtype=complex if np.iscomplexobj(phi_p) else float)
    out[idx] = phi_p
    static_fac = _Factor(Kss, "the slave stiffness K_ss") if static else None
    for r in range(test.n_modes):
        w2 = 0.0 if static else (2 * np.pi * test.freq_hz[r]) ** 2
        if static:
            f = static_fac
        else:
            A = Kss - w2 * Mss
            try:
                f = _Factor(sp.csc_matrix(A) if sp.issparse(A) else A, "K_ss - ω²M_ss")
            except ModalabValueError:
                raise ModalabValueError(
                    f"K_ss - ω²M_ss is singular at test mode {r + 1} ({test.freq_hz[r]:.6g} Hz): that frequency is a "
                    "natural frequency of the model with the measured DOFs fixed. Add measured DOFs, or use "
                    "serep_expand/modal_expand for this mode") from None
        out[s, r] = -f.solve((Ksp - w2 * Msp) @ phi_p[:, r])      # eq. 2.47 / 2.48
    return _result(test, out, dofs, "kidder-static" if static else "kidder")


def _fit_matrix(analysis: ModeSet, test: ModeSet, dofmap, modes, rcond):
    _check_modes(test)
    _check_modes(analysis, "analysis")
    sel = analysis if modes is None else analysis.select_modes(np.asarray(modes))
    phi = sel.real_shapes if np.iscomplexobj(sel.shapes) else np.asarray(sel.shapes, float)
    C = as_dofmap(dofmap).matrix(test.dofs, sel.dofs)
    phi_p = np.asarray(C @ phi)                                  # Φ_p (2.58) / Φ₁₁ (2.49)
    n_meas, m = phi_p.shape
    if n_meas < m:
        raise ModalabValueError(
            f"{m} analytical modes but only {n_meas} measured DOFs: the pseudo-inverse of eq. 2.53 is rank "
            "deficient and the expansion physically meaningless. Keep at most as many analytical modes as "
            "measured DOFs (e.g. the modes paired with the test modes)")
    rank = np.linalg.matrix_rank(phi_p, tol=rcond * max(np.abs(phi_p).max(), 1e-300) * max(phi_p.shape))
    if rank < m:
        raise ModalabValueError(f"the analytical modes are linearly dependent at the measured DOFs (rank {rank} "
                                f"of {m}); drop modes the sensors cannot distinguish or add sensors")
    return sel, phi, C, np.linalg.pinv(phi_p, rcond=rcond)


def serep_expand(analysis: ModeSet, test: ModeSet, *, dofmap=None, modes=None, rcond: float = 1e-10) -> ModeSet:
    """SEREP expansion, eqs. 2.57–2.61: ``x = Φ Φ_p⁺ x_p`` with ``Φ_p = C Φ``.

    Parameters
    ----------
    analysis : analytical modes on the model DOFs (Φ).
    test : measured modes on the test labels (x_p).
    dofmap : maps test labels onto model DOFs (oblique sensors allowed).
    modes : indices of the analytical modes to use (default all); at most as many as measured DOFs.
    rcond : pseudo-inverse cut-off.

    Exact (to round-off) when the test modes are combinations of the used analytical modes.
    """
    sel, phi, C, pinv = _fit_matrix(analysis, test, dofmap, modes, rcond)
    q = pinv @ np.asarray(test.shapes)                            # eq. 2.59
    return _result(test, phi @ q, sel.dofs, "serep", analytical_modes=_mode_ids(analysis, modes))


def modal_expand(analysis: ModeSet, test: ModeSet, *, dofmap=None, modes=None, keep_measured: bool = True,
                 rcond: float = 1e-10) -> ModeSet:
    """Expansion by a linear combination of analytical modes, eqs. 2.49–2.56.

    ``ν^r = Φ₁₁⁺ φ₁^r`` (2.53) fits the measured part, the unmeasured DOFs get
    ``Φ₂₁ ν^r`` (2.52; rotations in 2.56).  With ``keep_measured=True`` the
    measured model DOFs keep the measurement (hybrid vector); with False they get
    the smoothed fit ``Φ₁₁ ν`` of eq. 2.50 (then identical to SEREP expansion).
    Oblique sensors cannot be substituted and always take the fitted values.

    Parameters as for :func:`serep_expand`; ``modes`` should select the analytical
    modes paired with the test modes.
    """
    sel, phi, C, pinv = _fit_matrix(analysis, test, dofmap, modes, rcond)
    x_t = np.asarray(test.shapes)
    nu = pinv @ x_t                                               # eq. 2.53 / 2.55
    out = phi @ nu                                                # eqs. 2.50-2.52, 2.56
    if keep_measured:
        Cc = sp.csr_matrix(C)
        for i in range(Cc.shape[0]):
            a, b = Cc.indptr[i], Cc.indptr[i + 1]
            if b - a == 1 and Cc.data[a] != 0:
                out[Cc.indices[a]] = x_t[i] / Cc.data[a]
    return _result(test, out, sel.dofs, "modal", keep_measured=keep_measured,
                   analytical_modes=_mode_ids(analysis, modes))


def _mode_ids(analysis: ModeSet, modes):
    return list(range(analysis.n_modes)) if modes is None else [int(i) for i in np.arange(analysis.n_modes)[modes]]
