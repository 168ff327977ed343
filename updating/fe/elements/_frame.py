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

from modalab.errors import ModalabValueError


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


def transformation(lam: np.ndarray, n_nodes: int = 2) -> np.ndarray:
    """Block-diagonal T with u_local = T u_basic (2 triplets per node)."""
    T = np.zeros((6 * n_nodes, 6 * n_nodes))
    for k in range(2 * n_nodes):
        T[3 * k:3 * k + 3, 3 * k:3 * k + 3] = lam
    return T


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


def frame_local(L, E, G, rho, A, Iy, Iz, J, Ip, nsm, *, shear_y=None, shear_z=None,
                lumped=False, rotary=False):
    """Local 12×12 stiffness and mass of a 3-D frame element.

    shear_y, shear_z : shear factors κ for Timoshenko behaviour in the x–y and
    x–z planes (None: shear-rigid).  rotary : include rotary inertia of bending.
    lumped : Nastran-style lumped mass (half the translational mass at each
    node, no rotary or torsional inertia), as with PARAM COUPMASS < 0.
    """
    dtype = np.result_type(E, G, rho, A, Iy, Iz, J, Ip, nsm, float)
    K = np.zeros((12, 12), dtype)
    M = np.zeros((12, 12), dtype)
    iu, it = [0, 6], [3, 9]
    K[np.ix_(iu, iu)] = _axial(E * A / L)
    K[np.ix_(it, it)] = _axial(G * J / L)
    phi_z = 12 * E * Iz / (shear_y * G * A * L * L) if shear_y else 0.0   # x–y plane
    phi_y = 12 * E * Iy / (shear_z * G * A * L * L) if shear_z else 0.0   # x–z plane
    ixy = [1, 5, 7, 11]                      # v1, θz1, v2, θz2 ; θz = v'
    ixz = [2, 4, 8, 10]                      # w1, θy1, w2, θy2 ; θy = −w'
    S = np.diag([1.0, -1.0, 1.0, -1.0])
    K[np.ix_(ixy, ixy)] = _bending_K(E * Iz, L, phi_z)
    K[np.ix_(ixz, ixz)] = S @ _bending_K(E * Iy, L, phi_y) @ S
    m = rho * A + nsm
    if lumped:
        for k in (0, 1, 2, 6, 7, 8):
            M[k, k] = m * L / 2
        return K, M
    M[np.ix_(iu, iu)] = m * L / 6 * np.array([[2, 1], [1, 2]])
    M[np.ix_(it, it)] = rho * Ip * L / 6 * np.array([[2, 1], [1, 2]])
    M[np.ix_(ixy, ixy)] = _bending_M(m, rho * Iz if rotary else 0.0, L, phi_z)
    M[np.ix_(ixz, ixz)] = S @ _bending_M(m, rho * Iy if rotary else 0.0, L, phi_y) @ S
    return K, M
