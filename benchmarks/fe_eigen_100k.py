"""Benchmark: 20 modes of a >= 100k-DOF free-free frame model by shift-invert Lanczos.

Builds a free-free 3-D frame (a grillage of Euler–Bernoulli beams, two layers
joined by vertical posts, 6 DOFs per node), then prints

* assembly time;
* one sparse factorisation of K − σM with SuperLU's MMD_AT_PLUS_A ordering
  (symmetric mode) beside scipy's default COLAMD ordering;
* the whole eigen-solution (:func:`updating.fe.solvers.eigen_sparse`, 20 modes,
  negative shift) beside its baseline cost = one factorisation + the Lanczos
  solves it needed (number of solves × the time of one solve), and the ratio
  (target: ≤ 3).

Run: ``python benchmarks/fe_eigen_100k.py [--nx 92 --ny 92] [--modes 20] [--no-colamd]``.

One run on the development machine (2 cores shared with other jobs, so wall
times are noisy): 101 568 DOFs; factorisation MMD_AT_PLUS_A 29 s, COLAMD 110 s
(3.7×, fill 1.3e8 vs 6.0e7); eigen-solution 72 s for 20 modes with 64 Lanczos
solves, 1.7× its factorisation + solves baseline; six rigid-body modes below 1e-4 Hz.
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from updating.fe import Beam3D, BeamProperty, FEModel, Material, RectangularSection, eigen_sparse
from updating.fe.solvers import _shift


def grillage(nx: int, ny: int, layers: int = 2, pitch: float = 0.1) -> FEModel:
    """``layers`` nx × ny beam grids (spacing ``pitch``) stacked in z, joined by posts at every node."""
    m = FEModel("benchmark grillage")
    m.add_material(Material(1, E=70e9, nu=0.3, rho=2700.0))
    m.add_property(BeamProperty(1, 1, RectangularSection(0.02, 0.01), name="beam"))
    m.add_property(BeamProperty(2, 1, RectangularSection(0.015, 0.015), name="post"))

    def nid(i, j, k):
        return 1 + i + nx * (j + ny * k)

    for k in range(layers):
        for j in range(ny):
            for i in range(nx):
                m.add_node(nid(i, j, k), (i * pitch, j * pitch, k * pitch))
    eid = 1
    for k in range(layers):
        for j in range(ny):
            for i in range(nx):
                if i + 1 < nx:
                    m.add_element(Beam3D(eid, nid(i, j, k), nid(i + 1, j, k), 1, (0.0, 0.0, 1.0)))
                    eid += 1
                if j + 1 < ny:
                    m.add_element(Beam3D(eid, nid(i, j, k), nid(i, j + 1, k), 1, (0.0, 0.0, 1.0)))
                    eid += 1
                if k + 1 < layers:
                    m.add_element(Beam3D(eid, nid(i, j, k), nid(i, j, k + 1), 2, (1.0, 0.0, 0.0)))
                    eid += 1
    return m


def timed(fn, *a, **kw):
    t0 = time.perf_counter()
    out = fn(*a, **kw)
    return out, time.perf_counter() - t0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--nx", type=int, default=92)
    ap.add_argument("--ny", type=int, default=92)
    ap.add_argument("--layers", type=int, default=2)
    ap.add_argument("--modes", type=int, default=20)
    ap.add_argument("--no-colamd", action="store_true", help="skip the (slow) COLAMD factorisation")
    args = ap.parse_args(argv)

    model, t_build = timed(grillage, args.nx, args.ny, args.layers)
    mats, t_asm = timed(model.assemble)
    K, M = mats.K.tocsc(), mats.M.tocsc()
    n = K.shape[0]
    print(f"model: {len(model.nodes)} nodes, {len(model.elements)} beams, {n} DOFs, nnz(K) = {K.nnz}")
    print(f"build {t_build:.2f} s, assembly {t_asm:.2f} s")

    sigma = _shift(None, None)
    A = sp.csc_matrix(K - sigma * M)
    lu, t_mmd = timed(spla.splu, A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                      options={"SymmetricMode": True})
    print(f"factorisation MMD_AT_PLUS_A (symmetric mode): {t_mmd:8.2f} s   fill nnz(L+U) = {lu.L.nnz + lu.U.nnz}")
    b = np.random.default_rng(0).standard_normal(n)
    reps = 5
    _, t_solves = timed(lambda: [lu.solve(b) for _ in range(reps)])
    t_solve = t_solves / reps
    print(f"one solve with that factor:                   {t_solve * 1e3:8.1f} ms")
    if not args.no_colamd:
        lu_c, t_col = timed(spla.splu, A, permc_spec="COLAMD")
        print(f"factorisation COLAMD (scipy default):         {t_col:8.2f} s   fill nnz(L+U) = "
              f"{lu_c.L.nnz + lu_c.U.nnz}   ratio COLAMD/MMD = {t_col / t_mmd:.1f}x")
        del lu_c
    del lu

    info = {}
    (w, phi), t_eig = timed(eigen_sparse, K, M, args.modes, solver="splu", info=info)
    f = w / (2 * np.pi)
    baseline = info["factor_time"] + info["n_solves"] * t_solve
    print(f"eigen-solution, {args.modes} modes:                  {t_eig:8.2f} s   "
          f"({info['n_solves']} Lanczos solves, factor {info['factor_time']:.2f} s, solves {info['solve_time']:.2f} s)")
    print(f"baseline = factorisation + {info['n_solves']} solves:      {baseline:8.2f} s")
    print(f"ratio eigen-solution / baseline:               {t_eig / baseline:8.2f}  (target <= 3)")
    print(f"ratio eigen-solution / one factorisation:      {t_eig / t_mmd:8.2f}")
    print(f"rigid-body modes (Hz): {np.array2string(f[:6], precision=1, floatmode='maxprec')}")
    print(f"first elastic modes (Hz): {np.array2string(f[6:12], precision=3)}")
    res = np.linalg.norm(K @ phi - (M @ phi) * w ** 2, axis=0) / np.linalg.norm(K @ phi, axis=0)
    print(f"max relative residual of the elastic modes: {res[6:].max():.1e}")


if __name__ == "__main__":
    main()
