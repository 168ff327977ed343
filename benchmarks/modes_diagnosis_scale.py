"""Timing of a modes-only diagnosis (``diagnose --modes``) on a 367-grid CBEAM beam (issue 16 #8).

Nominal: a free-free aluminium beam as a GVT engineer's Nastran deck (3.0 m, PBEAML BAR 8 × 50 mm, 366 CBEAM,
367 GRID, no SPC), with Nastran's default lumped mass (no COUPMASS: the rotations are massless and the rigid
torsion is a massless mechanism) or with PARAM,COUPMASS,1.  2202 DOFs.

Truth (independent of modalab's elements and solvers): an Euler-Bernoulli beam written here with consistent
mass, four times finer (1464 elements), E 2 % higher, and a concealed 0.15 kg point mass at x = 2.7 m (grid
330); the 10 lowest elastic vertical modes observed in z at 26 grids (every 14th grid from grid 1, and the
end grid), 1 % relative scatter per shape entry.  Sensors in z only: the lateral (y) bending, axial and
torsion modes of the model are unobservable.

Options: ``--grids N`` (a deck of N grids, the same beam more finely meshed; the truth at least as fine)
or ``--dofs N``; ``--parts`` times the parts of a large diagnosis one by one (:func:`parts`); ``--table`` runs
367 grids, 9000, 30000 and 100000 DOFs (lumped mass), each in a process of its own, and prints a table: wall
and CPU time, peak RSS, the ratio of CPU time to the baseline measured before the low-rank library and the
first-order pre-screen (:data:`BASELINE`) and to the issue's budget of 60 s, and the finding.

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

Measured 2026-11-25 (massless branch), shared 2-core machine, load average 9-15, one BLAS thread:

* 367 grids, 2202 DOFs: lumped 23.3 s CPU (75 s wall), coupled 24.7 s CPU (103 s wall): ratio 0.39 / 0.41 CPU
  to the budget; the same finding as before the two-pass extension (point mass at grid 331, 0.148 kg).
* 1500 grids, 9000 DOFs, lumped, before the two-pass extension: 171 s CPU (1092 s wall at load 13), 15000
  candidates, library G storage 540 MB; finding a point mass at grid 1351 of 0.149 kg, reported ambiguous
  with grids 1349 and 1348 (2 mm apart at this mesh: the data cannot tell them apart); after it: 107 s
  CPU (659 s wall at load 9), the same finding.
* 16667 grids, 100002 DOFs (``--dofs 100000``, parts only): deck 2.4 s CPU, massless mechanisms (one, the
  rigid torsion) 1.1 s, the lowest 30 modes 2.2 s CPU (bit-identical when solved again; rigid-body modes at
  0.007-0.046 Hz, the rounding of K − σM for elements 0.18 mm long, first elastic mode 4.65 Hz), screening
  subspace (74 vectors) 7.2 s CPU; subspace extension per point-mass candidate 203 ms CPU explicit → 39 ms
  with the deflated two-pass extension: ~54 min CPU per screen for ~83000 candidates on observed directions,
  and the candidate library would need ~67 GB (n × n CSR per candidate).  So a 100k-DOF model does not screen
  "in minutes": the library must store candidates in low-rank form (rows, L) and fewer candidates must reach
  the subspace evaluation (a first-order pre-screen), both outside the eigen-solvers.

Measured 2026-11-25 after the low-rank library (:class:`~updating.diagnosis.library.LocalMatrix`), the
first-order pre-screen (:mod:`~updating.diagnosis.modes_screen`, above 4000 candidates, the best 500
evaluated exactly) and the CBEAM lumped torsional inertia (the lumped deck now has six rigid modes), at
51522f5, ``--table``, lumped mass, load average 14-16 on the 2 cores (wall times inflated 3-5x; CPU is the
measure), one BLAS thread:

====== ======= ====== ===== ======== ========= ===== ====== ======= ====================================
grids  DOFs    wall s CPU s base CPU CPU ratio /60 s RSS MB base MB finding (truth grid)
====== ======= ====== ===== ======== ========= ===== ====== ======= ====================================
367    2202    150    24    22.7     1.06      0.40  135    174     point mass 331, 0.148 kg (330)
1500   9000    188    39    107      0.36      0.64  271    -       point mass 1351, 0.149 kg, ambiguous (1350)
5000   30000   975    226   -        -         3.76  642    -       point mass 4508, 0.148 kg, ambiguous (4500)
16667  100002  1582   372   -        -         6.20  1394   -       point mass 15061, 0.145 kg, ambiguous (15000)
====== ======= ====== ===== ======== ========= ===== ====== ======= ====================================

(the 100002-DOF row at d3c7e78, with the projected-derivative fits, alone (``--dofs 100000 --quick``), load
10-15: wall-time split baseline fit 66 s, screening 362 s, candidate fits 1022 s; the truth there is as fine
as the deck, and the mass is placed 11 mm from it, one of six grids within 2 mm reported as equally good.)

(base: the code before, 05ed0d1, run here at 367 grids under the same load, and its 9000-DOF CPU time above;
at 30000 and 100000 DOFs it could not run: its library alone needs 6 and 67 GB.)  At 367 grids there are
3670 candidates: no pre-screen, the same screening numbers and finding as before.  At 30000 DOFs the
screening took 159 s and the candidate fits 618 s of the wall time: every evaluation of a fit assembled the
model and projected n-size matrices.  Since d3c7e78 a fit over parameters that enter K and M linearly uses
projected derivatives instead (a 9000-DOF baseline fit 7.4 → 1.9 s CPU, the same residual to 7 digits).
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


def deck(path: Path, coupmass: bool, n_el: int = N_EL) -> Path:
    lines = ["SOL 103", "CEND", "BEGIN BULK", "EIGRL,10,,,20"] + (["PARAM,COUPMASS,1"] if coupmass else [])
    # PBEAML BAR: DIM1 along the element z axis here (h = 8 mm: the vertical plane is the flexible one)
    lines += ["MAT1,1,7.e10,,.33,2700.", "PBEAML,1,1,,BAR", "+,.008,.05"]
    lines += [f"GRID,{i + 1},,{LENGTH * i / n_el:.10f},0.,0." for i in range(n_el + 1)]
    lines += [f"CBEAM,{i + 1},1,{i + 1},{i + 2},0.,1.,0." for i in range(n_el)]
    path.write_text("\n".join(lines + ["ENDDATA", ""]))
    return path


def truth_modes(refine=4, e_factor=1.02, mass=0.15, x_mass=2.7, n_modes=10, noise=0.01, seed=3, n_deck=N_EL):
    """Vertical modes of an independent consistent-mass Euler-Bernoulli beam (banded eigen-solution), observed
    in z at 26 grids of a deck of ``n_deck`` elements."""
    n_el = n_deck * refine
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
    w2, V = spla.eigsh(K, k=n_modes + 2, M=sp.csc_matrix(M), sigma=-1.0, v0=np.ones(n))
    o = np.argsort(w2)
    w2, V = w2[o][2:], V[:, o][:, 2:]
    step = max(1, round(14 * n_deck / N_EL))                   # 26 sensors whatever the mesh
    grids = sorted(set(list(range(0, n_deck + 1, step)) + [n_deck]))
    phi = V[0::2][np.asarray(grids) * refine]
    phi = phi * (1 + noise * np.random.default_rng(seed).standard_normal(phi.shape))
    return ModeSet(freq_hz=np.sqrt(w2) / (2 * np.pi), shapes=phi, dofs=[f"{g + 1}+Z" for g in grids]), \
        int(round(x_mass / LENGTH * n_deck)) + 1


#: measured before the low-rank library and the first-order pre-screen (this docstring, 2026-11-25, lumped
#: mass): process CPU seconds and peak RSS (MB) by DOF count; None where the run could not be made
BASELINE = {2202: (22.7, 174.0), 9000: (107.0, None), 30000: (None, None), 100002: (None, None)}
#: the sizes of ``--table``: 367 grids (the issue's deck), ~9k, ~30k and 100k DOFs
TABLE = (("--grids", 367), ("--dofs", 9000), ("--dofs", 30000), ("--dofs", 100000))


def _args(argv=None):
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    size = ap.add_mutually_exclusive_group()
    size.add_argument("--grids", type=int, help=f"a deck of N grids (default {N_EL + 1})")
    size.add_argument("--dofs", type=int, help="a deck of about N DOFs (N/6 grids), e.g. 100000")
    ap.add_argument("--quick", action="store_true", help="the lumped-mass deck only (default: lumped and coupled)")
    ap.add_argument("--parts", action="store_true", help="time the parts of a large diagnosis one by one")
    ap.add_argument("--table", action="store_true", help="367 grids, 9000, 30000 and 100000 DOFs, each in a "
                                                         "process of its own, as a table")
    return ap.parse_args(argv)


def _n_el(a) -> int:
    if a.grids is not None:
        return a.grids - 1
    if a.dofs is not None:                                      # e.g. --dofs 100000: 16667 grids x 6 DOFs
        return int(np.ceil(a.dofs / 6)) - 1
    return N_EL


def run_one(n_el: int, coupled=(False, True)):
    """The whole modes-only diagnosis of the deck with ``n_el`` elements; one ``RESULT {json}`` line per mass
    formulation (wall, CPU, peak RSS, finding)."""
    import json
    refine = max(1, round(4 * N_EL / n_el))                     # the truth: 1464 elements or more (at least the deck's)
    t0 = time.perf_counter()
    test, grid = truth_modes(refine=refine, n_deck=n_el)
    print(f"truth ({n_el * refine} elements, {time.perf_counter() - t0:.1f} s): 0.15 kg at grid {grid}; test modes "
          f"{np.round(test.freq_hz, 2)} Hz at {len(test.dofs)} z DOFs")
    with tempfile.TemporaryDirectory() as tmp:
        for coup in coupled:
            t0 = time.perf_counter()
            model = build_model(read_bdf(deck(Path(tmp) / "beam.bdf", coup, n_el)))
            t_build = time.perf_counter() - t0
            t0, c0 = time.perf_counter(), time.process_time()
            d = diagnose_modes(model, test)
            dt, dc = time.perf_counter() - t0, time.process_time() - c0
            n = model.structure().n_dof
            print(f"{'coupled' if coup else 'lumped '} mass, {n_el + 1} grids, {n} DOFs "
                  f"(deck read and built in {t_build:.1f} s): {dt:6.1f} s wall, {dc:6.1f} s CPU (ratio to the 60 s "
                  f"budget {dt / BUDGET_S:.2f} wall, {dc / BUDGET_S:.2f} CPU; load average {os.getloadavg()[0]:.1f}; "
                  f"peak RSS {_peak_rss_mb():.0f} MB)")
            print("   timings:", {k: round(v, 1) for k, v in d.timings.items()})
            for f in d.findings:
                print(f"   finding: {f.candidate.label} = {f.value:.4g} {f.candidate.unit}"
                      + (" (ambiguous)" if f.ambiguous else ""))
            print("   fit:", {k: round(v["freq_error_max_pct"], 3) for k, v in d.fit.items()})
            print("   " + d.statement)
            finding = "; ".join(f"{f.candidate.label} = {f.value:.3g} {f.candidate.unit}"
                                + (" (ambiguous)" if f.ambiguous else "") for f in d.findings) or "none"
            print("RESULT " + json.dumps(dict(mass="coupled" if coup else "lumped", grids=n_el + 1, dofs=n, wall=dt,
                                              cpu=dc, rss=_peak_rss_mb(), load=os.getloadavg()[0],
                                              timings=d.timings, finding=finding, truth_grid=grid)), flush=True)


def table(sizes=TABLE):
    """Each size in a process of its own (peak RSS per run), lumped mass; a table with the ratios to the
    baseline and to the 60 s budget."""
    import json
    import subprocess
    rows = []
    for flag, val in sizes:
        out = subprocess.run([sys.executable, __file__, flag, str(val), "--quick"], capture_output=True, text=True)
        res = [json.loads(line[7:]) for line in out.stdout.splitlines() if line.startswith("RESULT ")]
        if not res:
            print(f"{flag} {val}: failed\n{out.stdout[-2000:]}\n{out.stderr[-2000:]}", flush=True)
            continue
        rows.append(res[0])
        print(f"{flag} {val}: done in {res[0]['wall']:.0f} s wall", flush=True)
    print(f"\n{'grids':>6} {'DOFs':>7} {'wall s':>7} {'CPU s':>7} {'base CPU':>8} {'CPU ratio':>9} {'/60 s':>6} "
          f"{'RSS MB':>7} {'base MB':>7} {'screen s':>8} {'fits s':>7}  finding (truth grid)")
    for r in rows:
        base_cpu, base_mb = BASELINE.get(r["dofs"], (None, None))
        ratio = f"{r['cpu'] / base_cpu:9.2f}" if base_cpu else f"{'-':>9}"
        print(f"{r['grids']:6d} {r['dofs']:7d} {r['wall']:7.0f} {r['cpu']:7.0f} {base_cpu or '-':>8} {ratio} "
              f"{r['cpu'] / BUDGET_S:6.2f} {r['rss']:7.0f} {base_mb or '-':>7} {r['timings']['screening']:8.0f} "
              f"{r['timings']['fits']:7.0f}  {r['finding']} ({r['truth_grid']})")


def main(argv=None):
    a = _args(argv)
    if a.table:
        return table()
    n_el = _n_el(a)
    if a.parts:
        return parts(n_el)
    run_one(n_el, (False,) if a.quick else (False, True))


def parts(n_el: int):
    """The parts of a modes-only diagnosis of a large deck, timed one by one, and the screening projected.

    The whole diagnosis of a 100k-DOF deck does not fit this machine: the candidate library
    (:func:`updating.diagnosis.library.build_library`) stores each candidate's ``G`` as an n × n CSR matrix
    whose row pointer alone is ``4(n + 1)`` bytes, so ~10 candidates per grid need ``40 n²/6`` bytes
    (67 GB at 100k DOFs; measured 32 MB at 2202 DOFs, 540 MB at 9000).  What is timed here: the deck, the
    massless mechanisms (lumped mass), the lowest 30 modes (twice: bit-identical), the modal subspace of the
    screening, and the subspace extension per point-mass candidate (``ModalSubspace.extended``: one sparse
    solve and some ten passes over the n × m basis), from which one screen is projected.
    """
    import resource
    import scipy.sparse as sp
    from modalab.core.eigen import massless_mechanisms
    from updating.diagnosis.modes import ModalSubspace, _extended_rows

    def clock():
        return time.perf_counter(), time.process_time()

    def since(t):
        return f"{time.perf_counter() - t[0]:.1f} s wall, {time.process_time() - t[1]:.1f} s CPU"

    with tempfile.TemporaryDirectory() as tmp:
        t = clock()
        model = build_model(read_bdf(deck(Path(tmp) / "beam.bdf", False, n_el)))
        st = model.structure()
        print(f"lumped mass, {n_el + 1} grids, {st.n_dof} DOFs: deck read and built in {since(t)}")
        t = clock()
        fix, _ = massless_mechanisms(sp.csr_matrix(st.K), sp.csr_matrix(st.M))
        print(f"   massless mechanisms: {fix.size} (the rigid torsion) in {since(t)}")
        t = clock()
        w, _ = st.normal_modes(30)
        print(f"   lowest 30 modes in {since(t)}: rigid {np.round(w[:5] / (2 * np.pi), 4)} Hz, elastic from "
              f"{w[5] / (2 * np.pi):.3f} Hz")
        print("   solved again: bit-identical", np.array_equal(w, st.normal_modes(30)[0]))
        t = clock()
        grids = np.linspace(1, n_el + 1, 26).round().astype(int)
        idx = {(d.node, d.axis): i for i, d in enumerate(st.dofs)}
        basis = ModalSubspace(st, [idx[(g, 3)] for g in grids], 226.5, 22)
        print(f"   screening subspace: {basis.size} vectors ({basis.n_modes} modes) in {since(t)}")
        nodes = np.linspace(2, n_el, 20).round().astype(int)
        mi = np.array([idx[(g, 3)] for g in grids])
        n_cand = 10 * (n_el + 1)
        basis.deflation                                           # once per basis
        for name, extend in (("explicit Gram-Schmidt (ModalSubspace.extended)",
                              lambda r: basis.extended(r, np.eye(3))),
                             ("deflated, two passes (modes._extended_rows, what the screening uses)",
                              lambda r: _extended_rows(basis, r, np.eye(3), mi))):
            t = clock()
            for g in nodes:
                extend(np.array([idx[(g, a)] for a in (1, 2, 3)]))
            per = (time.process_time() - t[1]) / nodes.size
            print(f"   subspace extension per point-mass candidate, {name}: {per * 1e3:.0f} ms CPU; ~{n_cand} "
                  f"candidates, about half on observed directions: {per * n_cand / 2 / 60:.0f} min CPU per screen")
        print(f"   candidate library G storage ≈ {4 * (st.n_dof + 1) * n_cand / 1e9:.0f} GB")
        print(f"   peak RSS {_peak_rss_mb():.0f} MB")


def _peak_rss_mb() -> float:
    import resource
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


if __name__ == "__main__":
    main()
