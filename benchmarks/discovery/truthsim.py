"""Independent truth simulator of the discovery benchmark (numpy/scipy only).

Nothing here imports modalab, ``updating``, ``hardware_sim`` or ``identification``: the truth structures are
built with their own elements, their own damping model and their own frequency-response solver, so that the
benchmark does not share code with the diagnosis it judges (no inverse crime).

* Element: the 3-D two-node Timoshenko beam (shear deformation and rotary inertia) with the exact-interpolation
  stiffness of Przemieniecki (1968, ch. 5) and the consistent mass of Friedman & Kosmatka (1993, Comput. Struct.
  47, 473), axial and torsion by linear interpolation; polar mass moment rho*(Iy+Iz).
* Damping: hysteretic, a complex stiffness (1 + i*eta) per element (loss factor per section) and per spring.
* Joints: a twin node shares five global components with its master; the sixth (a rotation about a global axis)
  is its own DOF, tied to the master's by a rotational spring (an exact joint flexibility, no penalty).
* FRF: exact direct frequency response, receptance X = (K* - w^2 M)^-1 F solved by sparse LU at every line.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

__all__ = ["Section", "tube", "box", "beam_matrices", "TruthModel"]


@dataclass(frozen=True)
class Section:
    """Cross-section constants (SI): area, second moments about local y and z, torsion constant, shear factors."""

    A: float
    Iy: float
    Iz: float
    J: float
    ky: float
    kz: float


def tube(ro: float, ri: float) -> Section:
    """Circular tube; shear factor of a thin circular tube (Cowper 1966): k = 2(1+nu)/(4+3nu) ~ 0.53 -> 0.5."""
    A = np.pi * (ro ** 2 - ri ** 2)
    Ib = np.pi * (ro ** 4 - ri ** 4) / 4
    m = ri / ro
    nu = 0.3
    k = 6 * (1 + nu) * (1 + m * m) ** 2 / ((7 + 6 * nu) * (1 + m * m) ** 2 + (20 + 12 * nu) * m * m)  # Cowper
    return Section(A, Ib, Ib, 2 * Ib, k, k)


def box(b: float, h: float, t: float) -> Section:
    """Rectangular tube b (along local y) x h (along local z), wall t: Bredt torsion, shear by the webs."""
    bi, hi = b - 2 * t, h - 2 * t
    A = b * h - bi * hi
    Iy = (b * h ** 3 - bi * hi ** 3) / 12      # bending about local y (deflection along z)
    Iz = (h * b ** 3 - hi * bi ** 3) / 12
    Am = (b - t) * (h - t)
    J = 4 * Am ** 2 * t / (2 * (b - t) + 2 * (h - t))
    ky = 2 * b * t / A                        # shear along y carried by the walls parallel to y
    kz = 2 * h * t / A
    return Section(A, Iy, Iz, J, ky, kz)


def _bend(EI, L, phi, rhoA, rhoI):
    """4x4 stiffness and mass of one bending plane (w1, th1, w2, th2), th = +dw/dx (Friedman & Kosmatka)."""
    c = EI / ((1 + phi) * L ** 3)
    K = c * np.array([[12, 6 * L, -12, 6 * L],
                      [6 * L, (4 + phi) * L * L, -6 * L, (2 - phi) * L * L],
                      [-12, -6 * L, 12, -6 * L],
                      [6 * L, (2 - phi) * L * L, -6 * L, (4 + phi) * L * L]])
    p = phi
    a = rhoA * L / (210 * (1 + p) ** 2)
    m11 = 70 * p * p + 147 * p + 78
    m12 = (35 * p * p + 77 * p + 44) * L / 4
    m13 = 35 * p * p + 63 * p + 27
    m14 = -(35 * p * p + 63 * p + 26) * L / 4
    m22 = (7 * p * p + 14 * p + 8) * L * L / 4
    m24 = -(7 * p * p + 14 * p + 6) * L * L / 4
    Mt = a * np.array([[m11, m12, m13, m14],
                       [m12, m22, -m14, m24],
                       [m13, -m14, m11, -m12],
                       [m14, m24, -m12, m22]])
    r = rhoI / (30 * (1 + p) ** 2 * L)
    q = (3 - 15 * p) * L
    d = (4 + 5 * p + 10 * p * p) * L * L
    e = (-1 - 5 * p + 5 * p * p) * L * L
    Mr = r * np.array([[36, q, -36, q],
                       [q, d, -q, e],
                       [-36, -q, 36, -q],
                       [q, e, -q, d]])
    return K, Mt + Mr


def beam_matrices(x1, x2, vref, sec: Section, E: float, G: float, rho: float):
    """12x12 global stiffness and mass of a Timoshenko beam from x1 to x2; local y in the plane of (axis, vref)."""
    x1, x2 = np.asarray(x1, float), np.asarray(x2, float)
    d = x2 - x1
    L = float(np.linalg.norm(d))
    e1 = d / L
    e3 = np.cross(e1, vref)
    e3 /= np.linalg.norm(e3)
    e2 = np.cross(e3, e1)
    R = np.vstack([e1, e2, e3])
    K = np.zeros((12, 12))
    M = np.zeros((12, 12))
    # axial and torsion
    for i, j, k, m in ((0, 6, E * sec.A / L, rho * sec.A * L / 6), (3, 9, G * sec.J / L, rho * (sec.Iy + sec.Iz) * L / 6)):
        K[np.ix_([i, j], [i, j])] += k * np.array([[1, -1], [-1, 1]])
        M[np.ix_([i, j], [i, j])] += m * np.array([[2, 1], [1, 2]])
    # x-y plane: v and theta_z (theta_z = +dv/dx)
    phi_y = 12 * E * sec.Iz / (sec.ky * G * sec.A * L * L)
    Kb, Mb = _bend(E * sec.Iz, L, phi_y, rho * sec.A, rho * sec.Iz)
    idx = [1, 5, 7, 11]
    K[np.ix_(idx, idx)] += Kb
    M[np.ix_(idx, idx)] += Mb
    # x-z plane: w and theta_y (theta_y = -dw/dx)
    phi_z = 12 * E * sec.Iy / (sec.kz * G * sec.A * L * L)
    Kb, Mb = _bend(E * sec.Iy, L, phi_z, rho * sec.A, rho * sec.Iy)
    S = np.diag([1.0, -1.0, 1.0, -1.0])
    idx = [2, 4, 8, 10]
    K[np.ix_(idx, idx)] += S @ Kb @ S
    M[np.ix_(idx, idx)] += S @ Mb @ S
    T = np.zeros((12, 12))
    for b in range(4):
        T[3 * b:3 * b + 3, 3 * b:3 * b + 3] = R
    return T.T @ K @ T, T.T @ M @ T


@dataclass
class TruthModel:
    """A beam structure assembled with :func:`beam_matrices`; DOFs are 6 per node in the global axes.

    ``twin(master, new, axis)`` makes ``new`` share the master's DOFs except the rotation about ``axis``
    (0, 1, 2 = X, Y, Z); :meth:`spring` adds a (complex) spring between two DOFs or to ground.
    """

    nodes: dict = field(default_factory=dict)          # id -> xyz
    _dof: dict = field(default_factory=dict)           # id -> 6 global indices
    _n: int = 0
    _trip: list = field(default_factory=list)          # (rows, cols, K, M, eta) element blocks
    _fixed: set = field(default_factory=set)
    _tags: list = field(default_factory=list)          # one tag per entry of _trip (e.g. the nominal element)

    def add_node(self, nid, xyz):
        if nid in self.nodes:
            raise ValueError(f"node {nid} exists")
        self.nodes[nid] = np.asarray(xyz, float)
        self._dof[nid] = np.arange(self._n, self._n + 6)
        self._n += 6

    def twin(self, master, new, axis):
        self.nodes[new] = self.nodes[master].copy()
        d = self._dof[master].copy()
        d[3 + axis] = self._n
        self._n += 1
        self._dof[new] = d

    def dof(self, nid, comp):
        """Global index of component comp (1..6) of node nid."""
        return int(self._dof[nid][comp - 1])

    def beam(self, n1, n2, vref, sec, E, G, rho, eta, tag=None):
        K, M = beam_matrices(self.nodes[n1], self.nodes[n2], vref, sec, E, G, rho)
        idx = np.concatenate([self._dof[n1], self._dof[n2]])
        self._trip.append((idx, K, M, eta))
        self._tags.append(tag)

    def spring(self, a, b, k, eta=0.0):
        """Spring of stiffness k between global DOF a and b (b None: to ground)."""
        if b is None:
            self._trip.append((np.array([a]), np.array([[k]]), np.zeros((1, 1)), eta))
        else:
            self._trip.append((np.array([a, b]), k * np.array([[1.0, -1.0], [-1.0, 1.0]]), np.zeros((2, 2)), eta))
        self._tags.append(None)

    def mass(self, nid, m, inertia=(0.0, 0.0, 0.0)):
        idx = self._dof[nid]
        M = np.diag([m, m, m, *inertia])
        self._trip.append((idx, np.zeros((6, 6)), M, 0.0))
        self._tags.append(None)

    def fix(self, nid, comps="123456"):
        for c in comps:
            self._fixed.add(self.dof(nid, int(c)))

    # ------------------------------------------------------------------ assembly
    def free_dofs(self):
        return np.setdiff1d(np.arange(self._n), np.fromiter(self._fixed, int, len(self._fixed)))

    def matrices(self, damped=True):
        """(K, M) sparse on the free DOFs; K complex (hysteretic) when ``damped``."""
        rows, cols, kv, mv = [], [], [], []
        for idx, K, M, eta in self._trip:
            r = np.repeat(idx, idx.size)
            c = np.tile(idx, idx.size)
            rows.append(r)
            cols.append(c)
            kv.append((K * (1 + 1j * eta) if damped else K.astype(complex)).ravel())
            mv.append(M.ravel())
        r, c = np.concatenate(rows), np.concatenate(cols)
        n = self._n
        K = sp.coo_matrix((np.concatenate(kv), (r, c)), shape=(n, n)).tocsc()
        M = sp.coo_matrix((np.concatenate(mv), (r, c)), shape=(n, n)).tocsc()
        f = self.free_dofs()
        K = K[f][:, f]
        M = M[f][:, f]
        if not damped:
            K = K.real
        return K, M

    def frequencies(self, n=20):
        """Lowest n undamped natural frequencies (Hz), rigid-body modes included (as ~0)."""
        return self.modes(n, vectors=False)

    def modes(self, n=20, vectors=True):
        """Lowest n undamped modes: frequencies (Hz) and, with ``vectors``, mass-normalised shapes on the free DOFs."""
        K, M = self.matrices(damped=False)
        n = min(n, K.shape[0] - 2)
        v0 = 1.0 + 0.5 * np.sin(np.arange(K.shape[0]) * 0.7)          # fixed start vector: deterministic
        out = spla.eigsh(K, k=n, M=M, sigma=-10.0, which="LM", return_eigenvectors=vectors, v0=v0)
        lam, phi = out if vectors else (out, None)
        o = np.argsort(lam)
        f = np.sqrt(np.clip(lam[o], 0, None)) / (2 * np.pi)
        return (f, phi[:, o]) if vectors else f

    def energy_fractions(self, phi):
        """{tag: strain-energy fraction per mode (array)} of the tagged elements for the shapes phi (free DOFs)."""
        f = self.free_dofs()
        pos = np.full(self._n, -1)
        pos[f] = np.arange(f.size)
        total = np.zeros(phi.shape[1])
        per: dict = {}
        for (idx, K, _, _), tag in zip(self._trip, self._tags):
            p = pos[idx]
            ok = p >= 0
            v = np.zeros((idx.size, phi.shape[1]))
            v[ok] = phi[p[ok]]
            e = np.einsum("im,ij,jm->m", v, K, v)
            total += e
            if tag is not None:
                per[tag] = per.get(tag, 0.0) + e
        return {t: e / np.maximum(total, 1e-300) for t, e in per.items()}

    def receptance(self, freq_hz, out_dofs, in_dofs):
        """Receptance X[out, in, line] (m/N) by exact direct frequency response at every line.

        out_dofs/in_dofs: lists of (node, comp) with comp 1..6.
        """
        K, M = self.matrices(damped=True)
        f = self.free_dofs()
        pos = {g: i for i, g in enumerate(f)}
        oi = np.array([pos[self.dof(n, c)] for n, c in out_dofs])
        ii = np.array([pos[self.dof(n, c)] for n, c in in_dofs])
        F = np.zeros((K.shape[0], ii.size), complex)
        F[ii, np.arange(ii.size)] = 1.0
        X = np.empty((oi.size, ii.size, len(freq_hz)), complex)
        for k, fh in enumerate(freq_hz):
            w2 = (2 * np.pi * fh) ** 2
            lu = spla.splu((K - w2 * M).tocsc(), permc_spec="MMD_AT_PLUS_A")
            X[:, :, k] = lu.solve(F)[oi]
        return X
