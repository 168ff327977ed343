"""Timing of a whole missing-physics diagnosis (issue 7): 30 outputs, 3 references, 2000 lines.

Structure: the GARTEUR-like frame (:func:`updating.fe.models.garteur.garteur_model`, 396 DOFs, Beam3D) on its
suspension; truth = the same frame with 3 % stiffer wing, PARAM G = 0.02 and a concealed grounded spring
(2×10⁴ N/m on z at a wing node); 30 response DOFs (z and y of 15 nodes spread over the frame), references at
the wing tips and the fin tip, 2000 lines 1–100 Hz, 1 % complex noise.  Nominal: the frame without the extra
spring, default parameters (E and ρ per property group) plus the background loss factor.

Prints the time of each step of :func:`updating.diagnosis.diagnose` and the total against the issue's
budget of 60 s (ratio < 1 is within budget).  Run: ``python benchmarks/diagnose_timing.py``.

Measured 2026-11-22 on the shared 2-core machine (load 4-8), before the Ritz basis and the FRF screening:
total 379 s (ratio 6.3), and the finding was wrong (a 480 kg point mass at node 200).

Measured 2026-11-24 (same machine, load ~1.3, one BLAS thread): nominal 0.4 s, parameters 1.0 s,
localise+name 18-28 s, model 1.8 s, proof 0.8 s, total 23-33 s (ratio 0.38-0.55); finding: spring to ground
at 204+Z of 19 999.9 N/m (truth 2×10⁴), held-out FRF error 62 % (parameters only) → 0.4 %.  The time goes
to the FRF screening of 1290 candidates (~4 s per screen, two screens in the first round) and to FRF fits of
the few best candidates in a Ritz basis.

Measured 2026-11-30 (same machine, quiet, BLAS on both cores), after the diagnosis gained the damping screen, the
fitted runners-up and neighbouring places, priors and cross-validation: total 82.2 s at 399752a (ratio 1.37; user
CPU 149 s), 75.2 s after the screening's singularity test became a determinant bound (ratio 1.25; localise+name
67 s of it): over the budget.  Same finding both times: spring to ground at 204+Z of 19 990 N/m, held-out FRF
error 289 % (parameters only) -> 1.8 %.  Under profile the time goes to the FRF fits of options and picks
(least squares in a Ritz basis, ~50 %), the complex-step parameter derivatives (~18 %) and the screenings (~17 %).
"""
from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from modalab.core.frf import FRF  # noqa: E402
from updating.diagnosis import diagnose  # noqa: E402
from updating.fe import Spring  # noqa: E402
from updating.fe.models.garteur import garteur_model  # noqa: E402

BUDGET_S = 60.0


def case(n_lines=2000, noise=0.01, seed=0):
    nominal = garteur_model(suspension=True)
    truth = garteur_model(suspension=True)
    for mid, mat in list(truth.materials.items()):
        if getattr(mat, "name", "") == "wing":
            truth.materials[mid] = dataclasses.replace(mat, E=mat.E * 1.03)
    truth.global_ge = 0.02
    pts = truth.metadata["points"]
    wing_nodes = sorted(n for n in truth.nodes if 200 <= n < 300)
    spring_node = wing_nodes[len(wing_nodes) // 4]
    truth.add_element(Spring(99001, (spring_node, 3), None, 2.0e4, group="concealed"))
    truth._changed()
    # nodes with independent z and y (not slaved by a rigid link: the diagnosis measures independent DOFs)
    free = {str(d) for d in nominal.structure().dofs}
    nodes = sorted(n for n in truth.nodes if f"{n}+Z" in free and f"{n}+Y" in free)
    pick = [nodes[i] for i in np.linspace(0, len(nodes) - 1, 15).astype(int)]
    refs = [f"{pts['right_tip']}+Z", f"{pts['left_tip']}+Z", f"{pts['fin_tip']}+Y"]
    resp = [f"{n}+Z" for n in pick] + [f"{n}+Y" for n in pick]
    for r in refs:                                   # driving points must be measured
        if r not in resp:
            resp[-1 - refs.index(r)] = r
    f = np.linspace(1.0, 100.0, n_lines)
    H = truth.frf(f, resp, refs, quantity="receptance")
    rng = np.random.default_rng(seed)
    Hn = H.H * (1 + noise * (rng.standard_normal(H.H.shape) + 1j * rng.standard_normal(H.H.shape)) / np.sqrt(2))
    meas = FRF(freq_hz=f, H=Hn, responses=H.responses, references=H.references, coherence=np.ones(H.H.shape),
               quantity="receptance")
    return nominal, meas, spring_node


def main():
    t0 = time.perf_counter()
    nominal, meas, node = case()
    t_case = time.perf_counter() - t0
    print(f"case: {nominal.structure().n_dof} DOFs, FRF {meas.shape} (built in {t_case:.1f} s); "
          f"concealed: grounded spring at {node}+Z")
    diag = diagnose(nominal, meas, progress=lambda m: None)
    for k, v in diag.timings.items():
        print(f"  {k:<22s} {v:7.2f} s")
    total = diag.timings["total"]
    print(f"total {total:.1f} s  ratio to the {BUDGET_S:.0f} s budget: {total / BUDGET_S:.2f}")
    print("findings:", [(f.candidate.label, round(f.value, 1)) for f in diag.findings])
    print("held-out FRF error: parameters only {:.3f}, with physics {:.3f}".format(
        diag.fit["parameters_only"]["frf_error_held_out"], diag.fit["with_physics"]["frf_error_held_out"]))


if __name__ == "__main__":
    main()
