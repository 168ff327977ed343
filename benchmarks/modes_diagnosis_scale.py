"""Timing of a modes-only diagnosis (``diagnose --modes``) on a 367-grid CBEAM beam (issue 16 #8).

Nominal: a free-free aluminium beam as a GVT engineer's Nastran deck (3.0 m, PBEAML BAR 8 × 50 mm, 366 CBEAM,
367 GRID, no SPC), with Nastran's default lumped mass (no COUPMASS: the rotations are massless and the rigid
torsion is a massless mechanism) or with PARAM,COUPMASS,1.  2202 DOFs.

Truth (independent of modalab's elements and solvers): an Euler-Bernoulli beam written here with consistent
mass, four times finer (1464 elements), E 2 % higher, and a concealed 0.15 kg point mass at x = 2.7 m (grid
330); the 10 lowest elastic vertical modes observed in z at 26 grids (every 14th grid from grid 1, and the
end grid), 1 % relative scatter per shape entry.  Sensors in z only: the lateral (y) bending, axial and
torsion modes of the model are unobservable.

Prints, per mass formulation, the time of the whole diagnosis against the issue's budget of 60 s on 2
cores (ratio < 1 is within budget) and the finding.  Run: ``python benchmarks/modes_diagnosis_scale.py``
(``--quick`` for the lumped deck only).

Before this change (issue 16): one dense eigen-solution per candidate value, 1.18 s × 3670 candidates ×
13 values × 2 screens ≈ 31 h with coupled mass; with lumped mass the eigen-solution raised, the error was
caught into a constant residual and the run ended "Nothing is missing".

Measured 2026-11-25 on the shared 2-core machine under a load average of 9-10 (one BLAS thread), so the
wall time is inflated by other jobs and the process CPU time is the better estimate of an idle run:
lumped mass 26.0 s CPU (111 s wall), coupled mass 24.9 s CPU (47 s wall): CPU ratio 0.43 / 0.41 to the
60 s budget.  Both find a point mass at grid 331 of 0.148 kg (truth 0.15 kg at grid 330); held-out frequency
error (test modes 3, 6, 9) 1.2 % after parameter updating → 0.1 % with the mass.  Most of the time is the
screening (3670 candidates, two screens; those acting only on unobserved directions are skipped before
evaluation).
"""
from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")          # one BLAS thread, as the CLI (MODALAB_BLAS_THREADS)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from modalab.core.modes import ModeSet  # noqa: E402
from updating.fe.bulk import build_model, read_bdf  # noqa: E402
from updating.diagnosis import diagnose_modes  # noqa: E402

BUDGET_S = 60.0
LENGTH, N_EL, B, H, E, RHO = 3.0, 366, 0.05, 0.008, 7e10, 2700.0


def deck(path: Path, coupmass: bool) -> Path:
    lines = ["SOL 103", "CEND", "BEGIN BULK", "EIGRL,10,,,20"] + (["PARAM,COUPMASS,1"] if coupmass else [])
    # PBEAML BAR: DIM1 along the element z axis here (h = 8 mm: the vertical plane is the flexible one)
    lines += ["MAT1,1,7.e10,,.33,2700.", "PBEAML,1,1,,BAR", "+,.008,.05"]
    lines += [f"GRID,{i + 1},,{LENGTH * i / N_EL:.8f},0.,0." for i in range(N_EL + 1)]
    lines += [f"CBEAM,{i + 1},1,{i + 1},{i + 2},0.,1.,0." for i in range(N_EL)]
    path.write_text("\n".join(lines + ["ENDDATA", ""]))
    return path


def truth_modes(refine=4, e_factor=1.02, mass=0.15, x_mass=2.7, n_modes=10, noise=0.01, seed=3):
    """Vertical modes of an independent consistent-mass Euler-Bernoulli beam (banded eigen-solution)."""
    n_el = N_EL * refine
    le = LENGTH / n_el
    EI, rA = E * e_factor * B * H ** 3 / 12, RHO * B * H
    k = EI / le ** 3 * np.array([[12, 6 * le, -12, 6 * le], [6 * le, 4 * le ** 2, -6 * le, 2 * le ** 2],
                                 [-12, -6 * le, 12, -6 * le], [6 * le, 2 * le ** 2, -6 * le, 4 * le ** 2]])
    m = rA * le / 420 * np.array([[156, 22 * le, 54, -13 * le], [22 * le, 4 * le ** 2, 13 * le, -3 * le ** 2],
                                  [54, 13 * le, 156, -22 * le], [-13 * le, -3 * le ** 2, -22 * le, 4 * le ** 2]])
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla
    rows, cols, kv, mv = [], [], [], []
    for e in range(n_el):
        idx = np.arange(2 * e, 2 * e + 4)
        rows += list(np.repeat(idx, 4))
        cols += list(np.tile(idx, 4))
        kv += list(k.ravel())
        mv += list(m.ravel())
    n = 2 * (n_el + 1)
    K = sp.csc_matrix((kv, (rows, cols)), shape=(n, n))
    M = sp.lil_matrix(sp.csc_matrix((mv, (rows, cols)), shape=(n, n)))
    j = int(round(x_mass / le))
    M[2 * j, 2 * j] += mass
    w2, V = spla.eigsh(K, k=n_modes + 2, M=sp.csc_matrix(M), sigma=-1.0)
    o = np.argsort(w2)
    w2, V = w2[o][2:], V[:, o][:, 2:]
    grids = sorted(set(list(range(0, N_EL + 1, 14)) + [N_EL]))
    phi = V[0::2][np.asarray(grids) * refine]
    phi = phi * (1 + noise * np.random.default_rng(seed).standard_normal(phi.shape))
    return ModeSet(freq_hz=np.sqrt(w2) / (2 * np.pi), shapes=phi, dofs=[f"{g + 1}+Z" for g in grids]), \
        int(round(x_mass / LENGTH * N_EL)) + 1


def main():
    quick = "--quick" in sys.argv
    test, grid = truth_modes()
    print(f"truth: 0.15 kg at grid {grid}; test modes {np.round(test.freq_hz, 2)} Hz at {len(test.dofs)} z DOFs")
    with tempfile.TemporaryDirectory() as tmp:
        for coup in ((False,) if quick else (False, True)):
            model = build_model(read_bdf(deck(Path(tmp) / "beam.bdf", coup)))
            t0, c0 = time.perf_counter(), time.process_time()
            d = diagnose_modes(model, test)
            dt, dc = time.perf_counter() - t0, time.process_time() - c0
            print(f"{'coupled' if coup else 'lumped '} mass, {model.structure().n_dof} DOFs: {dt:6.1f} s wall, "
                  f"{dc:6.1f} s CPU (ratio to the 60 s budget {dt / BUDGET_S:.2f} wall, {dc / BUDGET_S:.2f} CPU; "
                  f"load average {os.getloadavg()[0]:.1f})")
            print("   timings:", {k: round(v, 1) for k, v in d.timings.items()})
            for f in d.findings:
                print(f"   finding: {f.candidate.label} = {f.value:.4g} {f.candidate.unit}"
                      + (" (ambiguous)" if f.ambiguous else ""))
            print("   fit:", {k: round(v["freq_error_max_pct"], 3) for k, v in d.fit.items()})
            print("   " + d.statement)


if __name__ == "__main__":
    main()
