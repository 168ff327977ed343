"""Timing of a whole missing-physics diagnosis (issue 7): 30 outputs, 3 references, 2000 lines.

Structure: the GARTEUR-like frame (:func:`updating.fe.models.garteur.garteur_model`, 396 DOFs, Beam3D) on its
suspension; truth = the same frame with 3 % stiffer wing, PARAM G = 0.02 and a concealed grounded spring
(2×10⁴ N/m on z at a wing node); 30 response DOFs (z and y of 15 nodes spread over the frame), references at
the wing tips and the fin tip, 2000 lines 1–100 Hz, 1 % complex noise.  Nominal: the frame without the extra
spring, default parameters (E and ρ per property group) plus the background loss factor.

Runs the diagnosis of this case on the code of this checkout and, beside it, on the code of ``--baseline``
(``git archive`` of that revision, default :data:`BEFORE_REV`), each in a child process, one after the other
(``benchmarks/_baseline.py``), and prints side by side the time of each step of
:func:`updating.diagnosis.diagnose`, the children's CPU and wall times with their ratios (now / baseline), the
total against the issue's budget of 60 s, and both findings.  Nothing is asserted.  Run:
``python benchmarks/diagnose_timing.py [--baseline REV]``.

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

Measured 2026-11-30, fifteenth session (quiet machine), each diagnosis run as the CLI runs it (BLAS on one
thread): at 34fc930 total 37.4 s (ratio 0.62; CPU 39.5 s; localise+name 33.4 s), the same finding (spring to
ground at 204+Z, 19 990 N/m; held-out FRF error 289 % -> 1.8 %); the baseline a1b66d7 stopped after 33 s with
'K + σM is singular': a joint at the link 101-500 fitted from 2.4e12 to 4.7e29 N/m in a Ritz basis (two BLAS
threads round otherwise and never got there; 34fc930 reports such a candidate as not evaluated).  With
``MODALAB_BLAS_THREADS=2`` (BLAS on both cores, how this script ran the diagnosis before): a1b66d7 67.9 s, 34fc930
74.6 s (ratio 1.10; CPU 130 s against 143 s), the same finding: the 75-82 s above were two-thread BLAS, twice the
time of one thread for this work of many small dense solves.

Measured 2026-12-03 (that session's machine, quiet, one BLAS thread): baseline af8c5fc total 73.3 s (CPU 76.6 s),
358325e (exact derivatives cached as an affine function of the loss factors, the Ritz Jacobian one product per
matrix, the hysteretic Ritz resolvent from one eigen-decomposition) 66.8 s (ratio 0.91; CPU 70.5 s;
localise+name 64.2 -> 59.9 s), the same finding (spring to ground at 204+Z, 19 990 N/m; held-out FRF error
289 % -> 1.8 %).

Measured 2026-11-30, sixteenth session, after the nominal mesh's own error is taken out of the data where the data
show it (``updating.diagnosis.mesh.mesh_discrepancy``: one more fit, of the model with its beams cut in two):
total 38.6 s (0.64 of the budget; CPU 40.8 s; localise+name 33.9 s), the same finding (spring to ground at 204+Z,
19 990 N/m; held-out FRF error 289 % -> 1.8 %); the baseline a1b66d7 stopped as above after 34 s.

Measured 2026-11-30 (quiet machine, one BLAS thread) after the screenings re-fit the parameters to first order
(0981941): 41.2 s against 41.3 s at 30f4fb3 (ratio 1.00), the same finding.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._baseline import measure, side_by_side  # noqa: E402
from modalab.core.frf import FRF  # noqa: E402
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


#: the default baseline: the code at the start of the fifteenth session (2026-11-30)
BEFORE_REV = "a1b66d7"
#: what each child runs on its own code (``PYTHONPATH``): the case of that code's :func:`case`, one diagnosis, with
#: BLAS limited to ``MODALAB_BLAS_THREADS`` threads (default 1) as the CLI limits it
_DRIVER = """
import json, os, sys
from threadpoolctl import threadpool_limits
from benchmarks.diagnose_timing import case
from updating.diagnosis import diagnose
nominal, meas, node = case()
with threadpool_limits(limits=int(os.environ["MODALAB_BLAS_THREADS"])):      # as `modalab diagnose` runs
    diag = diagnose(nominal, meas, progress=lambda m: None)
json.dump({"timings": diag.timings, "findings": [[f.candidate.label, float(f.value)] for f in diag.findings],
           "held_out": [diag.fit["parameters_only"]["frf_error_held_out"],
                        diag.fit["with_physics"]["frf_error_held_out"]]}, open(sys.argv[1], "w"))
"""


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", default=BEFORE_REV, help="git revision of the baseline (default %(default)s)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="diagtime_") as tmp:
        tmp = Path(tmp)
        srcs = side_by_side(a.baseline, tmp, "diagnosis")
        res, out = {}, {}
        for code, src in srcs.items():
            js = tmp / f"{code}.json"
            res[code] = measure(src, ["-c", _DRIVER, str(js)], tmp)
            if res[code]["rc"]:                   # said, and the other run's times shown alone
                print(f"{code}: exit {res[code]['rc']} after {res[code]['wall_s']:.1f} s: {res[code]['err']}")
            out[code] = json.loads(js.read_text()) if js.exists() else {"timings": {}, "findings": None}
        if out["now"]["findings"] is None:
            return 1
        b, n = out["baseline"]["timings"], out["now"]["timings"]
        print(f"{'step':<22} {'baseline s':>10} {'now s':>8} {'ratio':>6}")
        for k in list(dict.fromkeys([*b, *n])):
            tb, tn = b.get(k), n.get(k)
            ratio = f"{tn / tb:6.2f}" if tb and tn is not None else f"{'-':>6}"
            print(f"{k:<22} {'-' if tb is None else format(tb, '.2f'):>10} {'-' if tn is None else format(tn, '.2f'):>8} "
                  f"{ratio}")
        rb, rn = res["baseline"], res["now"]
        for what, key in (("process CPU (s)", "cpu_s"), ("process wall (s)", "wall_s")):
            ratio = f"{rn[key] / rb[key]:6.2f}" if not rb["rc"] else f"{'-':>6}"
            print(f"{what:<22} {rb[key]:>10.1f} {rn[key]:>8.1f} {ratio}")
        print(f"now: total {n['total']:.1f} s, {n['total'] / BUDGET_S:.2f} of the {BUDGET_S:.0f} s budget")
        for code in (c for c in srcs if out[c]["findings"] is not None):
            o = out[code]
            print(f"{code}: findings {[(lab, round(v, 1)) for lab, v in o['findings']]}; held-out FRF error "
                  f"parameters only {o['held_out'][0]:.3f}, with physics {o['held_out'][1]:.3f}")
        if out["baseline"]["findings"] is not None:
            fb, fn = out["baseline"]["findings"], out["now"]["findings"]
            same = len(fb) == len(fn) and all(lb == ln and abs(vb - vn) <= 1e-6 * max(abs(vb), abs(vn))
                                              for (lb, vb), (ln, vn) in zip(fb, fn))
            print("findings", "same (values to 1e-6)" if same else "DIFFER")
    return 0


if __name__ == "__main__":
    sys.exit(main())
