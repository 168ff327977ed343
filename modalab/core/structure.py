"""Structure descriptions shared by the simulator and the later stages.

:class:`Structure` holds sparse mass ``M``, stiffness ``K``, optional viscous
damping ``C`` and hysteretic (structural) damping ``D`` on labelled DOFs, and
computes its exact FRFs.  The equation of motion is

    M x'' + C x' + (K + iD) x = f            (D only meaningful in harmonic motion)

so the receptance is ``H(ω) = (K + iD + iωC − ω²M)⁻¹``.

:class:`ModalModel` is the pole–residue form of the same dynamics,

    H(s) = Σ_k  r_k l_kᵀ / (s − λ_k)  +  Σ_r φ_r φ_rᵀ / s²,

with every pole listed explicitly (no implied conjugates, so hysteretic damping
is represented exactly for s = iω, ω > 0) and undamped rigid-body modes kept
as the double pole at zero.  It is exact when all modes are kept: the modal
damping matrices are diagonalised analytically when they are diagonal
(proportional damping) and through the state-space eigenproblem in modal
coordinates otherwise.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .dense import use_dense
from .dof import Dof, locate, parse_dofs
from .eigen import dense_modes, drop_mechanisms, lanczos_modes, massless_dofs, restore
from .errors import ModalabValueError, ShapeError
from .frf import FRF, check_window_beta
from .units import QUANTITY_UNITS, check_quantity

__all__ = ["Structure", "ModalModel"]

_ORDER = {"receptance": 0, "mobility": 1, "accelerance": 2}


def _as_sparse(A, name, n=None):
    if A is None:
        return None
    S = sp.csr_matrix(A, dtype=float) if not np.iscomplexobj(A) else sp.csr_matrix(A)
    if S.shape[0] != S.shape[1]:
        raise ShapeError(f"{name} must be square; got {S.shape}")
    if n is not None and S.shape[0] != n:
        raise ShapeError(f"{name} is {S.shape[0]}x{S.shape[0]} but the model has {n} DOFs")
    return S


def _zero_energy(A, phi: np.ndarray) -> np.ndarray:
    """Per column of ``phi``: is the energy ``φᵀAφ`` zero within the rounding of its own evaluation,
    ``|φᵀAφ| ≤ n·ε·|φ|ᵀ|A||φ|`` (n DOFs, ε the machine epsilon: the worst-case error bound of a sum of n
    products, N. J. Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., SIAM 2002, §3.1)?
    All True for ``A`` None.

    A scale-free test of a rigid-body mode: the computed rigid-body modes of the demo project's frame
    (``examples/demo_project/nominal.bdf``) give 0.2·ε|φ|ᵀ|K||φ| and less, its pitch and roll on three 500 N/m
    bungees (0.105 and 0.239 Hz) 1.5·10⁵ and 3.9·10⁶ times it.  A threshold on the frequency relative to
    the highest one, used before (ω < 10⁻⁶ ω_max), took both for rigid-body modes: the frame's stiff rigid links
    put ω_max at 787 kHz, so anything below 0.79 Hz counted as free, and the simulated lab tested a structure
    whose pitch and roll were free (the direct solve of the same model differed by a factor 3.8 at 0.25 Hz)."""
    if A is None:
        return np.ones(phi.shape[1], bool)
    A = sp.csr_matrix(A)
    energy = np.einsum("ij,ij->j", phi, A @ phi).real
    scale = np.einsum("ij,ij->j", np.abs(phi), abs(A) @ np.abs(phi))
    return np.abs(energy) <= phi.shape[0] * np.finfo(float).eps * scale


@dataclass
class ModalModel:
    """Pole–residue model: ``H(s) = Σ right[:,k] left[k,:]/(s−poles[k]) + rigid rigidᵀ/s²`` (receptance).

    ``dofs`` labels the rows of ``right`` and the columns of ``left``.
    ``hysteretic`` is True when the model contains structural damping: its
    poles then reproduce H(iω) for ω > 0 only and have no causal impulse response.
    """

    poles: np.ndarray
    right: np.ndarray
    left: np.ndarray
    rigid: np.ndarray
    dofs: list
    hysteretic: bool = False

    @property
    def n_dof(self) -> int:
        return len(self.dofs)

    def _factors(self, responses, references):
        """Labels and the signed rows of the residue factors for the requested DOFs."""
        resp = self.dofs if responses is None else parse_dofs(responses)
        refs = self.dofs if references is None else parse_dofs(references)
        io, so = locate(self.dofs, resp, "response DOF", "the model")
        ii, si = locate(self.dofs, refs, "reference DOF", "the model")
        so, si = np.asarray(so)[:, None], np.asarray(si)[:, None]
        return (resp, refs, self.right[io] * so, self.left[:, ii] * si.T, self.rigid[io] * so,
                self.rigid[ii] * si)

    def frf(self, freq_hz, responses=None, references=None, quantity: str = "accelerance",
            chunk: int = 2048, *, window_beta_per_s: float = 0.0) -> FRF:
        """Exact FRFs at ``freq_hz`` between the labelled DOFs (all DOFs by default), at ``s = iω + β``.

        ``window_beta_per_s`` β (1/s, default 0): the decay of an exponential window ``e^{−βt}`` on the
        measured records; the windowed FRF is the transfer function at ``s = iω + β``
        (:attr:`FRF.s <modalab.core.frf.FRF.s>`), so a model compared with it is evaluated there (pass the
        measured FRF's ``window_beta_per_s``).  The result carries β."""
        q = check_quantity(quantity)
        freq = np.asarray(freq_hz, dtype=float)
        beta = check_window_beta(window_beta_per_s)
        resp, refs, R, L, G, Gi = self._factors(responses, references)
        order = _ORDER[q]
        H = np.empty((len(resp), len(refs), freq.size), complex)
        for a in range(0, freq.size, chunk):
            s = 2j * np.pi * freq[a:a + chunk] + beta
            with np.errstate(divide="ignore", invalid="ignore"):
                w = s[None, :] ** order / (s[None, :] - self.poles[:, None])      # (m, f)
                Hc = np.einsum("ok,ki,kf->oif", R, L, w, optimize=True)
                if G.shape[1]:
                    g = s ** (order - 2) if order < 2 else np.ones_like(s)
                    Hc = Hc + np.einsum("or,ir,f->oif", G, Gi, g, optimize=True)
            H[..., a:a + chunk] = Hc
        return FRF(freq_hz=freq, H=H, responses=resp, references=refs, quantity=q,
                   metadata={"estimator": "exact"}, window_beta_per_s=beta)

    def impulse_response(self, t, responses=None, references=None) -> np.ndarray:
        """Receptance impulse responses h(t) (n_out, n_in, n_t), exact for viscous damping, t ≥ 0."""
        if self.hysteretic:
            raise ModalabValueError("a model with hysteretic damping has no causal impulse response; "
                                    "synthesise in the frequency domain instead (ModalModel.frf)")
        t = np.asarray(t, dtype=float)
        _, _, R, L, G, Gi = self._factors(responses, references)
        h = np.einsum("ok,ki,kt->oit", R, L, np.exp(self.poles[:, None] * t[None, :]), optimize=True).real
        if self.rigid.shape[1]:
            h = h + np.einsum("or,ir,t->oit", G, Gi, t)
        return h


class Structure:
    """Mass, stiffness and damping on labelled DOFs.

    Parameters (keyword-only)
    ----------
    M, K : (n, n) symmetric matrices (dense or sparse) in kg and N/m (kg·m², N·m/rad for rotations).
    dofs : n DOF labels, one per row (positive directions).
    C : optional viscous damping matrix, N·s/m.
    D : optional hysteretic damping matrix (imaginary stiffness), N/m.
    coords : optional {node: (x, y, z)} in m, for plots and geometry export.
    name : free text.
    """

    def __init__(self, *, M, K, dofs, C=None, D=None, coords: dict | None = None, name: str = ""):
        self.dofs: list[Dof] = parse_dofs(dofs)
        n = len(self.dofs)
        self.M = _as_sparse(M, "M", n)
        self.K = _as_sparse(K, "K", n)
        self.C = _as_sparse(C, "C", n)
        self.D = _as_sparse(D, "D", n)
        for nm, A in (("M", self.M), ("K", self.K), ("C", self.C), ("D", self.D)):
            if A is None:
                continue
            asym = abs(A - A.T).max() if A.nnz else 0.0
            scale = abs(A).max() if A.nnz else 1.0
            if asym > 1e-9 * max(scale, 1e-300):
                raise ModalabValueError(f"{nm} is not symmetric (max |A-Aᵀ| = {asym:.3g}); "
                                        "structural matrices must be symmetric")
        self.coords = dict(coords or {})
        self.name = name
        self._modal = None

    @property
    def n_dof(self) -> int:
        return len(self.dofs)

    def __repr__(self) -> str:
        damp = "+".join(x for x, A in (("C", self.C), ("D", self.D)) if A is not None) or "undamped"
        return f"Structure({self.name or 'unnamed'}: {self.n_dof} DOFs, {damp})"

    def index(self, dofs):
        """Row indices and signs of the given labels."""
        return locate(self.dofs, dofs)

    # ----------------------------------------------------------------- modes
    def normal_modes(self, n_modes: int | None = None):
        """Undamped natural frequencies ω (rad/s) and mass-normalised shapes Φ (n, m), ascending.

        All finite modes with ``n_modes=None``.  A positive definite M is solved directly (``eigh(K, M)``);
        a singular one — DOFs without mass, as Nastran's default lumped mass gives the rotations of a beam
        deck — by the shift-inverted form of :mod:`modalab.core.eigen`, which drops the infinite-frequency
        (massless) directions exactly and constrains massless mechanisms.  Above 2000 DOFs with ``n_modes``
        given: shift-invert Lanczos from a fixed start vector (deterministic).
        """
        n = self.n_dof
        if n_modes is not None and int(n_modes) < 1:
            raise ModalabValueError(f"n_modes = {n_modes}; expected at least 1")
        if n_modes is None or use_dense(n, "eigen") or int(n_modes) >= n - 1:
            if massless_dofs(self.M).size:
                return dense_modes(self.K, self.M, n_modes)
            Md, Kd = self.M.toarray(), self.K.toarray()
            try:
                w2, phi = sla.eigh(Kd, Md)
            except np.linalg.LinAlgError:
                # M is singular without a whole zero row: the shift-inverted solver handles it or says why not
                return dense_modes(self.K, self.M, n_modes)
            if n_modes is not None:
                w2, phi = w2[:n_modes], phi[:, :n_modes]
            w2 = np.where(w2 < 0, 0.0, w2)
            return np.sqrt(w2), phi
        w, phi, _ = lanczos_modes(self.K, self.M, int(n_modes))
        return w, phi

    def modal_model(self, n_modes: int | None = None) -> ModalModel:
        """Pole–residue model; exact with ``n_modes=None`` (all modes).

        A mode is a rigid-body mode (the double pole at zero) when its strain energy ``φᵀKφ`` and its damping
        energies ``φᵀCφ``, ``φᵀDφ`` are zero within the rounding of their own evaluation
        (:func:`_zero_energy`); every other mode keeps its poles, however slow (a test article's suspension).
        """
        if n_modes is None and self._modal is not None:
            return self._modal
        omega, phi = self.normal_modes(n_modes)
        m = omega.size
        Cm = phi.T @ (self.C @ phi) if self.C is not None else np.zeros((m, m))
        Dm = phi.T @ (self.D @ phi) if self.D is not None else np.zeros((m, m))
        wmax = max(omega.max(), 1e-300) if m else 1.0
        rigid = _zero_energy(self.K, phi) & _zero_energy(self.C, phi) & _zero_energy(self.D, phi)
        el = ~rigid
        phi_e = phi[:, el]
        K2 = np.diag(omega[el] ** 2) + 1j * Dm[np.ix_(el, el)]
        C2 = Cm[np.ix_(el, el)]
        me = int(el.sum())
        offdiag = (np.abs(C2 - np.diag(np.diag(C2))).max(initial=0.0) * wmax
                   + np.abs(Dm[np.ix_(el, el)] - np.diag(np.diag(Dm[np.ix_(el, el)]))).max(initial=0.0))
        if offdiag <= 1e-10 * max(wmax ** 2, 1e-300):
            c, k = np.diag(C2), np.diag(K2)
            disc = np.sqrt(c.astype(complex) ** 2 - 4 * k)
            s1 = (-c + disc) / 2
            s2 = (-c - disc) / 2
            gap = s1 - s2
            gap = np.where(np.abs(gap) < 1e-12 * wmax, 1e-12 * wmax, gap)
            poles = np.concatenate([s1, s2])
            right = np.concatenate([phi_e / gap[None, :], -phi_e / gap[None, :]], axis=1)
            left = np.concatenate([phi_e.T, phi_e.T], axis=0).astype(complex)
        else:
            A = np.zeros((2 * me, 2 * me), complex)
            A[:me, me:] = np.eye(me)
            A[me:, :me] = -K2
            A[me:, me:] = -C2
            lam, V = sla.eig(A)
            Vinv = sla.inv(V)
            poles = lam
            right = phi_e @ V[:me, :]
            left = Vinv[:, me:] @ phi_e.T
        mm = ModalModel(poles=poles, right=right.astype(complex), left=left.astype(complex),
                        rigid=phi[:, rigid], dofs=list(self.dofs), hysteretic=self.D is not None)
        if n_modes is None:
            self._modal = mm
        return mm

    # ------------------------------------------------------------------ FRFs
    def frf(self, freq_hz, responses=None, references=None, quantity: str = "accelerance",
            method: str = "modal", *, window_beta_per_s: float = 0.0) -> FRF:
        """Exact FRFs: ``method='modal'`` (all modes, fast for many lines) or ``'direct'`` (a sparse solve per line),
        at ``s = iω + β`` with β = ``window_beta_per_s`` (1/s, default 0): pass a measured FRF's
        ``window_beta_per_s`` to compare the model with exponentially windowed data (see :meth:`ModalModel.frf`)."""
        beta = check_window_beta(window_beta_per_s)
        if method == "modal":
            return self.modal_model().frf(freq_hz, responses, references, quantity, window_beta_per_s=beta)
        if method != "direct":
            raise ModalabValueError(f"method {method!r}; expected 'modal' or 'direct'")
        q = check_quantity(quantity)
        freq = np.asarray(freq_hz, dtype=float)
        resp = self.dofs if responses is None else parse_dofs(responses)
        refs = self.dofs if references is None else parse_dofs(references)
        io, so = locate(self.dofs, resp, "response DOF", "the model")
        ii, si = locate(self.dofs, refs, "reference DOF", "the model")
        n = self.n_dof
        F = np.zeros((n, len(ii)), complex)
        F[ii, np.arange(len(ii))] = si
        Kc = self.K.astype(complex) + (1j * self.D if self.D is not None else 0)
        Mc, Cc = self.M, self.C
        # a massless mechanism (no mass, no stiffness) is constrained as for the modes (MECHFIX): the
        # response there is zero, as in the modal FRF
        keep, _, _ = drop_mechanisms(self.K, self.M)
        if keep is not None:
            Kc, Mc = Kc[keep][:, keep], Mc[keep][:, keep]
            Cc = None if Cc is None else Cc[keep][:, keep]
            F = F[keep]
        H = np.empty((len(io), len(ii), freq.size), complex)
        for k, f in enumerate(freq):
            w = 2j * np.pi * f + beta                 # s = iω + β
            Z = Kc + w ** 2 * Mc + (w * Cc if Cc is not None else 0)
            try:
                X = restore(spla.splu(sp.csc_matrix(Z)).solve(F), keep, n)
            except RuntimeError:
                raise ModalabValueError(f"the dynamic stiffness is singular at {f} Hz (an undamped resonance or a "
                                        "rigid-body mode at 0 Hz); avoid that line or add damping") from None
            H[:, :, k] = X[io] * np.asarray(so)[:, None] * w ** _ORDER[q]
        return FRF(freq_hz=freq, H=H, responses=resp, references=refs, quantity=q,
                   units=QUANTITY_UNITS[q], metadata={"estimator": "exact"}, window_beta_per_s=beta)
