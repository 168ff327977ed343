"""Eigendynamic constraint method, thesis section 3.2.1 (Eq. 3.33–3.39).

The measured modes must satisfy the eigen-equation and the mass
normalisation of the updated model (Eq. 3.33–3.35).  With
``ΔM = Σ a_i M_i``, ``ΔK = Σ b_i K_i`` (Eq. 3.31; here ``∂M/∂p_i``, ``∂K/∂p_i`` of
any :class:`~updating.fe.parametric.ParametricModel`) each measured mode ``r``
gives N + 1 linear equations (Eq. 3.38), stacked over the modes (Eq. 3.39)
and solved by least squares (Eq. 3.32):

    Σ_i Δp_i (ω_r² ∂M/∂p_i − ∂K/∂p_i) φ_r = (K_A − ω_r² M_A) φ_r            (3.36)
    Σ_i Δp_i φ_rᵀ ∂M/∂p_i φ_r            = 1 − φ_rᵀ M_A φ_r                (3.37)

Sign note: the thesis prints the right-hand sides as ``ω²Mφ − Kφ`` and
``φᵀMφ − 1``; substituting ``K_A + ΔK``, ``M_A + ΔM`` into (3.33)–(3.34) gives the
signs above (with the printed ones the correction has the wrong sign).
Equation (3.37) applies only to mass-normalised shapes; for other scalings
it is dropped and the scale between mass and stiffness must come from the
parameterisation itself.

The shapes must be known at all model DOFs: incomplete measured shapes are
expanded with Kidder's method (Eq. 2.45–2.48) using the current model, and
for non-linear parameterisations the derivatives are re-evaluated; either
way the method iterates until the parameters stop changing.  For a linear
:class:`~updating.fe.parametric.MatrixModel` and complete exact data one step is exact.

Limitation (measured on the six-DOF case): with only DOFs 2–4 measured and
all 16 parameters free, the expansion–solution iteration collapses to the
trivial solution p = 0 (which satisfies (3.36) for any shape); use complete
shapes, fewer parameters, or the MCI / inverse eigensensitivity methods there.

Rows are scaled so that the blocks are dimensionless: (3.36) of mode r by
``1/(ω_r² ‖M_A φ_r‖)``·√N and (3.37) by 1.
"""
from __future__ import annotations

import logging

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from modalab.core.dense import use_dense
from modalab.core.errors import ModalabValueError, NotFittedError, ShapeError
from modalab.core.modes import ModeSet

from updating.fe.sensitivity import StackedDerivatives
from updating.fe.parametric import parameter_indices
from updating.correlation.dofmap import observation_matrix
from updating.correlation.metrics import mac, observability, pair_modes
from updating.fe.sensitivity import solve_modes

log = logging.getLogger(__name__)

__all__ = ["kidder_expand", "eigendynamic_system", "EigendynamicConstraint"]


def kidder_expand(K, M, omega, phi_measured, measured) -> np.ndarray:
    """Kidder's expansion, Eq. (2.47)–(2.48): ``φ_s = −(K_ss − ω²M_ss)⁻¹(K_sp − ω²M_sp) φ_p`` per mode.

    ``phi_measured`` (n_meas, m) on the model rows ``measured``; returns (N, m).
    """
    K = sp.csr_matrix(K)
    M = sp.csr_matrix(M)
    n = K.shape[0]
    measured = np.asarray(measured, int)
    s = np.setdiff1d(np.arange(n), measured)
    P = np.asarray(phi_measured, float)
    if P.ndim == 1:
        P = P[:, None]
    omega = np.atleast_1d(np.asarray(omega, float))
    if P.shape != (measured.size, omega.size):
        raise ShapeError(f"phi_measured has shape {P.shape}; expected ({measured.size}, {omega.size})")
    out = np.zeros((n, omega.size))
    out[measured] = P
    if s.size == 0:
        return out
    for r, w in enumerate(omega):
        A = (K - w ** 2 * M).tocsr()
        Ass = A[s][:, s].toarray() if use_dense(n, "eigen") else A[s][:, s]
        rhs = -(A[s][:, measured] @ P[:, r])
        if sp.issparse(Ass):
            out[s, r] = spla.spsolve(Ass.tocsc(), rhs)
        else:
            out[s, r] = sla.solve(Ass, rhs)
    return out


def eigendynamic_system(model, phi_X: np.ndarray, omega_X: np.ndarray, p=None, *, params=None,
                        mass_normalised: bool = True):
    """Stacked Eq. (3.39): returns (A, δ) with A (m(N+1) × P) [or m·N × P without (3.37)], row-scaled."""
    p = np.asarray(model.p0 if p is None else p, float)
    st = model.structure(p)
    K, M = st.K.tocsr(), st.M.tocsr()
    n = K.shape[0]
    phi = np.asarray(phi_X, float)
    w = np.asarray(omega_X, float)
    sd = StackedDerivatives(model.derivatives(p), n)
    idx = np.arange(sd.P) if params is None else np.asarray(params, int)
    blocks, rhs = [], []
    for r in range(phi.shape[1]):
        x = phi[:, r]
        Mx = M @ x
        sc = np.sqrt(n) / max(w[r] ** 2 * np.linalg.norm(Mx), 1e-300)
        B = (w[r] ** 2 * sd.columns("M", x, idx) - sd.columns("K", x, idx)).toarray()
        blocks.append(B * sc)
        rhs.append((K @ x - w[r] ** 2 * Mx) * sc)
        if mass_normalised:
            blocks.append(sd.quadratic("M", x)[idx][None, :])
            rhs.append(np.array([1.0 - x @ Mx]))
    return np.vstack(blocks), np.concatenate(rhs)


class EigendynamicConstraint:
    """Eigendynamic constraint updater (thesis 3.2.1).

    Parameters
    ----------
    params : names or indices of the parameters to update (default all).
    max_iter, tol : iterations (re-expansion / re-linearisation) and the
        convergence threshold on the largest relative parameter change.

    ``fit(model, test_modes, dofmap=None)``: ``test_modes`` a :class:`~modalab.core.modes.ModeSet`
    (real shapes used).  Mass-normalised sets (``scaling='unit_modal_mass'``) use (3.37);
    others only (3.36).  Test DOFs are located on the model DOFs by label (signs honoured).

    Attributes: ``p_``, ``params_``, ``history_`` (parameter vectors), ``converged_``,
    ``n_iter_``, ``residual_norm_`` (of the final linear system).
    """

    def __init__(self, params=None, *, max_iter: int = 50, tol: float = 1e-10, mac_min: float = 0.5,
                 pairing: dict | None = None):
        self.mac_min = mac_min
        self.pairing = pairing
        self.params = params
        self.max_iter = max_iter
        self.tol = tol

    def fit(self, model, test_modes: ModeSet, dofmap=None) -> "EigendynamicConstraint":

        if not isinstance(test_modes, ModeSet):
            raise ModalabValueError(f"test_modes must be a ModeSet; got {type(test_modes).__name__}")
        if not test_modes.has_shapes:
            raise ModalabValueError("the eigendynamic method needs measured mode shapes; this test set has "
                                    "frequencies only: use inverse eigensensitivity (frequencies only)")
        C = observation_matrix(test_modes.dofs, model.dofs, dofmap).tocsr()
        n = len(model.dofs)
        # only test modes with an analysis partner (the one pairing rule) enter the equations: a spurious or
        # unmatched test mode would be forced onto the model as if it were one of its modes

        sol = solve_modes(model, np.asarray(model.p0, float), min(n, max(2 * test_modes.n_modes,
                                                                             test_modes.n_modes + 6)))
        Pa = np.asarray(C @ sol.phi)
        pr = pair_modes(mac(Pa, test_modes.real_shapes), sol.freq_hz, test_modes.freq_hz, mac_min=self.mac_min,
                        observability=observability(Pa, sol.phi, model.dofs),
                        mode_shapes=(Pa, test_modes.real_shapes), **(self.pairing or {}))
        self.pairing_ = pr
        if not pr.pairs:
            raise ModalabValueError(f"no test mode pairs with an analysis mode ({pr.method}); check the DOF map")
        if pr.unpaired_test:
            log.warning("eigendynamic: test modes %s have no analysis partner and are left out",
                        [j + 1 for j in pr.unpaired_test])
        test_modes = test_modes.select_modes(pr.test_index)
        # each test DOF must be one signed model DOF for the partition of Kidder's expansion
        if np.any(np.diff(C.indptr) != 1):
            raise ModalabValueError("the eigendynamic method needs test DOFs that coincide with model DOFs "
                                    "(no oblique sensors); map them with a DOF map")
        measured = C.indices
        signs = C.data
        if len(set(measured.tolist())) != measured.size:
            raise ModalabValueError("two test DOFs map onto the same model DOF")
        phi_m = test_modes.real_shapes * signs[:, None]
        w = test_modes.omega
        mn = test_modes.scaling == "unit_modal_mass"
        if not mn:
            log.info("test modes are not mass-normalised: Eq. (3.37) is dropped")
        idx = parameter_indices(model, self.params)
        p = np.array(model.p0, float)
        scale = np.where(p[idx] != 0, np.abs(p[idx]), 1.0)
        self.history_ = [p.copy()]
        self.converged_ = False
        change = np.inf
        it = 0
        for it in range(1, self.max_iter + 1):
            st = model.structure(p)
            phi = kidder_expand(st.K, st.M, w, phi_m, measured) if measured.size < n else \
                np.zeros((n, w.size))
            if measured.size == n:
                phi[measured] = phi_m
            A, d = eigendynamic_system(model, phi, w, p, params=idx, mass_normalised=mn)
            As = A * scale[None, :]
            dx = np.linalg.lstsq(As, d, rcond=None)[0]
            p = p.copy()
            p[idx] += dx * scale
            change = float(np.max(np.abs(dx)))
            self.history_.append(p.copy())
            if change < self.tol:
                self.converged_ = True
                break
        if not self.converged_:
            log.warning("eigendynamic constraint method: no convergence in %d iterations (change %.3g)", it, change)
        self.residual_norm_ = float(np.linalg.norm(As @ dx - d))
        self.p_ = p
        self.params_ = idx
        self.n_iter_ = it
        return self

    def _check(self):
        if not hasattr(self, "p_"):
            raise NotFittedError("fit the EigendynamicConstraint first")
