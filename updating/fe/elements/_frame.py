"""Shared kernels of the 3-D frame elements: local axes and 12×12 local matrices.

Local DOF order per node: u, v, w, θx, θy, θz (12 per element).  Bending in
the local x–y plane uses (v, θz) with θz = v′ and inertia Iz; bending in the
x–z plane uses (w, θy) with θy = −w′ and inertia Iy.

Bending matrices are those of the shear-deformable two-node element with
interdependent interpolation (Friedman & Kosmatka, Comput. Struct. 47, 1993);
with φ = 12 E I /(κ G A L²) = 0 they reduce exactly to the Euler–Bernoulli
cubic (Hermite) element of Przemieniecki (1968).
"""
from __future__ import annotations

import numpy as np

from modalab.core.errors import ModalabValueError


def local_axes(x1, x2, v, eid) -> tuple[float, np.ndarray]:
    """Length and 3×3 rotation λ (rows: local x, y, z in basic) for the element from x1 to x2.

    ``v`` is the orientation vector (Nastran CBAR v): local y is the part of v
    orthogonal to local x.
    """
    d = np.asarray(x2, float) - np.asarray(x1, float)
    L = float(np.sqrt(d @ d))
    if L <= 0:
        raise ModalabValueError(f"element {eid} has zero length (its two nodes coincide); "
                                "check the node coordinates")
    ex = d / L
    v = np.asarray(v, float)
    if v.shape != (3,):
        raise ModalabValueError(f"element {eid}: orientation vector {v!r}; expected three components")
    ez = np.cross(ex, v)
    nz = np.sqrt(ez @ ez)
    if nz < 1e-8 * max(np.sqrt(v @ v), 1e-300):
        raise ModalabValueError(f"element {eid}: orientation vector {tuple(v)} is parallel to the element "
                                f"axis {tuple(np.round(ex, 6))}; give a vector that is not along the beam")
    ez = ez / nz
    ey = np.cross(ez, ex)
    return L, np.vstack([ex, ey, ez])


def _bending_K(EI, L, phi):
    c = EI / ((1 + phi) * L ** 3)
    return c * np.array([
        [12, 6 * L, -12, 6 * L],
        [6 * L, (4 + phi) * L * L, -6 * L, (2 - phi) * L * L],
        [-12, -6 * L, 12, -6 * L],
        [6 * L, (2 - phi) * L * L, -6 * L, (4 + phi) * L * L]])


def _bending_M(m, rhoI, L, phi):
    """Translational (m = mass per length) plus rotary (rhoI) consistent mass, (w, w′) order."""
    p2 = phi * phi
    c = m * L / (210 * (1 + phi) ** 2)
    m11 = 70 * p2 + 147 * phi + 78
    m12 = (35 * p2 + 77 * phi + 44) * L / 4
    m13 = 35 * p2 + 63 * phi + 27
    m14 = -(35 * p2 + 63 * phi + 26) * L / 4
    m22 = (7 * p2 + 14 * phi + 8) * L * L / 4
    m24 = -(7 * p2 + 14 * phi + 6) * L * L / 4
    Mt = c * np.array([[m11, m12, m13, m14],
                       [m12, m22, -m14, m24],
                       [m13, -m14, m11, -m12],
                       [m14, m24, -m12, m22]])
    r = rhoI / (30 * (1 + phi) ** 2 * L)
    a = (3 - 15 * phi) * L
    b = (10 * p2 + 5 * phi + 4) * L * L
    e = (5 * p2 - 5 * phi - 1) * L * L
    Mr = r * np.array([[36, a, -36, a],
                       [a, b, -a, e],
                       [-36, -a, 36, -a],
                       [a, e, -a, b]])
    return Mt + Mr


def _axial(k):
    return k * np.array([[1, -1], [-1, 1]])


# ------------------------------------------------------------------ batched
def _fill(n, dtype, entries):
    """(n, r, c) array from a nested list of scalars/(n,) arrays."""
    r, c = len(entries), len(entries[0])
    out = np.zeros((n, r, c), dtype)
    for i in range(r):
        for j in range(c):
            out[:, i, j] = entries[i][j]
    return out


def local_axes_batch(x1, x2, v, eids):
    """Lengths (n,) and rotations (n, 3, 3) of many elements (see :func:`local_axes`)."""
    d = x2 - x1
    L = np.sqrt(np.einsum("ij,ij->i", d, d))
    bad = np.flatnonzero(L <= 0)
    if bad.size:
        raise ModalabValueError(f"element {eids[bad[0]]} has zero length (its two nodes coincide); "
                                "check the node coordinates")
    ex = d / L[:, None]
    ez = np.cross(ex, v)
    nz = np.sqrt(np.einsum("ij,ij->i", ez, ez))
    nv = np.sqrt(np.einsum("ij,ij->i", v, v))
    bad = np.flatnonzero(~(nz >= 1e-8 * np.maximum(nv, 1e-300)) | (nv == 0))
    if bad.size:
        k = bad[0]
        raise ModalabValueError(f"element {eids[k]}: orientation vector {tuple(v[k])} is parallel to the element "
                                f"axis {tuple(np.round(ex[k], 6))}; give a vector that is not along the beam")
    ez = ez / nz[:, None]
    ey = np.cross(ez, ex)
    return L, np.stack([ex, ey, ez], axis=1)


def _bending_K_batch(EI, L, phi, n, dtype):
    c = EI / ((1 + phi) * L ** 3)
    L2 = L * L
    return c[:, None, None] * _fill(n, dtype, [
        [12, 6 * L, -12, 6 * L],
        [6 * L, (4 + phi) * L2, -6 * L, (2 - phi) * L2],
        [-12, -6 * L, 12, -6 * L],
        [6 * L, (2 - phi) * L2, -6 * L, (4 + phi) * L2]])


def _bending_M_batch(m, rhoI, L, phi, n, dtype):
    p2 = phi * phi
    c = m * L / (210 * (1 + phi) ** 2)
    m11 = 70 * p2 + 147 * phi + 78
    m12 = (35 * p2 + 77 * phi + 44) * L / 4
    m13 = 35 * p2 + 63 * phi + 27
    m14 = -(35 * p2 + 63 * phi + 26) * L / 4
    m22 = (7 * p2 + 14 * phi + 8) * L * L / 4
    m24 = -(7 * p2 + 14 * phi + 6) * L * L / 4
    Mt = c[:, None, None] * _fill(n, dtype, [[m11, m12, m13, m14], [m12, m22, -m14, m24],
                                             [m13, -m14, m11, -m12], [m14, m24, -m12, m22]])
    r = rhoI / (30 * (1 + phi) ** 2 * L)
    a = (3 - 15 * phi) * L
    b = (10 * p2 + 5 * phi + 4) * L * L
    e = (5 * p2 - 5 * phi - 1) * L * L
    Mr = r[:, None, None] * _fill(n, dtype, [[36, a, -36, a], [a, b, -a, e], [-36, -a, 36, -a], [a, e, -a, b]])
    return Mt + Mr


def frame_local_batch(L, E, G, rho, A, Iy, Iz, J, Ip, nsm, *, shear_y=None, shear_z=None,
                      lumped=False, rotary=False, lumped_torsion=False, e_over_g=None):
    """Local 12×12 stiffness and mass of n 3-D frame elements (every argument an (n,) array).

    shear_y, shear_z : shear factors κ (n,) for Timoshenko behaviour in the x–y and
    x–z planes (None, or 0 for an element: shear-rigid).  rotary : include rotary
    inertia of bending.  lumped : Nastran-style lumped mass (half the translational
    mass at each node, no rotary inertia), as with PARAM COUPMASS < 0; with the torsional inertia
    ρ·Ip·L/2 at each node where ``lumped_torsion`` (bool or (n,) bool: Nastran's CBEAM), none elsewhere (CBAR).
    e_over_g : E/G (n,) for the shear parameter φ = 12 (E/G) I / (κ A L²); None: E / G.  Give 2(1+ν) where G is
    derived from E, so that φ does not depend on E even in complex arithmetic: E/G of a complex-step E is E's
    round-off in its imaginary part, a spurious ∂M/∂E and ∂K/∂E non-linear in E (``updating.methods.mci_condensed``
    then assembles every parameter derivative at every step instead of caching them).
    """
    n = L.shape[0]
    dtype = np.result_type(E, G, rho, A, Iy, Iz, J, Ip, nsm, float)
    K = np.zeros((n, 12, 12), dtype)
    M = np.zeros((n, 12, 12), dtype)
    B = np.array([[1.0, -1.0], [-1.0, 1.0]])
    iu, it = np.array([0, 6]), np.array([3, 9])
    K[:, iu[:, None], iu[None, :]] = (E * A / L)[:, None, None] * B
    K[:, it[:, None], it[None, :]] = (G * J / L)[:, None, None] * B
    zero = np.zeros(n)
    eg = E / G if e_over_g is None else e_over_g

    def shear_phi(I, k):
        # k = 0 (or None) marks a shear-rigid plane
        if k is None:
            return zero
        on = np.real(k) > 0
        return np.where(on, 12 * eg * I / (np.where(on, k, 1.0) * A * L * L), 0.0)

    phi_z = shear_phi(Iz, shear_y)
    phi_y = shear_phi(Iy, shear_z)
    ixy = np.array([1, 5, 7, 11])
    ixz = np.array([2, 4, 8, 10])
    S = np.array([1.0, -1.0, 1.0, -1.0])
    SS = S[:, None] * S[None, :]
    K[:, ixy[:, None], ixy[None, :]] = _bending_K_batch(E * Iz, L, phi_z, n, dtype)
    K[:, ixz[:, None], ixz[None, :]] = SS * _bending_K_batch(E * Iy, L, phi_y, n, dtype)
    m = rho * A + nsm
    if lumped:
        for k in (0, 1, 2, 6, 7, 8):
            M[:, k, k] = m * L / 2
        tors = np.where(np.broadcast_to(np.asarray(lumped_torsion, bool), (n,)), rho * Ip * L / 2, 0.0)
        M[:, 3, 3] = M[:, 9, 9] = tors
        return K, M
    C = np.array([[2.0, 1.0], [1.0, 2.0]])
    M[:, iu[:, None], iu[None, :]] = (m * L / 6)[:, None, None] * C
    M[:, it[:, None], it[None, :]] = (rho * Ip * L / 6)[:, None, None] * C
    M[:, ixy[:, None], ixy[None, :]] = _bending_M_batch(m, rho * Iz if rotary else zero, L, phi_z, n, dtype)
    M[:, ixz[:, None], ixz[None, :]] = SS * _bending_M_batch(m, rho * Iy if rotary else zero, L, phi_y, n, dtype)
    return K, M


def to_basic(A, lam):
    """Rotate (n, 12, 12) local matrices to basic: Tᵀ A T with T = blockdiag(λ) per triplet."""
    n = A.shape[0]
    Ar = A.reshape(n, 4, 3, 4, 3)
    out = np.einsum("nij,naibk,nkl->najbl", lam, Ar, lam, optimize=True)
    return out.reshape(n, 12, 12)
