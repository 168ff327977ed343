"""Local damping screened with the model's parameters re-fitted alongside, on the model reduced to a Ritz basis.

The exact FRF screening (:func:`~updating.diagnosis.frfscreen.frf_screen`) adds a candidate to the model as the
parameter fit left it.  For local damping that is the least reliable order of all (see
:func:`~updating.diagnosis.terms._distinct_places`): the sections' and the model's loss factors were fitted
without the local term and already carry part of its dissipation, so the element that carries it can rank far
down (tuning case 1448: the truth's element, fitted with the parameters, leaves χ²/N 0.10 against 0.70 for the
screening's first, which ranked it eighth among the elements; case1424 the same).  Here every structural-damping
candidate is fitted together with a change of every updating parameter (E, ρ, the loss factors), on the model
reduced to a Ritz basis Φ, M-orthonormal and K-diagonal (Λ): its normal modes up to :data:`MODES_TO` × the
band's top and the static corrections at the data's DOFs (residual flexibility, the basis of
:class:`~updating.diagnosis.ritz.RitzBasis`, every one of its pseudo-modes):

    Z(s, x) = Λ + s² I + i Φᵀ D Φ + s Φᵀ C Φ + θ i Φᵀ G Φ + Σ_j δp_j Φᵀ (∂K_j + i ∂D_j + s² ∂M_j) Φ,
    H(x) = H_exact + Φ_m [Z(s, x)⁻¹ − Z(s, 0)⁻¹] Φ_rᵀ,

``G`` the candidate's element matrix and ``θ`` its loss factor: a modal (Ritz) model of the change, coupled
through the full modal damping matrix (the diagonal, modal-strain-energy form — Ungar & Kerwin, J. Acoust. Soc.
Am. 34 (1962) 954-957; Johnson & Kienholz, AIAA J. 20 (1982) 1284-1290 — misses the coupling of close modes
that a local damper brings, and ranked case1448's element 28th), added to the current model's exact receptance.
Shapes change only within the basis.  Modes alone (the basis until 2026-12-03) leave out the local change of
shape that the damper and the parameters bring: on tuning case 2036 (a ladder frame's element 9 damped, loss
factor 0.0734) they ranked twenty places within 4 % of the best gain and element 9 thirteenth, so it was never
fitted; with the static corrections element 9 ranks first.  Until 2026-12-05 only the pseudo-modes up to 10 × the
band's top were kept (2.5 s instead of 6.3 s on 2036, element 9 first with 0.0716 instead of 0.0734): the ones
dropped carry the residual flexibility the static corrections are there for, so the reduced model's parameter
re-fit already differed from the exact one.  On held-out case 2665 (a ladder frame on mounts, element 13 damped,
loss factor 0.101; analysed after its score) the reduced re-fit left 0.0143 against the exact 0.0175, every place
gained 64-67 % and element 13 ranked 26th at 0.33 — never fitted, nothing found; with every pseudo-mode the
re-fit is the exact one (0.0175), element 13 ranks first at 0.101 and is found (0.1009).

The ranking is by the training FRF error each candidate leaves against the same fit without it.  It only chooses
which places the full fit (:meth:`~updating.diagnosis.workflow.Diagnoser._try`, and the screening picks of
:meth:`~updating.diagnosis.acceptance._Acceptance._judge_picks`) tries; that fit decides.

Without a viscous term ``Z(s, x) = K(x) + s² M(x)`` is one pencil for all lines: one eigensolution per ``x``
(``Z⁻¹ = V diag(1 / (λ + s²)) Vᵀ``, :meth:`_ModalChange._modes`) replaces an LU per line, and the Jacobian's
``Vᵀ A_j V`` are formed once per ``x``; it is used when its backward error is below :data:`BACKWARD_ERROR`,
otherwise every line is solved.  The same rankings to six digits on held-out case 2237 and tuning case 2036,
in 12 s instead of 26 s and 1.3 s instead of 4.2 s (one screening each, 2 cores).
"""
from __future__ import annotations

import logging
import time

import numpy as np
import scipy.linalg
import scipy.sparse as sp

from modalab.core.parallel import fork_map
from updating.diagnosis.fit import _indices, model_frf
from updating.diagnosis.ritz import RitzBasis

log = logging.getLogger(__name__)

#: normal modes of the current model up to this multiple of the band's top frequency carry the change
MODES_TO = 2.0
#: candidates fitted to convergence, the best after two steps of every one
FITTED = 20
#: normal modes in the basis at most, for every model size (RitzBasis's max_modes; before the Ritz basis, the cap
#: applied to the sparse solver's large models only)
MAX_MODES = 40
#: the largest relative backward error of the reduced receptance taken from one eigensolution per parameter set
#: (:meth:`_ModalChange._accurate`); above it each line is solved on its own
BACKWARD_ERROR = 1e-10


def _basis(structure, cols, f_top_hz: float):
    """ω² and the M-orthonormal, K-diagonal Ritz basis Q of ``structure`` for the receptance at DOF indices
    ``cols``: the normal modes up to :data:`MODES_TO` × ``f_top_hz`` (rigid-body modes among them) and the
    static corrections at ``cols`` (:class:`~updating.diagnosis.ritz.RitzBasis`), every pseudo-mode of them: the
    stiff ones carry the residual flexibility that a truncation would leave out."""
    rb = RitzBasis(structure, cols, f_top_hz, mode_factor=MODES_TO, min_modes=0, max_modes=MAX_MODES)
    Q, _, w2, _, _ = rb.modal(structure)
    return w2, Q


def _projected(A, phi) -> np.ndarray:
    """``Φᵀ A Φ`` for a library matrix (``LocalMatrix``) or a sparse matrix (None: zeros), symmetrised (the
    structural matrices are symmetric; this only removes rounding, so that ``Z(s, x)`` is exactly symmetric)."""
    if A is None:
        return np.zeros((phi.shape[1], phi.shape[1]))
    if hasattr(A, "low_rank"):
        rows, L = A.low_rank()
        B = L.T @ phi[rows]
        return B.T @ B
    P = phi.T @ (sp.csr_matrix(A) @ phi)
    return 0.5 * (P + P.T)


def _bilinear_orthonormal(V, M, lam):
    """Eigenvectors ``V`` of a complex symmetric pencil (``K v = λ M v``) made orthonormal in the bilinear form
    ``vᵀ M w`` (the transpose, not the conjugate): vectors of distinct eigenvalues are so already and are only
    scaled; within a cluster of (nearly) equal eigenvalues — the rigid-body modes, the repeated modes of a
    symmetric frame — LAPACK's vectors are any basis of the space, so they are orthonormalised (Gram-Schmidt
    in that form).  None when a vector is isotropic (``vᵀ M v = 0``: no such basis)."""
    V = V.copy()
    scale = max(float(np.max(np.abs(lam))), 1e-300)
    order = np.argsort(lam.real, kind="stable")
    clusters, cur = [], [order[0]]
    for k in order[1:]:
        if abs(lam[k] - lam[cur[-1]]) <= 1e-7 * scale:
            cur.append(k)
        else:
            clusters.append(cur)
            cur = [k]
    clusters.append(cur)
    for cl in clusters:
        done = []
        for k in cl:
            v = V[:, k]
            for j in done:
                v = v - (V[:, j] @ (M @ v)) * V[:, j]
            n = v @ (M @ v)
            if not np.isfinite(n) or abs(n) <= 1e-12 * float(np.vdot(v, M @ v).real):
                return None
            V[:, k] = v / np.sqrt(n)
            done.append(k)
    return V


class _ModalChange:
    """The data, the current model's exact receptance, and the model reduced to its modes at the data's DOFs:
    the weighted residual of a change ``Σ x_j A_j(s)`` of the reduced dynamic stiffness, and its Jacobian."""

    def __init__(self, structure, data):
        self.data = data
        mi, ms, ri, rs = _indices(structure.dofs, data)
        w2, self.phi = _basis(structure, np.concatenate([mi, ri]), float(np.max(data.freq_hz)))
        s2 = data.s ** 2
        Dp, Cp = _projected(structure.D, self.phi), _projected(structure.C, self.phi)
        # Z(s, x) = K(x) + s² M(x) without a viscous term: one eigensolution per x gives every line (_modes)
        self.K0 = np.diag(w2).astype(complex) + 1j * Dp
        self.viscous = bool(np.any(Cp))
        Z0 = self.K0[None] + s2[:, None, None] * np.eye(w2.size)[None] + data.s[:, None, None] * Cp[None]
        self.Z0 = Z0                                                                     # (n_s, m, m)
        self._last = None
        self.pm, self.pr = self.phi[mi] * ms[:, None], self.phi[ri] * rs[:, None]
        self.H00 = self._reduced_at(np.zeros(1), (np.zeros((1,) + Z0.shape[1:]),) * 2)  # (n_s, n_m, n_r)
        wt = np.broadcast_to(np.asarray(data.quality, float), data.H.shape)
        scale = wt / data.den / np.sqrt(max(float(np.sum(wt ** 2)), 1e-300))
        self.scale = np.ascontiguousarray(scale.transpose(2, 0, 1))
        self.r0 = np.ascontiguousarray(((model_frf(structure, data) - data.H) * scale).transpose(2, 0, 1))
        #: a drop of the error below this is rounding, not a gain (1e-9 of the weighted data's norm; an exact
        #: model's error is ~1e-14 of it, and which candidate lowers it by rounding is chance)
        self.rounding = 1e-9 * float(np.linalg.norm(data.H * scale))

    @property
    def n_modes(self) -> int:
        return self.phi.shape[1]

    def term(self, K=None, M=None, D=None) -> tuple:
        """``A(s) = Φᵀ(K + iD + s²M)Φ`` as its two (m, m) parts ``(Φᵀ(K + iD)Φ, ΦᵀMΦ)``: ``A(s) = A0 + s² A2``.
        The (lines × m × m) array is never formed: one per candidate and parameter, kept for a fit, is what
        made the demo's diagnosis peak at 20 GB."""
        return _projected(K, self.phi) + 1j * _projected(D, self.phi), _projected(M, self.phi)

    @staticmethod
    def stack(terms) -> tuple:
        """Terms of :meth:`term` as the pair of stacks ``(A0 (n_x, m, m), A2 (n_x, m, m))`` the fits take."""
        return np.stack([a for a, _ in terms]), np.stack([b for _, b in terms])

    def _changed(self, x, A) -> tuple:
        """The change ``(Σ x_j A0_j, Σ x_j A2_j)`` of the reduced stiffness and mass, each (m, m)."""
        A0, A2 = A
        m = A0.shape[1]
        z0 = (x.astype(complex) @ A0.reshape(A0.shape[0], -1)).reshape(m, m)
        z2 = (x @ A2.reshape(A2.shape[0], -1)).reshape(m, m)
        return z0, z2

    def _modes(self, x, A):
        """``(P, g, Q, V)`` with ``Φ_m Z(s, x)⁻¹ Φ_rᵀ = P diag(g(s)) Q`` on every line, from one eigensolution of
        the changed reduced model: ``K v = λ M v``, ``K = Λ + iΦᵀDΦ + Σ x_j A0_j``, ``M = I + Σ x_j A2_j``,
        normalised ``Vᵀ M V = I`` (complex symmetric: the transpose, not the conjugate), so that
        ``Z(s)⁻¹ = V diag(1 / (λ + s²)) Vᵀ``; ``g`` (n_s, m).  None when the model has a viscous term (``Z`` is
        then quadratic in ``s``), when ``M`` is singular, or when the eigenvectors' backward error exceeds
        :data:`BACKWARD_ERROR` (:meth:`_accurate`; close eigenvalues of a non-Hermitian pencil): the caller then
        solves line by line (:meth:`_solve`)."""
        key = np.asarray(x, float).tobytes()        # the last x and terms (held, so that no other array has their id)
        if self._last is not None and self._last[0] == key and self._last[1] is A[0] and self._last[2] is A[1]:
            return self._last[3]
        out = None
        if not self.viscous:
            z0, z2 = self._changed(x, A)
            K, M = self.K0 + z0, np.eye(z2.shape[0]) + z2
            lam, V = scipy.linalg.eig(K, M.astype(complex))
            V = _bilinear_orthonormal(V, M, lam) if np.all(np.isfinite(lam)) else None   # M singular: no pencil
            if V is not None:
                out = self._accurate(V, K, M)
        self._last = (key, A[0], A[1], out)
        return out

    def _accurate(self, V, K, M):
        """``(P, g, Q, V)`` of :meth:`_modes` from the normalised eigenvectors ``V``, or None when they do not
        diagonalise ``Z(s) = K + s² M`` well enough.  With ``Vᵀ K V = diag(λ) + E_K`` (``λ`` the Rayleigh
        quotients) and ``Vᵀ M V = I + E_M``, ``V diag(1 / (λ + s²)) Vᵀ`` is the exact inverse of ``Z`` changed
        by ``V⁻ᵀ (E_K + s² E_M) V⁻¹``: a relative backward error of at most
        ‖V⁻¹‖² max(‖E_K‖ / ‖K‖, ‖E_M‖ / ‖M‖) on every line, which must stay below :data:`BACKWARD_ERROR`
        (the line-by-line LU's is ~1e-15 times its growth; the data's noise ~1e-3)."""
        KV, MV = V.T @ K @ V, V.T @ M @ V
        lam = np.diag(KV).copy()
        e = max(np.linalg.norm(KV - np.diag(lam)) / np.linalg.norm(K, 2),
                np.linalg.norm(MV - np.eye(lam.size)) / np.linalg.norm(M, 2))
        sv = np.linalg.svd(V, compute_uv=False)
        if not (np.isfinite(e) and sv[-1] > 0 and e / sv[-1] ** 2 <= BACKWARD_ERROR):
            return None
        return self.pm @ V, 1.0 / (lam[None, :] + (self.data.s ** 2)[:, None]), V.T @ self.pr.T, V

    def _solve(self, x, A, rhs):
        """``Z(s, x)⁻¹ rhs`` on every line (``rhs`` (m, k)): one LU each, never the inverse (``Z`` is complex
        symmetric, so ``Φ_m Z⁻¹ = (Z⁻¹ Φ_mᵀ)ᵀ``: one solve gives both sides of the Jacobian)."""
        z0, z2 = self._changed(x, A)
        Z = self.Z0 + z0[None] + (self.data.s ** 2)[:, None, None] * z2[None]
        return np.linalg.solve(Z, np.broadcast_to(rhs.astype(complex), (Z.shape[0],) + rhs.shape))

    def _reduced_at(self, x, A) -> np.ndarray:
        """``Φ_m Z(s, x)⁻¹ Φ_rᵀ`` (n_s, n_m, n_r): from the eigensolution (:meth:`_modes`), else solved on the
        smaller side."""
        modes = self._modes(x, A)
        if modes is not None:
            P, g, Q, _ = modes
            return ((g[:, None, :] * P[None]).reshape(-1, P.shape[1]) @ Q).reshape(g.shape[0], P.shape[0], -1)
        if self.pr.shape[0] <= self.pm.shape[0]:
            return self.pm[None] @ self._solve(x, A, self.pr.T)
        return (self.pr[None] @ self._solve(x, A, self.pm.T)).transpose(0, 2, 1)

    def residual(self, x, A) -> np.ndarray:
        """The weighted complex residual (flat) of the model changed by ``Σ x_j A_j`` (``A``: :meth:`stack`)."""
        return (self.r0 + (self._reduced_at(x, A) - self.H00) * self.scale).ravel()

    def jacobian(self, x, A) -> np.ndarray:
        """d(residual)/d(x), (n_x, n) complex: ``-Φ_m Z⁻¹ A_j(s) Z⁻¹ Φ_rᵀ``, in the eigenvectors
        ``-P diag(g) Vᵀ A_j(s) V diag(g) Q`` (the (m, m) products ``Vᵀ A_j V`` once per ``x``, not per line)."""
        A0, A2 = A
        s2 = (self.data.s ** 2)[:, None, None]
        n_x = A0.shape[0]
        modes = self._modes(x, A)
        if modes is not None:                            # GEMMs over all parameters and lines at once
            P, g, Q, V = modes
            n_s, m, n_r = g.shape[0], g.shape[1], Q.shape[1]
            X = (g[:, :, None] * Q[None]).transpose(1, 0, 2)                               # (m, n_s, n_r)
            X = np.concatenate([X, X * s2.reshape(1, n_s, 1)]).reshape(2 * m, -1)           # [X; s² X]
            B = np.concatenate([np.einsum("ak,jab,bl->jkl", V, A0, V, optimize=True),
                                np.einsum("ak,jab,bl->jkl", V, A2, V, optimize=True)], axis=2)   # [B0_j, B2_j]
            T = (B.reshape(-1, 2 * m) @ X).reshape(n_x, m, n_s, n_r)                       # B_j(s) g Q
            T *= g.T[None, :, :, None]
            J = (P @ T.transpose(1, 0, 2, 3).reshape(m, -1)).reshape(-1, n_x, n_s, n_r)   # (n_m, n_x, n_s, n_r)
            J = -J.transpose(1, 2, 0, 3) * self.scale[None]
            return J.reshape(n_x, -1)
        n_m = self.pm.shape[0]
        W = self._solve(x, A, np.hstack([self.pm.T, self.pr.T]))
        Y = W[:, :, :n_m].transpose(0, 2, 1)                                             # (n_s, n_m, m)
        X = W[:, :, n_m:]                                                                # (n_s, m, n_r)
        J = np.empty((n_x,) + self.scale.shape, complex)                                 # (n_x, n_s, n_m, n_r)
        for j in range(n_x):                             # A_j(s) X = A0_j X + s² A2_j X, one parameter at a time
            J[j] = -(Y @ (A0[j] @ X + s2 * (A2[j] @ X))) * self.scale
        return J.reshape(n_x, -1)

    def fit(self, A, lower, upper, x0, iters: int = 15):
        """Levenberg-Marquardt over real ``x`` projected on ``lower``..``upper`` (a handful of values: the
        normal matrix is formed directly): (x, error)."""
        x = np.clip(np.asarray(x0, float), lower, upper)
        r = self.residual(x, A)
        f, lam = float(np.vdot(r, r).real), 1e-3
        for _ in range(iters):
            J = self.jacobian(x, A)
            H, g = (J.conj() @ J.T).real, (J.conj() @ r).real
            d = np.maximum(np.diag(H), 1e-12 * max(float(np.max(np.diag(H))), 1e-300))
            while lam < 1e8:
                xn = np.clip(x - np.linalg.solve(H + lam * np.diag(d), g), lower, upper)
                rn = self.residual(xn, A)
                fn = float(np.vdot(rn, rn).real)
                if fn < f:
                    break
                lam *= 4.0
            if lam >= 1e8:
                break
            done = f - fn < 1e-6 * f
            x, r, f, lam = xn, rn, fn, lam / 3.0
            if done:
                break
        return x, float(np.sqrt(f))


def damping_screen(pm, p, candidates, data, jobs: int | None = 1) -> list:
    """``[(candidate, loss factor, gain)]`` best first for the structural-damping candidates (matrix ``D``) of
    ``candidates`` on the model ``pm`` at ``p``, each fitted with every parameter's change (see the module
    docstring); ``gain`` the relative drop of the training FRF error against the parameters re-fitted without
    a candidate (only candidates that lower it).  The candidates' fits are independent: on ``jobs`` processes
    (:func:`~modalab.core.parallel.fork_map`, bit for bit the serial result; space frame 2909 on 2 cores: its three
    screenings took 29 s of its 83 s on one core while the other waited, 15 s on both)."""
    cands = [c for c in candidates if c.matrix == "D" and c.G is not None]
    if not cands:
        return []
    t0 = time.perf_counter()
    mc = _ModalChange(pm.structure(p), data)
    if mc.n_modes == 0:
        return []
    A = [mc.term(d.dK, d.dM, d.dD) for d in pm.derivatives(p)]
    inf = np.full(len(A), np.inf)
    e_base = mc.fit(mc.stack(A), -inf, inf, np.zeros(len(A)))[1] if A else \
        float(np.linalg.norm(mc.r0))

    def problem(c):
        """The candidate's fit: its terms (1 + n_p) x m x m twice, bounds and start; None when it changes
        nothing in the basis."""
        Ac = mc.term(D=c.G)
        if not np.any(np.abs(Ac[0]) > 0):
            return None
        up = getattr(c, "upper", 1.0)
        return mc.stack([Ac] + A), np.r_[0.0, -inf], np.r_[up, inf], np.r_[0.05 * min(1.0, up), np.zeros(len(A))]

    def fit(c, x0=None, **kw):
        prob = problem(c)
        return None if prob is None else mc.fit(*prob[:3], prob[3] if x0 is None else x0, **kw)

    # two steps for every candidate, then the best :data:`FITTED` to the end
    steps = fork_map(lambda c: fit(c, iters=2), [(c,) for c in cands], jobs, by_reference=cands)
    first = sorted(((r[1], k, r[0]) for k, r in enumerate(steps) if r is not None), key=lambda t: t[0])
    ends = fork_map(lambda c, x: fit(c, x), [(cands[k], x) for _, k, x in first[:FITTED]], jobs, by_reference=cands)
    out = []
    for i, (e, k, x) in enumerate(first):
        if i < FITTED:
            x, e = ends[i]
        if e < e_base - mc.rounding and x[0] > 0:
            out.append((cands[k], float(x[0]), 1.0 - e / e_base))
    out.sort(key=lambda t: -t[2])
    log.info("damping screening of %d candidates on %d modes and %d lines with the %d parameters re-fitted (error %.4g "
             "so, %.1f s): best %s", len(cands), mc.n_modes, data.s.size, len(A), e_base, time.perf_counter() - t0,
             ", ".join(f"{c.label} ({100 * g:.0f} %)" for c, _, g in out[:3]))
    return out
