"""Exact low-rank screening of releases: joint flexibility and support (clamp) flexibility at every place.

A joint of the nominal model is rigid: the members meeting at a node share its six components.  Joint
flexibility about an axis ``c`` gives one member end (a group ``A`` of elements at node ``n``) a rotation of
its own, ``θ_A = θ_n + δ``, tied to the node by a spring ``k``.  A clamp (SPC/SPC1/GRID PS) sets components
of a node to zero; its flexibility frees them, ``u_c = δ``, each held by a spring ``k`` to ground.  Both add
``r`` DOFs ``δ`` (one per released component) to the nominal model; with ``u = T x + E δ`` (``T`` the
model's constraint reduction, ``E`` the released components in the unconstrained DOFs) the dynamic
stiffness of the released model is

    [ Z(s)        W(s)              ]        W(s)  = Tᵀ Z_A(s) E      (n_a × r)
    [ W(s)ᵀ  W_cc(s) + k(1 + i g) I ]        W_cc = Eᵀ Z_A(s) E       (r × r)

where ``Z_A(s) = K_A + s C_A + s² M_A + i D_A`` is the dynamic stiffness of what moves with ``δ``: the
group's elements for a joint, the whole unconstrained model for a clamp, and ``g`` the model-wide loss
factor that the spring element carries (PARAM G).  Condensing ``δ`` exactly (Schur complement) gives the
released model on the nominal DOFs as a rank-``r`` modification of the nominal dynamic stiffness,
``Z − W (W_cc + k I)⁻¹ Wᵀ``, and by the Woodbury identity its receptance (``H = Z⁻¹``)

    H_k = H + H W [W_cc + k(1 + i g) I − Wᵀ H W]⁻¹ Wᵀ H,

which tends to the nominal as ``k → ∞`` (the stiff-penalty formulation of a joint as two coincident nodes
tied by springs, in its exact limit) and is the fully released model at ``k = 0``.  Only the receptance
columns at the measured, reference and released-support DOFs are needed (one factorisation per line), and
each candidate then costs a few ``r × r`` solves per value and line: the screening is exact, covers every
joint node and every constrained component, and its cost is linear in the number of candidates.

The released models are exactly those the candidates build (:mod:`~updating.diagnosis.library`: a node split
with a rigid link on the other components and a spring, or an SPC edited into a spring), which a test checks.
"""
from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp
from scipy.optimize import minimize_scalar
from scipy.sparse.linalg import splu

from modalab.core.errors import ModalabValueError

from updating.fe.assembly import assemble
from modalab.core.dense import use_dense
from updating.correlation.condensation import dynamic_stiffness
from updating.diagnosis.fit import FRFData, _indices
from updating.diagnosis.frfscreen import _Misfit

log = logging.getLogger(__name__)
__all__ = ["release_screen", "release_vectors", "released_receptance", "release_visibility", "ReleaseVectors"]



class ReleaseVectors:
    """``W(s)`` and ``W_cc(s)`` of one release candidate as matrix polynomials in ``s`` on the support rows."""

    def __init__(self, rows, WK, WM, WC, WD, CK, CM, CC, CD):
        self.rows = np.asarray(rows, int)             # a-set rows where W is not zero
        self.W = (WK, WM, WC, WD)                     # (n_rows, r) each, or None
        self.Wcc = (CK, CM, CC, CD)                   # (r, r) each, or None
        self.rank = int(WK.shape[1])

    def at(self, s):
        """``W`` (n_s, n_rows, r) and ``W_cc`` (n_s, r, r) at the complex frequencies ``s``."""
        s = np.asarray(s, complex)

        def poly(parts):
            K, M, C, D = parts
            out = K[None].astype(complex) + (s ** 2)[:, None, None] * M[None]
            if C is not None:
                out = out + s[:, None, None] * C[None]
            if D is not None:
                out = out + 1j * D[None]
            return out
        return poly(self.W), poly(self.Wcc)

    @property
    def stiffness(self) -> float:
        """The static stiffness of what is released, per component (the scale of the spring values)."""
        return float(np.abs(np.trace(self.Wcc[0]))) / max(self.rank, 1)


def release_vectors(model, candidate, *, _cache=None) -> ReleaseVectors | None:
    """The :class:`ReleaseVectors` of a release ``candidate`` (its ``release`` description, see
    :class:`~updating.diagnosis.library.Candidate`) on ``model``; None for a candidate that is not a release.

    Raises :class:`~modalab.core.errors.ModalabValueError` when the candidate's node or components are not in
    the model (the library and the model disagree)."""
    rel = getattr(candidate, "release", None)
    if rel is None:
        return None
    kind, node, comps, elements = rel
    cache = {} if _cache is None else _cache
    if "red" not in cache:
        red = model.reduction()
        cache["red"] = red
        cache["fidx"] = {(d.node, d.axis): i for i, d in enumerate(red.full_dofs)}
        cache["T"] = sp.csr_matrix(red.T)
    red, fidx, T = cache["red"], cache["fidx"], cache["T"]
    missing = [c for c in comps if (node, c) not in fidx]
    if missing:
        raise ModalabValueError(f"release candidate {candidate.label!r}: node {node} has no component(s) "
                                f"{missing} in the model")
    cols = [fidx[(node, c)] for c in comps]
    if kind == "joint":
        mats = assemble(model, elements=[model.elements[e] for e in elements])
    elif kind == "support":
        if "all" not in cache:
            cache["all"] = assemble(model)
        mats = cache["all"]
    else:
        raise ModalabValueError(f"release candidate {candidate.label!r}: unknown release kind {kind!r}")
    W, C = [], []
    for A in (mats.K, mats.M, mats.C, mats.D):
        if A is None:
            W.append(None)
            C.append(None)
            continue
        AE = sp.csc_matrix(A)[:, cols]                                # (n_full, r)
        W.append(np.asarray((T.T @ AE).todense()))
        C.append(np.asarray(AE[cols].todense()))
    nz = np.zeros(T.shape[1], bool)
    for A in W:
        if A is not None:
            nz |= np.any(A != 0, axis=1)
    rows = np.flatnonzero(nz)
    if rows.size == 0:
        return None                                                   # releases nothing that moves
    W = [None if A is None else A[rows] for A in W]
    if W[1] is None:
        W[1] = np.zeros_like(W[0])
        C[1] = np.zeros_like(C[0])
    return ReleaseVectors(rows, *W, *C)


def _solves(structure, s, cols):
    """Per line ``f`` (a generator): ``(f, X)`` with ``X = Z(s_f)⁻¹ E_cols`` (n, n_cols), exact."""
    n = structure.n_dof
    K, M, C, D = structure.K, structure.M, structure.C, structure.D
    E = np.zeros((n, len(cols)), complex, order="F")
    E[cols, np.arange(len(cols))] = 1.0
    if use_dense(n, "solve"):      # batched dense solves, else one sparse LU per line (modalab.core.dense)
        dense = [None if A is None else (A.toarray() if sp.issparse(A) else np.asarray(A)) for A in (K, M, C, D)]
        for a in range(0, s.size, 16):
            ss = s[a:a + 16]
            Z = dense[0][None].astype(complex) + (ss ** 2)[:, None, None] * dense[1][None]
            if dense[2] is not None:
                Z = Z + ss[:, None, None] * dense[2][None]
            if dense[3] is not None:
                Z = Z + 1j * dense[3][None]
            X = np.linalg.solve(Z, np.broadcast_to(E, (ss.size,) + E.shape))
            for k in range(ss.size):
                yield a + k, X[k]
        return
    for f, sf in enumerate(s):
        # a symmetric pattern: minimum degree on Aᵀ + A keeps the factors of a beam frame banded
        lu = splu(sp.csc_matrix(dynamic_stiffness(K, M, C, D, sf)), permc_spec="MMD_AT_PLUS_A")
        yield f, lu.solve(E)


class _Blocks:
    """Receptance blocks of one structure for release candidates with support rows ``supports``: the measured
    × reference block, the support rows × (measured, reference) columns, and each candidate's own support ×
    support block.  ``Z`` is complex symmetric, so ``H[m, S] = H[S, m]ᵀ``; memory and work are linear in the
    number of candidates (one factorisation per line, the columns at the measured, reference and support
    DOFs, and only the blocks each candidate needs are kept)."""

    def __init__(self, structure, data: FRFData, supports):
        mi, ms, ri, rs = _indices(structure.dofs, data)
        self.sign = ms[:, None, None] * rs[None, :, None]
        self.mi, self.ri = mi, ri
        supports = [np.asarray(r, int) for r in supports]
        U = np.unique(np.concatenate(supports)) if supports else np.zeros(0, int)
        io = np.unique(np.concatenate([mi, ri]))
        cols = np.unique(np.concatenate([io, U]))
        cpos = {int(c): i for i, c in enumerate(cols)}
        io_c = np.array([cpos[int(c)] for c in io], int)
        n_s = np.asarray(data.s).size
        # flat gather indices of every candidate's support × support block in the (n, n_cols) solution
        self._blk, flat, start = [], [], 0
        for r in supports:
            idx = (r[:, None] * cols.size + np.array([cpos[int(c)] for c in r])[None, :]).ravel()
            flat.append(idx)
            self._blk.append((start, r.size))
            start += idx.size
        flat = np.concatenate(flat) if flat else np.zeros(0, int)
        self.n_cols = int(cols.size)
        self.H_io = np.empty((io.size, io.size, n_s), complex)             # (measured ∪ references)²
        self.H_uio = np.empty((U.size, io.size, n_s), complex)             # support rows × (measured ∪ refs)
        self.H_blk = np.empty((flat.size, n_s), complex)
        for f, X in _solves(structure, np.asarray(data.s, complex), cols):
            self.H_io[:, :, f] = X[io][:, io_c]
            self.H_uio[:, :, f] = X[U][:, io_c]
            self.H_blk[:, f] = X.ravel()[flat]
        self._iopos = {int(c): i for i, c in enumerate(io)}
        self._upos = {int(u): i for i, u in enumerate(U)}
        self._m = [self._iopos[int(i)] for i in mi]
        self._r = [self._iopos[int(i)] for i in ri]

    def H0(self):
        return self.H_io[self._m][:, self._r]

    def candidate(self, k: int, rows):
        """``H[m, S]`` (n_m, n_sup, n_s), ``H[S, r]`` (n_sup, n_r, n_s), ``H[S, S]`` (n_sup, n_sup, n_s) of the
        ``k``-th support set ``rows``."""
        Hs_io = self.H_uio[[self._upos[int(r)] for r in rows]]
        Hms = Hs_io[:, self._m].transpose(1, 0, 2)
        Hsr = Hs_io[:, self._r]
        a, m = self._blk[k]
        Hss = self.H_blk[a:a + m * m].reshape(m, m, -1)
        return Hms, Hsr, Hss


def released_receptance(structure, model, candidate, k: float, data: FRFData, loss_factor: float = 0.0):
    """The receptance (n_m, n_r, n_s, data's signs applied) of ``structure`` with ``candidate`` released into a
    spring ``k`` (module docstring): what :func:`release_screen` evaluates, for checks and figures."""
    rv = release_vectors(model, candidate)
    if rv is None:
        raise ModalabValueError(f"{candidate.label!r} is not a release candidate")
    B = _Blocks(structure, data, [rv.rows])
    Wf, Cf = rv.at(data.s)
    Hm, Hr, Hs = _support_blocks(B.candidate(0, rv.rows), Wf)
    A = Cf + k * (1 + 1j * loss_factor) * np.eye(rv.rank)[None] - Hs
    X = np.linalg.solve(A, Hr.transpose(2, 0, 1))                    # (n_s, r, n_r)
    dH = np.einsum("mkf,fkr->mrf", Hm, X)
    return (B.H0() + dH) * B.sign


def _support_blocks(blocks, Wf):
    """``H[m, :] W`` (n_m, r, n_s), ``Wᵀ H[:, r]`` (r, n_r, n_s) and ``Wᵀ H W`` (n_s, r, r) from a candidate's
    blocks ``(H[m, S], H[S, r], H[S, S])``."""
    Hms, Hsr, Hss = blocks
    Hm = np.einsum("mjf,fjk->mkf", Hms, Wf)
    Hr = np.einsum("fjk,jrf->krf", Wf, Hsr)
    Hs = np.einsum("fjk,jlf,flq->fkq", Wf, Hss, Wf)
    return Hm, Hr, Hs


def _releases(model, structure, data, candidates, what: str):
    """The releases among ``candidates`` with their vectors (:func:`release_vectors`, stiffness > 0) and the
    receptance blocks at their rows: ``(work, blocks)``, ``([], None)`` when there are none.  ``structure``
    must have the model's constrained DOFs (``what`` names the caller in the error)."""
    red_dofs = model.reduction().dofs
    if [(d.node, d.axis) for d in red_dofs] != [(d.node, d.axis) for d in structure.dofs]:
        raise ModalabValueError(f"{what}: the structure's DOFs are not the model's constrained DOFs")
    cache: dict = {}
    work = []
    for c in candidates:
        rv = release_vectors(model, c, _cache=cache)
        if rv is not None and rv.stiffness > 0:
            work.append((c, rv))
    if not work:
        return [], None
    return work, _Blocks(structure, data, [rv.rows for _, rv in work])


class _ReleaseMisfit(_Misfit):
    """The current model's misfit on the data that each release's Woodbury update is scored against (the
    :class:`~updating.diagnosis.frfscreen._Misfit` of the shared candidates, on the release blocks ``B``), with
    the parameters re-fitted to first order when a :class:`~updating.diagnosis.frfscreen.ParameterRefit` is
    given."""

    def __init__(self, B, data: FRFData, refit=None):
        super().__init__(B.H0(), B.sign, data, refit)

    def errors(self, Hm, Hr, A0, g, r: int):
        """``errors(ks)``: the weighted FRF error of the model with a rank-``r`` release (blocks ``Hm``, ``Hr``,
        the denominator ``A0`` without the spring) at each spring value ``ks``, the spring carrying ``g``."""
        Wt, E0, c0, refit = self.Wt, self.E0, self.c0, self.refit
        if r == 1:
            U = Hm[:, 0, None, :] * Hr[None, 0, :, :] * self.sign     # (n_m, n_r, n_s)
            P = np.sum(Wt * np.conj(E0) * U, axis=(0, 1))
            S = np.sum(Wt * np.abs(U) ** 2, axis=(0, 1))
            a0 = A0[:, 0, 0]
            T = None if refit is None else refit.projections(np.sqrt(Wt) * U)

            def errors(ks):
                d = a0[None, :] + ks[:, None] * g
                tot = c0 + 2 * np.sum((P[None] / d).real, axis=1) + np.sum(S[None] / np.abs(d) ** 2, axis=1)
                return self.error(tot, None if T is None else self.g0[None] + ((1.0 / d) @ T.T).real)
            return errors
        HrT = Hr.transpose(2, 0, 1)                                   # (n_s, r, n_r)

        def errors(ks):
            res = []
            for kv in ks:
                X = np.linalg.solve(A0 + kv * g * np.eye(r)[None], HrT)
                dH = np.einsum("mkf,fkq->mqf", Hm, X) * self.sign
                rc = np.sqrt(Wt) * (E0 + dH)
                res.append(self.error(float(np.sum(np.abs(rc) ** 2)), None if refit is None else refit.g(rc)))
            return np.array(res)
        return errors


def release_screen(structure, model, candidates, data: FRFData, *, loss_factor: float = 0.0,
                   n_values: int = 281, n_values_multi: int = 19, top: int | None = None, refit=None) -> list:
    """Rank release candidates (joint and support flexibility; the others are skipped) by the training FRF
    error each alone leaves at its best spring value, exactly (module docstring).

    ``structure`` must be ``model.structure()`` (the same matrices; ``model`` gives the element groups and the
    constraints).  ``loss_factor`` is the model-wide structural damping (PARAM G) the spring carries.
    Values are searched on log-spaced points over seven decades around the released stiffness (from 10⁻⁴ of
    it): ``n_values`` for a rank-one release (a 6 % step, as the FRF screening's: a mode whose frequency the
    spring moves across a measured resonance makes the error dip over a few per cent of the value — BG 4207,
    a T's joint of 1.5e3 N·m/rad, analysed after its score: at the nominal parameters the error was 0.132 at
    1.58e3 and 0.22-0.29 a 26 % step either side, so the former 57-value grid saw 0.170 at 3.2e3 and the fit
    from there ran to a stiff joint), refined by Brent's method; ``n_values_multi`` for higher ranks.
    Returns ``[(candidate, k, gain)]`` best first, ``gain`` the relative drop of
    :func:`~updating.diagnosis.fit.frf_error` (only candidates that lower it).  With a
    :class:`~updating.diagnosis.frfscreen.ParameterRefit` the parameters of the fit ``structure`` are
    re-fitted to first order alongside each value, as in the FRF screening.  Raises
    :class:`~modalab.core.errors.ModalabValueError` when the model and the structure have different DOFs."""
    work, B = _releases(model, structure, data, candidates, "release screening")
    if not work:
        return []
    mis = _ReleaseMisfit(B, data, refit)
    e0 = mis.e0
    g = 1 + 1j * loss_factor
    out = []
    for i, (c, rv) in enumerate(work):
        Wf, Cf = rv.at(data.s)
        Hm, Hr, Hs = _support_blocks(B.candidate(i, rv.rows), Wf)
        A0 = Cf - Hs                                                  # (n_s, r, r): the denominator without k
        r = rv.rank
        errors = mis.errors(Hm, Hr, A0, g, r)
        k_ref = rv.stiffness
        grid = k_ref * np.logspace(-4, 3, n_values if r == 1 else n_values_multi)
        err = errors(grid)
        bad = ~np.isfinite(err)
        if bad.all():
            log.info("release screening: %s leaves a singular model at every value; not ranked", c.label)
            continue
        if bad.any():          # a value where the released model is singular at a line is no best value
            log.debug("release screening: %s singular at %d of %d values", c.label, int(bad.sum()), bad.size)
            err = np.where(bad, np.inf, err)
        j = int(np.argmin(err))
        kbest, ebest = float(grid[j]), float(err[j])
        if 0 < j < grid.size - 1:
            a, b = np.log(grid[j - 1]), np.log(grid[j + 1])
            sol = minimize_scalar(lambda x: float(errors(np.array([np.exp(x)]))[0]), bounds=(a, b),
                                  method="bounded", options={"xatol": 1e-3, "maxiter": 25 if r == 1 else 8})
            if sol.fun < ebest:
                kbest, ebest = float(np.exp(sol.x)), float(sol.fun)
        if ebest < e0:
            out.append((c, kbest, 1.0 - ebest / e0))
    out.sort(key=lambda t: -t[2])
    log.info("release screening of %d joint/support candidates (error %.4g now%s): best %s", len(work), e0,
             "" if refit is None else ", the parameters re-fitted to first order",
             ", ".join(f"{c.label} ({100 * gn:.1f} %)" for c, _, gn in out[:3]))
    return out[:top] if top else out


#: a release is tried "completely": its spring at this fraction of the released member's own stiffness
FULL_RELEASE = 1e-4


def release_visibility(structure, model, candidates, data: FRFData, *, loss_factor: float = 0.0) -> list:
    """How much each release candidate, released completely, can change the measured FRFs: ``[(candidate,
    chi2)]`` with ``chi2 = Σ |H_k − H|² / (den² σ²)`` over the data's values, in units of their noise
    (:attr:`~updating.correlation.receptance.FRFData.sigma`, the scale of :func:`~updating.diagnosis.fit.frf_error`),
    at ``k`` = :data:`FULL_RELEASE` × the released member's own stiffness (a hinge).

    The receptance of a released model is exactly the nominal one plus the Woodbury term of the module
    docstring; the change it makes at the measured × reference DOFs bounds what any data of this sensor and
    hit layout can reveal of the release.  A joint rotation that neither the hits excite nor the sensors see
    — the out-of-plane bending of a member of a planar frame tested in its plane: in- and out-of-plane motion
    decouple, and the measured rows and excited columns of the change of receptance θ − α (thesis eqs.
    3.62-3.64, the released against the nominal model) vanish — gives
    ``chi2`` of the order of round-off: no amount of data from this layout can locate or refute it.  Candidates
    that are not releases are skipped; one factorisation per line, a few ``r × r`` solves per candidate."""
    work, B = _releases(model, structure, data, candidates, "release visibility")
    if not work:
        return []
    Wt = (data.quality / data.floor) ** 2 / data.den ** 2                # 1 / (den σ)²
    g = 1 + 1j * loss_factor
    out = []
    for i, (c, rv) in enumerate(work):
        Wf, Cf = rv.at(data.s)
        Hm, Hr, Hs = _support_blocks(B.candidate(i, rv.rows), Wf)
        A = Cf - Hs + FULL_RELEASE * rv.stiffness * g * np.eye(rv.rank)[None]
        X = np.linalg.solve(A, Hr.transpose(2, 0, 1))                    # (n_s, r, n_r)
        dH = np.einsum("mkf,fkq->mqf", Hm, X)
        out.append((c, float(np.sum(Wt * np.abs(dH) ** 2))))
    return out
