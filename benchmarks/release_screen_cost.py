"""Benchmark: cost of the exact release screening (joint and support flexibility) against the number of candidates.

Run ``python benchmarks/release_screen_cost.py [--bays 4 8 16] [--lines 160]``.

A planar-in-layout, 3-D-beam ladder frame of ``bays`` bays (two rails, a cross member per bay, both ends of one
rail clamped) gives 3 rotations at every joint node where members meet plus the clamps' releases; measured
at every fourth node in z and y with two references, ``lines`` lines.  For each frame
:func:`updating.diagnosis.release.release_screen` is timed (CPU time of this process) on a quarter, half and all
of the candidates, and the per-candidate time printed with its ratio to the smallest frame's.  Linear cost means
a roughly constant time per candidate (after the one factorisation per line, which the quarter already pays).
Set ``OMP_NUM_THREADS=1`` on a shared machine: threaded BLAS in the sparse solves inflates CPU time there.
"""
from __future__ import annotations

import argparse
import time

import numpy as np


def ladder(bays: int):
    from updating.fe import Beam3D, BeamProperty, FEModel, Material, TubeSection
    m = FEModel(f"ladder {bays}", global_ge=0.01)
    m.add_material(Material(1, E=70e9, rho=2700.0))
    m.add_property(BeamProperty(1, 1, TubeSection(0.03, 0.026), name="rail"))
    m.add_property(BeamProperty(2, 1, TubeSection(0.02, 0.017), name="cross"))
    nx, ny = 2 * bays + 1, 4
    nid = lambda i, j: j * nx + i + 1                                          # noqa: E731
    for j in (0, ny - 1):
        for i in range(nx):
            m.add_node(nid(i, j), (0.1 * i, 0.1 * j, 0.0))
    eid = 1
    for j in (0, ny - 1):
        for i in range(nx - 1):
            m.add_element(Beam3D(eid, nid(i, j), nid(i + 1, j), 1, orientation=(0.0, 0.0, 1.0)))
            eid += 1
    for i in range(0, nx, 2):
        prev = nid(i, 0)
        for j in range(1, ny):
            if j < ny - 1:
                m.add_node(nid(i, j), (0.1 * i, 0.1 * j, 0.0))
            m.add_element(Beam3D(eid, prev, nid(i, j), 2, orientation=(0.0, 0.0, 1.0)))
            prev = nid(i, j)
            eid += 1
    m.add_spc(nid(0, 0), "123456")
    m.add_spc(nid(nx - 1, 0), "123456")
    return m


def main():
    from modalab.core.frf import FRF
    from updating.diagnosis.fit import frf_data
    from updating.diagnosis.library import build_library
    from updating.diagnosis.release import release_screen
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bays", type=int, nargs="+", default=[4, 8, 16])
    ap.add_argument("--lines", type=int, default=160)
    a = ap.parse_args()
    base = None
    print(f"{'bays':>5} {'DOFs':>6} {'cands':>6} {'CPU s':>8} {'ms/cand':>8} {'ratio':>6}")
    for bays in a.bays:
        m = ladder(bays)
        st = m.structure()
        nodes = sorted(m.nodes)[2::4]
        resp = [f"{n}+Z" for n in nodes] + [f"{n}+Y" for n in nodes]
        refs = resp[:1] + resp[len(nodes):len(nodes) + 1]
        f = np.linspace(5.0, 500.0, a.lines)
        H = st.frf(f, resp, refs, quantity="receptance")
        data = frf_data(FRF(freq_hz=f, H=H.H, responses=H.responses, references=H.references,
                            coherence=np.ones(H.H.shape), quantity="receptance"), max_lines=a.lines)
        lib = [c for c in build_library(m, kinds=["joint_flexibility", "boundary_flexibility"])
               if c.release is not None]
        for n in (len(lib) // 4, len(lib) // 2, len(lib)):
            t = time.process_time()
            release_screen(st, m, lib[:n], data, loss_factor=0.01)
            dt = time.process_time() - t
            per = 1e3 * dt / max(n, 1)
            if base is None:
                base = per
            print(f"{bays:>5} {st.n_dof:>6} {n:>6} {dt:>8.2f} {per:>8.1f} {per / base:>6.2f}")


if __name__ == "__main__":
    main()
