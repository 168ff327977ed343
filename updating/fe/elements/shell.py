"""Flat shell elements (Nastran CQUAD4 / CTRIA3 with PSHELL): :class:`Quad4` and :class:`Tria3`.

Both are *flat* facet shells with 6 DOFs per node (basic system): a membrane
part (u, v), a plate-bending part (w, θx, θy) and a small drilling stiffness
on θz, uncoupled in the element frame (isotropic material, no offset), then
rotated to the basic system.

Element frame (documented convention).  Local z is the unit normal: for the
quadrilateral the direction of (G3 − G1) × (G4 − G2) (the diagonals, as
Nastran), for the triangle (G2 − G1) × (G3 − G1).  Local x is the G1→G2 edge
projected on the element plane (Nastran's reference direction for THETA = 0),
y = z × x.  Nastran's CQUAD4 *element* system bisects the diagonals instead;
with an isotropic material and THETA = 0 the stiffness and mass do not depend
on the in-plane direction of x, so both conventions give the same matrices in
basic.  The nodes of a (slightly) warped quadrilateral are projected on the
mean plane through their centroid; the warp ratio ``max|h| / √A`` (h: node
distance to the mean plane, A: area) must not exceed :attr:`Quad4.warp_tol`.

Quad4 (4 nodes, 2×2 Gauss):

* membrane: bilinear displacements plus Wilson's incompatible modes
  (1 − ξ², 1 − η²) with the Taylor–Beresford–Wilson modification (derivatives
  of the incompatible modes from the centre Jacobian, scaled by det J₀/det J)
  so that the element passes the constant-strain patch test on distorted
  meshes (Taylor, Beresford & Wilson, IJNME 10, 1976); the internal modes are
  condensed statically;
* bending: Mindlin–Reissner plate with the MITC4 transverse-shear
  interpolation (covariant shear strains tied at the mid-edges A, B, C, D:
  Bathe & Dvorkin, IJNME 21, 1985, "A four-node plate bending element based
  on Mindlin/Reissner plate theory and a mixed interpolation") — no shear
  locking in the thin limit; shear correction TS/T (default 5/6).

Tria3 (3 nodes):

* membrane: constant-strain triangle (CST);
* bending: the discrete Kirchhoff triangle DKT (Batoz, Bathe & Ho, IJNME 15,
  1980, "A study of three-node triangular plate bending elements", explicit
  form of H_x, H_y and of B, as given in that paper); a Kirchhoff element,
  no transverse shear and hence no shear locking.

Drilling (both): a penalty ``α G t ∫ (θz − ω)² dA`` with ω = ½(∂v/∂x − ∂u/∂y)
the in-plane rotation of the membrane field (Hughes & Brezzi, CMAME 72,
1989), α = :attr:`drill` = 10⁻³; it vanishes for rigid motions (six exact
rigid-body modes) and stops the in-plane rotation from being singular.

Mass (``ctx.coupled_mass`` True): consistent with the bilinear / linear
interpolation of u, v, w (ρt + nsm per area) and of the rotations, with rotary
inertia ρt³/12 on θx, θy and θz (the DKT's translational mass uses the linear
interpolation, as is common for DKT facets).  Lumped (``coupled_mass`` False,
Nastran's default COUPMASS): a quarter / third of the translational mass at
each node and no rotary inertia, as Nastran's lumped mass and the beams here.

Stiffness constants (PSHELL with MID1 = MID2 = MID3): membrane E t/(1−ν²),
bending ``bending · E t³/(12(1−ν²))`` with ``bending`` = 12I/T³ (default 1),
transverse shear ``shear · G t`` with ``shear`` = TS/T (default 5/6).  Every
value may be complex (complex-step derivatives, :mod:`updating.fe.parameters`).

Both classes provide the vectorised ``batch_matrices`` (all elements of a
class in one call); ``matrices`` is the same kernel on one element.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from modalab.core.errors import ModalabValueError

from updating.fe.elements.base import Element, ElementMatrices, six_dofs
from updating.fe.properties import ShellProperty

__all__ = ["Quad4", "Tria3"]

_g = 1.0 / np.sqrt(3.0)
_GAUSS2 = ((-_g, -_g), (_g, -_g), (_g, _g), (-_g, _g))
_XI = np.array([-1.0, 1.0, 1.0, -1.0])
_ETA = np.array([-1.0, -1.0, 1.0, 1.0])


def _q4(xi, eta):
    """Bilinear shape functions and their (ξ, η) derivatives (2×4)."""
    N = 0.25 * (1 + _XI * xi) * (1 + _ETA * eta)
    dN = np.array([0.25 * _XI * (1 + _ETA * eta), 0.25 * _ETA * (1 + _XI * xi)])
    return N, dN


def _constants(el, ctx):
    """(Dm, Db, Gs, G t, ρt + nsm, ρt³/12, ge) of the element's property and material."""
    prop = ctx.prop(el.pid)
    if not isinstance(prop, ShellProperty):
        raise ModalabValueError(f"element {el.eid} ({type(el).__name__}) refers to property {el.pid}, a "
                                f"{type(prop).__name__}; a shell element needs a ShellProperty (PSHELL)")
    mat = ctx.material(prop.mid)
    t = prop.t
    if not np.real(t) > 0:
        raise ModalabValueError(f"element {el.eid} ({type(el).__name__}): property {prop.pid} has thickness "
                                f"t = {t!r}; expected t > 0 m")
    E, nu, G = mat.E, mat.nu, mat.shear_modulus
    if nu is None:
        nu = E / (2.0 * G) - 1.0
    c = 1.0 / (1.0 - nu * nu)
    iso = np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, (1.0 - nu) / 2.0]], dtype=np.result_type(nu, float))
    Dm = E * t * c * iso
    Db = prop.bending * E * t ** 3 / 12.0 * c * iso
    Gs = prop.shear * G * t
    rho_a = mat.rho * t + prop.nsm          # mass per area
    rot = mat.rho * t ** 3 / 12.0           # rotary inertia per area
    ge = prop.ge if prop.ge is not None else mat.ge
    return Dm, Db, Gs, G * t, rho_a, rot, ge


def _constants_batch(elements, ctx):
    """Per-element arrays of :func:`_constants` (evaluated once per property)."""
    pids = np.array([el.pid for el in elements])
    uniq, inv = np.unique(pids, return_inverse=True)
    per = []
    for u in range(len(uniq)):
        per.append(_constants(elements[int(np.flatnonzero(inv == u)[0])], ctx))
    return tuple(np.asarray([v[k] for v in per])[inv] for k in range(7))


def _frame(elements, X):
    """Element frames of a batch: λ (n,3,3; rows = local axes in basic), local 2-D coordinates (n,k,2),
    areas (n,) and warp ratios (n,)."""
    k = X.shape[1]
    c = X.mean(axis=1)
    if k == 4:
        nv = np.cross(X[:, 2] - X[:, 0], X[:, 3] - X[:, 1])
    else:
        nv = np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0])
    nn = np.linalg.norm(nv, axis=1)
    scale = np.maximum(np.abs(X - c[:, None]).max(axis=(1, 2)), 1e-300)
    d = X[:, 1] - X[:, 0]
    dl = np.linalg.norm(d, axis=1)
    bad = np.flatnonzero((nn <= 1e-12 * scale * scale) | (dl <= 1e-9 * scale))
    if bad.size:
        el = elements[int(bad[0])]
        raise ModalabValueError(f"element {el.eid} ({type(el).__name__}) on nodes {el.nodes} has zero area "
                                "or a zero-length edge G1-G2 (coincident or collinear nodes); check the node "
                                "coordinates and order")
    ez = nv / nn[:, None]
    d = d - np.einsum("ni,ni->n", d, ez)[:, None] * ez
    ex = d / np.linalg.norm(d, axis=1)[:, None]
    ey = np.cross(ez, ex)
    lam = np.stack([ex, ey, ez], axis=1)
    loc = np.einsum("nkj,nij->nki", X - c[:, None], lam)
    area = 0.5 * nn
    warp = np.abs(loc[:, :, 2]).max(axis=1) / np.sqrt(area)
    return lam, loc[:, :, :2], area, warp


def _to_basic(A, lam):
    """Tᵀ A T per element with T = blockdiag(λ, λ, ...) (local DOFs u_l = λ u_basic per triplet)."""
    n, d, _ = A.shape
    m = d // 3
    A5 = A.reshape(n, m, 3, m, 3)
    return np.einsum("nip,naibj,njq->napbq", lam, A5, lam).reshape(n, d, d)


def _assemble_local(k, Km, Kb, Kd, NN, rho_a, rot, dt):
    """(n, 6k, 6k) local K and M from membrane (u, v), bending (w, θx, θy), drilling (u, v, θz) parts."""
    n = Km.shape[0]
    mem = np.array([6 * i + j for i in range(k) for j in (0, 1)])
    ben = np.array([6 * i + j for i in range(k) for j in (2, 3, 4)])
    uvr = np.array([6 * i + j for i in range(k) for j in (0, 1, 5)])
    K = np.zeros((n, 6 * k, 6 * k), dt)
    K[:, mem[:, None], mem[None, :]] += Km
    K[:, ben[:, None], ben[None, :]] += Kb
    K[:, uvr[:, None], uvr[None, :]] += Kd
    M = np.zeros((n, 6 * k, 6 * k), dt)
    for j in range(6):
        idx = np.arange(j, 6 * k, 6)
        coef = rho_a if j < 3 else rot
        M[:, idx[:, None], idx[None, :]] += coef[:, None, None] * NN
    return K, M


class _Shell(Element):
    frame = "basic"
    #: drilling penalty factor α (K_drill = α G t ∫ (θz − ω)² dA)
    drill = 1e-3
    #: largest accepted warp ratio max|h|/√A (h: node distance to the mean plane; quadrilaterals)
    warp_tol = 0.05

    def dofs(self) -> list:
        return six_dofs(self.nodes)

    def matrices(self, ctx) -> ElementMatrices:
        K, M, ge = type(self).batch_matrices([self], ctx)
        return ElementMatrices(self.dofs(), K=K[0], M=M[0], ge=ge[0])

    @classmethod
    def batch_matrices(cls, elements, ctx):
        """(K, M, ge) of many elements of this class: (n, 6k, 6k), (n, 6k, 6k), (n,) in basic axes."""
        k = cls._n_nodes
        for el in elements:
            if len(set(el.nodes)) != k:
                raise ModalabValueError(f"element {el.eid} ({cls.__name__}) has repeated nodes {el.nodes}; it "
                                        f"needs {k} different nodes")
        X = np.array([[ctx.xyz(nd) for nd in el.nodes] for el in elements], dtype=float)
        lam, xy, area, warp = _frame(elements, X)
        bad = np.flatnonzero(warp > cls.warp_tol)
        if bad.size:
            el = elements[int(bad[0])]
            raise ModalabValueError(f"element {el.eid} ({cls.__name__}) on nodes {el.nodes} is warped: ratio "
                                    f"max|h|/sqrt(A) = {warp[bad[0]]:.4g} > {cls.warp_tol}; split it into two "
                                    "Tria3 or make the four nodes coplanar")
        consts = _constants_batch(elements, ctx)
        if not ctx.coupled_mass:      # lumped: translational mass only (Nastran's lumped mass)
            consts = consts[:5] + (np.zeros_like(consts[5]),) + consts[6:]
        Kl, Ml = cls._local(elements, xy, area, consts, ctx.coupled_mass)
        return _to_basic(Kl, lam), _to_basic(Ml, lam), consts[-1]


@dataclass
class Quad4(_Shell):
    """Four-node flat shell (CQUAD4): MITC4 bending, incompatible-mode membrane, drilling penalty.

    eid : element id.  n1..n4 : corner nodes in order around the element.
    pid : id of a :class:`~updating.fe.properties.ShellProperty`.  group : label for parameters.
    See the module docstring for the formulation and the element frame.
    """

    eid: int
    n1: int
    n2: int
    n3: int
    n4: int
    pid: int
    group: str = ""

    _n_nodes = 4

    @property
    def nodes(self) -> tuple:
        return (self.n1, self.n2, self.n3, self.n4)

    @classmethod
    def _local(cls, elements, xy, area, consts, coupled):
        Dm, Db, Gs, Gt, rho_a, rot, _ = consts
        dt = np.result_type(Dm, Db, Gs, rho_a, rot, float)
        n = xy.shape[0]
        # Jacobian at the centre (incompatible modes, Taylor's modification)
        J0 = _q4_jacobian(xy, _q4(0.0, 0.0)[1])
        detJ0 = np.linalg.det(J0)
        J0inv = np.linalg.inv(J0)
        _q4_check_convex(elements, xy, detJ0)
        Kmm = np.zeros((n, 8, 8), dt)
        Kma = np.zeros((n, 8, 4), dt)
        Kaa = np.zeros((n, 4, 4), dt)
        Kb = np.zeros((n, 12, 12), dt)
        Ks = np.zeros((n, 12, 12), dt)
        Kd = np.zeros((n, 12, 12))        # (u, v, θz) per node
        NN = np.zeros((n, 4, 4))
        gA, gC, gB, gD = _mitc4_tying(xy)
        for xi, eta in _GAUSS2:
            N, dN = _q4(xi, eta)
            J = _q4_jacobian(xy, dN)
            detJ = np.linalg.det(J)
            Jinv = np.linalg.inv(J)
            w = detJ[:, None, None]
            dNx = np.einsum("nab,bk->nak", Jinv, dN)          # rows: ∂N/∂x, ∂N/∂y
            Bm = _q4_membrane_B(dNx)
            Ba = _q4_incompatible_B(detJ0, detJ, J0inv, xi, eta)
            DmBm = np.einsum("nij,njb->nib", Dm, Bm)
            Kmm += np.einsum("nia,nib->nab", Bm, DmBm) * w
            Kma += np.einsum("nia,nib->nab", DmBm, Ba) * w
            Kaa += np.einsum("nia,nij,njb->nab", Ba, Dm, Ba) * w
            Bb = _q4_bending_B(dNx)
            Kb += np.einsum("nia,nij,njb->nab", Bb, Db, Bb) * w
            g_xi = 0.5 * (1 + eta) * gA + 0.5 * (1 - eta) * gC
            g_eta = 0.5 * (1 + xi) * gD + 0.5 * (1 - xi) * gB
            Bs = np.einsum("nab,nbk->nak", Jinv, np.stack([g_xi, g_eta], axis=1))
            Ks += Gs[:, None, None] * np.einsum("nak,nal->nkl", Bs, Bs) * w
            bd = _q4_drill_b(dNx, N)
            Kd += np.einsum("nk,nl->nkl", bd, bd) * w
            NN += np.outer(N, N)[None] * w
        Km = Kmm - Kma @ np.linalg.solve(Kaa, np.swapaxes(Kma, 1, 2))
        if not coupled:
            NN = np.eye(4)[None] * (area / 4.0)[:, None, None]
        return _assemble_local(4, Km, Kb + Ks, cls.drill * Gt[:, None, None] * Kd, NN, rho_a, rot, dt)


# ------------------------------------------------------------------ Quad4 kernels (batched over n elements)
def _q4_jacobian(xy, dN):
    """Jacobians (n, 2, 2) at one point of the elements' local corner coordinates ``xy`` (n, 4, 2)."""
    return np.einsum("ak,nkb->nab", dN, xy)


def _q4_check_convex(elements, xy, detJ0) -> None:
    """A Jacobian not positive at a corner (a concave element or nodes out of order) is an error."""
    for (xi, eta) in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
        bad = np.flatnonzero(np.linalg.det(_q4_jacobian(xy, _q4(xi, eta)[1])) <= 1e-10 * np.abs(detJ0))
        if bad.size:
            el = elements[int(bad[0])]
            raise ModalabValueError(f"element {el.eid} (Quad4) on nodes {el.nodes} is not convex or its "
                                    f"nodes are not ordered around it (Jacobian <= 0 at corner ({xi}, {eta})); "
                                    "reorder the nodes or split it into two Tria3")


def _mitc4_tying(xy):
    """MITC4: covariant shear γ_ξ = ∂w/∂ξ + β·∂x/∂ξ tied at A (0, 1), C (0, −1); γ_η at B (−1, 0), D (1, 0).

    Returns the rows (γ_ξ at A, γ_ξ at C, γ_η at B, γ_η at D), each (n, 12) over (w, θx, θy) per node.
    """
    n = xy.shape[0]

    def cov(xi, eta):
        N, dN = _q4(xi, eta)
        J = _q4_jacobian(xy, dN)
        rx = np.zeros((n, 12))
        re = np.zeros((n, 12))
        rx[:, 0::3] = dN[0]
        rx[:, 1::3] = -N * J[:, 0, 1, None]
        rx[:, 2::3] = N * J[:, 0, 0, None]
        re[:, 0::3] = dN[1]
        re[:, 1::3] = -N * J[:, 1, 1, None]
        re[:, 2::3] = N * J[:, 1, 0, None]
        return rx, re

    gA, _ = cov(0.0, 1.0)
    gC, _ = cov(0.0, -1.0)
    _, gB = cov(-1.0, 0.0)
    _, gD = cov(1.0, 0.0)
    return gA, gC, gB, gD


def _q4_membrane_B(dNx):
    """Membrane strain-displacement matrices (n, 3, 8) over (u, v) per node."""
    Bm = np.zeros((dNx.shape[0], 3, 8))
    Bm[:, 0, 0::2] = dNx[:, 0]
    Bm[:, 1, 1::2] = dNx[:, 1]
    Bm[:, 2, 0::2] = dNx[:, 1]
    Bm[:, 2, 1::2] = dNx[:, 0]
    return Bm


def _q4_incompatible_B(detJ0, detJ, J0inv, xi, eta):
    """Incompatible-mode membrane strains (n, 3, 4) over (a1u, a2u, a1v, a2v), Taylor's modification."""
    dP = (detJ0 / detJ)[:, None, None] * np.einsum("nab,bc->nac", J0inv,
                                                   np.array([[-2.0 * xi, 0.0], [0.0, -2.0 * eta]]))
    Ba = np.zeros((detJ.shape[0], 3, 4))
    Ba[:, 0, 0:2] = dP[:, 0]
    Ba[:, 1, 2:4] = dP[:, 1]
    Ba[:, 2, 0:2] = dP[:, 1]
    Ba[:, 2, 2:4] = dP[:, 0]
    return Ba


def _q4_bending_B(dNx):
    """Curvature-displacement matrices (n, 3, 12) over (w, θx, θy) per node."""
    Bb = np.zeros((dNx.shape[0], 3, 12))
    Bb[:, 0, 2::3] = dNx[:, 0]
    Bb[:, 1, 1::3] = -dNx[:, 1]
    Bb[:, 2, 1::3] = -dNx[:, 0]
    Bb[:, 2, 2::3] = dNx[:, 1]
    return Bb


def _q4_drill_b(dNx, N):
    """Drilling strain θz − ½(∂v/∂x − ∂u/∂y), rows (n, 12) over (u, v, θz) per node."""
    bd = np.zeros((dNx.shape[0], 12))
    bd[:, 0::3] = 0.5 * dNx[:, 1]
    bd[:, 1::3] = -0.5 * dNx[:, 0]
    bd[:, 2::3] = N
    return bd


# ------------------------------------------------------------------ DKT
def _dkt_B(xy, xi, eta):
    """DKT curvature matrices B (n×3×9) at area coordinates (ξ = L2, η = L3); DOFs (w, θx, θy) per node.

    Batoz, Bathe & Ho (1980): β_x = H_xᵀ U, β_y = H_yᵀ U with θx = ∂w/∂y, θy = −∂w/∂x;
    κ = [∂β_x/∂x, ∂β_y/∂y, ∂β_x/∂y + ∂β_y/∂x].
    """
    x, y = xy[:, :, 0], xy[:, :, 1]
    x23, x31, x12 = x[:, 1] - x[:, 2], x[:, 2] - x[:, 0], x[:, 0] - x[:, 1]
    y23, y31, y12 = y[:, 1] - y[:, 2], y[:, 2] - y[:, 0], y[:, 0] - y[:, 1]
    P, q, r, t = {}, {}, {}, {}
    for k, (a, b) in {4: (x23, y23), 5: (x31, y31), 6: (x12, y12)}.items():
        l2 = a * a + b * b
        P[k], q[k], r[k], t[k] = -6 * a / l2, 3 * a * b / l2, 3 * b * b / l2, -6 * b / l2
    P4, P5, P6 = P[4], P[5], P[6]
    q4, q5, q6 = q[4], q[5], q[6]
    r4, r5, r6 = r[4], r[5], r[6]
    t4, t5, t6 = t[4], t[5], t[6]
    a, e = 1 - 2 * xi, 1 - 2 * eta
    Hx_xi = np.array([P6 * a + (P5 - P6) * eta, q6 * a - (q5 + q6) * eta,
                      -4 + 6 * (xi + eta) + r6 * a - eta * (r5 + r6),
                      -P6 * a + eta * (P4 + P6), q6 * a - eta * (q6 - q4), -2 + 6 * xi + r6 * a + eta * (r4 - r6),
                      -eta * (P5 + P4), eta * (q4 - q5), -eta * (r5 - r4)])
    Hy_xi = np.array([t6 * a + eta * (t5 - t6), 1 + r6 * a - eta * (r5 + r6), -q6 * a + eta * (q5 + q6),
                      -t6 * a + eta * (t4 + t6), -1 + r6 * a + eta * (r4 - r6), -q6 * a - eta * (q4 - q6),
                      -eta * (t4 + t5), eta * (r4 - r5), -eta * (q4 - q5)])
    Hx_eta = np.array([-P5 * e - xi * (P6 - P5), q5 * e - xi * (q5 + q6),
                       -4 + 6 * (xi + eta) + r5 * e - xi * (r5 + r6),
                       xi * (P4 + P6), xi * (q4 - q6), -xi * (r6 - r4),
                       P5 * e - xi * (P4 + P5), q5 * e + xi * (q4 - q5), -2 + 6 * eta + r5 * e + xi * (r4 - r5)])
    Hy_eta = np.array([-t5 * e - xi * (t6 - t5), 1 + r5 * e - xi * (r5 + r6), -q5 * e + xi * (q5 + q6),
                       xi * (t4 + t6), xi * (r4 - r6), -xi * (q4 - q6),
                       t5 * e - xi * (t4 + t5), -1 + r5 * e + xi * (r4 - r5), -q5 * e - xi * (q4 - q5)])
    twoA = x31 * y12 - x12 * y31
    B = np.array([y31 * Hx_xi + y12 * Hx_eta,
                  -x31 * Hy_xi - x12 * Hy_eta,
                  -x31 * Hx_xi - x12 * Hx_eta + y31 * Hy_xi + y12 * Hy_eta]) / twoA   # (3, 9, n)
    return np.transpose(B, (2, 0, 1))


@dataclass
class Tria3(_Shell):
    """Three-node flat shell (CTRIA3): CST membrane, DKT bending (Batoz et al. 1980), drilling penalty.

    eid : element id.  n1, n2, n3 : corner nodes.  pid : id of a
    :class:`~updating.fe.properties.ShellProperty`.  group : label for parameters.
    """

    eid: int
    n1: int
    n2: int
    n3: int
    pid: int
    group: str = ""

    _n_nodes = 3

    @property
    def nodes(self) -> tuple:
        return (self.n1, self.n2, self.n3)

    @classmethod
    def _local(cls, elements, xy, area, consts, coupled):
        Dm, Db, Gs, Gt, rho_a, rot, _ = consts
        dt = np.result_type(Dm, Db, rho_a, rot, float)
        n = xy.shape[0]
        x, y = xy[:, :, 0], xy[:, :, 1]
        A2 = (2 * area)[:, None]
        b = np.stack([y[:, 1] - y[:, 2], y[:, 2] - y[:, 0], y[:, 0] - y[:, 1]], axis=1) / A2   # ∂L_i/∂x
        c = np.stack([x[:, 2] - x[:, 1], x[:, 0] - x[:, 2], x[:, 1] - x[:, 0]], axis=1) / A2   # ∂L_i/∂y
        Bm = np.zeros((n, 3, 6))
        Bm[:, 0, 0::2] = b
        Bm[:, 1, 1::2] = c
        Bm[:, 2, 0::2] = c
        Bm[:, 2, 1::2] = b
        w = area[:, None, None]
        Km = np.einsum("nia,nij,njb->nab", Bm, Dm, Bm) * w
        Kb = np.zeros((n, 9, 9), dt)
        Kd = np.zeros((n, 9, 9))
        for xi, eta in ((0.5, 0.0), (0.5, 0.5), (0.0, 0.5)):
            B = _dkt_B(xy, xi, eta)
            Kb += np.einsum("nia,nij,njb->nab", B, Db, B) * (w / 3.0)
            bd = np.zeros((n, 9))
            bd[:, 0::3] = 0.5 * c
            bd[:, 1::3] = -0.5 * b
            bd[:, 2::3] = np.array([1 - xi - eta, xi, eta])
            Kd += np.einsum("nk,nl->nkl", bd, bd) * (w / 3.0)
        if coupled:
            NN = (np.ones((3, 3)) + np.eye(3))[None] * (area / 12.0)[:, None, None]
        else:
            NN = np.eye(3)[None] * (area / 3.0)[:, None, None]
        return _assemble_local(3, Km, Kb, cls.drill * Gt[:, None, None] * Kd, NN, rho_a, rot, dt)
