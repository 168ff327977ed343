"""Scaling of the updating kernels (issue 6).

(a) All eigenvalue sensitivities of a ≥100k-DOF sparse model for P = 10, 100, 1000
    parameters, side by side with one eigen-solution (target ≤ 1.5×, independent of P)
    and with central finite differences (2P eigen-solutions, extrapolated from one
    timed re-solution).
(b) One MCI coefficient-matrix assembly (Eq. 3.77, all 3000 rows) and one
    response-function assembly (Eq. 3.56–3.57, normal equations, 30 measured DOFs) for a
    3000-DOF model with 1000 parameters and 1000 frequency lines, against the thesis'
    estimate of "a couple of months" for its aircraft.

Run:  python benchmarks/sensitivity_scaling.py  [--side 320] [--modes 10]
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from modalab.core.eigen import start_vector
from updating.methods.mci import mci_system
from updating.fe.parametric import Derivative, MatrixModel
from updating.methods.rfm import receptance_rows, rfm_system
from updating.fe.sensitivity import ModalSolution, StackedDerivatives, _normalise, eigenvalue_sensitivities


def grid_springs(nx, ny):
    """Edges (a, b) of an nx × ny grid of scalar DOFs plus grounding springs (b = -1) on the left edge."""
    idx = np.arange(nx * ny).reshape(ny, nx)
    h = np.c_[idx[:, :-1].ravel(), idx[:, 1:].ravel()]
    v = np.c_[idx[:-1, :].ravel(), idx[1:, :].ravel()]
    g = np.c_[idx[:, 0], np.full(ny, -1)]
    return np.vstack([h, v, g])


def spring_matrix(n, edges, k=None):
    """Assembled stiffness of springs ``edges`` (b = -1: to ground) with stiffnesses k (default 1)."""
    a, b = edges[:, 0], edges[:, 1]
    k = np.ones(len(a)) if k is None else k
    g = b < 0
    rows = np.r_[a, b[~g], a[~g], b[~g]]
    cols = np.r_[a, b[~g], b[~g], a[~g]]
    vals = np.r_[k, k[~g], -k[~g], -k[~g]]
    return sp.csr_matrix((vals, (rows, cols)), shape=(n, n))


def grid_model(nx, ny, P, *, damping=False, seed=0):
    """Grid model whose springs are split into P (or P−masses) groups by position; masses in groups too."""
    rng = np.random.default_rng(seed)
    n = nx * ny
    edges = grid_springs(nx, ny)
    kvals = 1e4 * rng.uniform(0.8, 1.2, len(edges))
    n_mass_groups = max(1, P // 10)
    n_damp_groups = max(1, P // 10) if damping else 0
    n_spring_groups = P - n_mass_groups - n_damp_groups
    sg = np.minimum((np.arange(len(edges)) * n_spring_groups) // len(edges), n_spring_groups - 1)
    mg = np.minimum((np.arange(n) * n_mass_groups) // n, n_mass_groups - 1)
    terms = []
    order = np.argsort(sg, kind="stable")
    bounds = np.searchsorted(sg[order], np.arange(n_spring_groups + 1))
    for q in range(n_spring_groups):
        e = order[bounds[q]:bounds[q + 1]]
        terms.append((f"k{q}", Derivative(dK=spring_matrix(n, edges[e], kvals[e]))))
    for q in range(n_mass_groups):
        d = (mg == q).astype(float) * rng.uniform(0.9, 1.1, n)
        terms.append((f"m{q}", Derivative(dM=sp.diags(d, format="csr"))))
    for q in range(n_damp_groups):
        e = order[bounds[q]:bounds[q + 1]]
        terms.append((f"c{q}", Derivative(dC=spring_matrix(n, edges[e], 1e-4 * kvals[e]))))
    return MatrixModel(dofs=[f"{i + 1}" for i in range(n)], terms=terms, p0=np.ones(len(terms)))


def assemble(model):
    K, M, C, D = model.matrices()
    return K.tocsc(), M.tocsc()


def eigen(K, M, k):
    sigma = -1e-6 * abs(K.diagonal()).max() / abs(M.diagonal()).max()
    lam, phi = spla.eigsh(K, k=k, M=M, sigma=sigma, which="LM", v0=start_vector(K.shape[0]))
    o = np.argsort(lam)
    return lam[o], _normalise(phi[:, o], M)


def part_a(side, n_modes):
    print(f"(a) eigenvalue sensitivities, {side}x{side} = {side * side} DOFs, {n_modes} modes")
    rows = []
    for P in (10, 100, 1000):
        model = grid_model(side, side, P)
        t0 = time.perf_counter()
        K, M = assemble(model)
        t_asm = time.perf_counter() - t0
        t0 = time.perf_counter()
        lam, phi = eigen(K, M, n_modes)
        t_eig = time.perf_counter() - t0
        sol = ModalSolution(lam=lam, phi=phi, p=model.p0, K=K.tocsr(), M=M.tocsr())
        t0 = time.perf_counter()
        S = eigenvalue_sensitivities(model, solution=sol, derivatives=StackedDerivatives(model.derivatives(), K.shape[0]))
        t_sens = time.perf_counter() - t0
        # central differences: 2P re-solutions (one timed; the matrices are re-assembled each time)
        p = model.p0.copy()
        p[0] *= 1 + 1e-6
        t0 = time.perf_counter()
        Kp, Mp = assemble(MatrixModel(dofs=model.dofs, terms=list(zip(model.parameter_names, model.derivatives())),
                                      p0=p)) if P <= 100 else (K + 1e-6 * model.derivatives()[0].dK, M)
        lp, _ = eigen(sp.csc_matrix(Kp), sp.csc_matrix(Mp), n_modes)
        t_one_fd = time.perf_counter() - t0
        fd0 = (lp - lam) / 1e-6
        check = np.abs(fd0 - S[:, 0]).max() / np.abs(S[:, 0]).max()
        rows.append((P, t_eig, t_sens, t_sens / t_eig, 2 * P * t_one_fd, 2 * P * t_one_fd / t_sens, t_asm, check))
    print(f"{'P':>6} {'eig [s]':>9} {'sens [s]':>9} {'sens/eig':>9} {'FD [s] (extrap.)':>17} {'FD/sens':>9} "
          f"{'assembly [s]':>13} {'fwd-diff check':>15}")
    for P, te, ts, r, tfd, rfd, ta, chk in rows:
        print(f"{P:>6} {te:>9.2f} {ts:>9.3f} {r:>9.3f} {tfd:>17.0f} {rfd:>9.0f} {ta:>13.2f} {chk:>15.1e}")
    print("target: sens/eig <= 1.5 for every P\n")


def part_b(n_side=(60, 50), P=1000, F=1000, n_meas=30):
    nx, ny = n_side
    n = nx * ny
    print(f"(b) MCI / response-function assembly: {n} DOFs, {P} parameters (springs, masses, dampers), {F} lines")
    model = grid_model(nx, ny, P, damping=True)
    K, M, C, _ = model.matrices()
    lam, _ = eigen(K.tocsc(), M.tocsc(), 6)
    f = np.linspace(0.5, 3.0, F) * np.sqrt(lam[-1]) / (2 * np.pi)
    omega = 2 * np.pi * f
    ref = np.array([n // 2])
    t0 = time.perf_counter()
    # experimental column at all DOFs (one sparse LU per line): the input both methods start from
    # Z symmetric: the receptance row of the reference DOF is its column
    theta = np.transpose(receptance_rows(model, model.p0, omega, ref), (2, 1, 0))      # (n, 1, F)
    t_frf = time.perf_counter() - t0
    t0 = time.perf_counter()
    A, b = mci_system(model, theta, omega, ref)
    t_mci = time.perf_counter() - t0
    meas = np.linspace(0, n - 1, n_meas).astype(int)
    t0 = time.perf_counter()
    HA = receptance_rows(model, model.p0, omega, meas)
    t_ha = time.perf_counter() - t0
    t0 = time.perf_counter()
    N, g = rfm_system(model, theta, omega, ref, meas, model.p0, normal=True, HA=HA)
    t_rfm = time.perf_counter() - t0
    print(f"  experimental FRF column (reference input, not timed below): {t_frf:8.1f} s")
    print(f"  MCI coefficient matrix, {A.shape[0]} x {A.shape[1]} sparse (nnz {A.nnz}): {t_mci:8.1f} s")
    print(f"  RFM analytical receptance rows H_A ({n_meas} DOFs x {F} lines):        {t_ha:8.1f} s")
    print(f"  RFM [R] for {n_meas * F} complex equations -> {P}x{P} normal equations:   {t_rfm:8.1f} s")
    months = 2 * 30 * 24 * 3600
    print(f"  versus the thesis' 'couple of months' (~{months:.1e} s): MCI {months / t_mci:.0e}x, "
          f"RFM {months / (t_ha + t_rfm):.0e}x faster")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--side", type=int, default=320, help="grid side for (a); side² DOFs (default 320 -> 102400)")
    ap.add_argument("--modes", type=int, default=10)
    ap.add_argument("--skip-a", action="store_true")
    ap.add_argument("--skip-b", action="store_true")
    a = ap.parse_args(argv)
    if not a.skip_a:
        part_a(a.side, a.modes)
    if not a.skip_b:
        part_b()


if __name__ == "__main__":
    main()
