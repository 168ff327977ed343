"""Benchmark: modalab's poly-reference pLSCF (identification.PolyMAX) against sdypy-EMA's LSCF.

Same synthetic data for both (modal superposition, 10 modes with a close pair at
240/247 Hz, complex noise of 1.5 % of each FRF's RMS):

* case A: 30 outputs x 1 reference, 4000 lines (0.25..1000 Hz);
* case B: 74 outputs x 3 references, 1600 lines (0.625..1000 Hz).

Orders 50, 100, 150.  sdypy-EMA's ``pol_order_high=N`` evaluates denominator
degrees 2, 4, ..., 2N (2N roots at the top); modalab's matrix polynomial of
order p has p·n_in roots, so modalab runs ``max_order = ceil(2N / n_in)``: the
same number of roots at the top order (with one reference on the same even orders
2, 4, ..., 2N as sdypy-EMA; with three references every order 1..p).  sdypy-EMA is single-reference, so in
case B its 222 FRFs enter as 222 "locations" with a common denominator.

Printed per run: wall time (s), peak traced memory (tracemalloc, MiB), number of
modes, max |frequency error| (%), max |damping error| (%), min MAC of the shapes
against the true shapes, and the speed-up.  Accuracy of sdypy-EMA is taken with
``select_closest_poles`` given the TRUE frequencies (its only non-interactive
selection) — a favour modalab does not get: it selects automatically.  Each run is a
subprocess with one BLAS thread; a run over the cap (``--cap`` seconds) is stopped
and reported as capped.

Usage: python benchmarks/identify_vs_sdypy.py [--orders 50 100 150] [--cap 600] [--cases A B]
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time

FN = [42.0, 95.0, 151.0, 240.0, 247.0, 333.0, 418.0, 560.0, 702.0, 861.0]
ZETA = [0.010, 0.008, 0.012, 0.006, 0.012, 0.009, 0.011, 0.007, 0.010, 0.008]
CASES = {"A": {"n_out": 30, "n_in": 1, "n_lines": 4000}, "B": {"n_out": 74, "n_in": 3, "n_lines": 1600}}


def _data(case):
    import numpy as np

    from identification.synthetic import modal_system, noisy_frf

    c = CASES[case]
    mm, phi = modal_system(np.array(FN), np.array(ZETA), c["n_out"], rng=0)
    refs = [mm.dofs[k] for k in (0, c["n_out"] // 3, 2 * c["n_out"] // 3)[: c["n_in"]]]
    f = np.linspace(1000.0 / c["n_lines"], 1000.0, c["n_lines"])
    return noisy_frf(mm, f, refs, noise=0.015, rng=100), phi


def _accuracy(freq, damp, shapes, phi):
    import numpy as np

    from identification import mac_vectors

    fn, zn = np.array(FN), np.array(ZETA)
    freq = np.asarray(freq)
    if freq.size == 0:
        return {"n_modes": 0, "ferr_pct": None, "zerr_pct": None, "mac_min": None, "missing": len(FN), "spurious": 0}
    idx = np.array([np.argmin(np.abs(freq - f)) for f in fn])
    found = np.abs(freq[idx] / fn - 1) < 0.01
    spurious = int(freq.size - np.unique(idx[found]).size)
    ferr = np.abs(freq[idx] / fn - 1)[found] * 100
    zerr = np.abs(np.asarray(damp)[idx] / zn - 1)[found] * 100
    mac = np.diag(mac_vectors(np.asarray(shapes)[:, idx], phi))[found]
    return {"n_modes": int(freq.size), "ferr_pct": float(ferr.max()) if ferr.size else None,
            "zerr_pct": float(zerr.max()) if zerr.size else None, "mac_min": float(mac.min()) if mac.size else None,
            "missing": int((~found).sum()), "spurious": spurious}


def worker(method, case, order):
    import tracemalloc

    import numpy as np

    frf, phi = _data(case)
    n_in = frf.n_in
    # imports outside the timed region for both
    import scipy.cluster.hierarchy  # noqa: F401
    import scipy.optimize  # noqa: F401
    from sdypy import EMA  # noqa: F401

    import identification  # noqa: F401
    tracemalloc.start()
    t0 = time.perf_counter()
    if method == "modalab":
        from identification import PolyMAX

        p = math.ceil(2 * order / n_in)
        # one reference: the even orders 2, 4, ..., 2N, the very degrees sdypy-EMA evaluates
        step = 2 if n_in == 1 else 1
        pm = PolyMAX(max_order=p, min_order=step, order_step=step).fit(frf)
        dt = time.perf_counter() - t0
        _, peak = tracemalloc.get_traced_memory()
        m = pm.modes_
        acc = _accuracy(m.freq_hz, m.damping, m.shapes, phi)
        extra = {"model_order": p, "roots_at_top": p * n_in, "reduced_matrix": list(pm.reduced_matrix_shape_)}
    else:
        import warnings

        from sdypy import EMA

        warnings.simplefilter("ignore")
        H = frf.H.reshape(frf.n_out * n_in, frf.n_freq)                # rows (output, reference)
        model = EMA.Model(frf=H, freq=frf.freq_hz, lower=float(frf.freq_hz[0]), upper=float(frf.freq_hz[-1]),
                          pol_order_high=int(order), frf_form=frf.quantity)
        model.get_poles(method="lscf", show_progress=False)
        model.select_closest_poles(FN)
        model.get_constants(method="lsfd")
        dt = time.perf_counter() - t0
        _, peak = tracemalloc.get_traced_memory()
        shapes = np.asarray(model.A).reshape(frf.n_out, n_in, -1)[:, 0, :]
        acc = _accuracy(model.nat_freq, model.nat_xi, shapes, phi)
        extra = {"model_order": int(order), "roots_at_top": 2 * int(order)}
    tracemalloc.stop()
    out = {"method": method, "case": case, "order": order, "time_s": dt, "peak_mib": peak / 2 ** 20}
    out.update(acc)
    out.update(extra)
    print("RESULT " + json.dumps(out))


def run(method, case, order, cap):
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    here = os.path.dirname(os.path.abspath(__file__))
    env["PYTHONPATH"] = os.path.dirname(here) + os.pathsep + env.get("PYTHONPATH", "")
    cmd = [sys.executable, os.path.abspath(__file__), "--worker", method, case, str(order)]
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=cap, env=env)
    except subprocess.TimeoutExpired:
        return {"method": method, "case": case, "order": order, "capped": cap}
    for line in p.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[7:])
    return {"method": method, "case": case, "order": order, "error": (p.stderr or p.stdout)[-400:]}


def _fmt(r):
    if "capped" in r:
        return f"{'> %.0f s (capped)' % r['capped']:>22}"
    if "error" in r:
        return f"{'error':>22}"
    f = lambda v, s: "-" if v is None else s % v  # noqa: E731
    return (f"{r['time_s']:8.2f} s {r['peak_mib']:7.1f} MiB  modes {r['n_modes']:3d} (miss {r['missing']}, "
            f"spur {r['spurious']})  df {f(r['ferr_pct'], '%.4f')} %  dz {f(r['zerr_pct'], '%.2f')} %  "
            f"MAC {f(r['mac_min'], '%.4f')}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--orders", type=int, nargs="+", default=[50, 100, 150])
    ap.add_argument("--cases", nargs="+", default=["A", "B"], choices=sorted(CASES))
    ap.add_argument("--cap", type=float, default=600.0, help="seconds allowed per sdypy-EMA run")
    ap.add_argument("--worker", nargs=3, metavar=("METHOD", "CASE", "ORDER"), help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.worker:
        worker(a.worker[0], a.worker[1], int(a.worker[2]))
        return 0
    print(__doc__.split("\n\n")[0])
    print("(one BLAS thread per run; sdypy-EMA gets the true frequencies for its pole selection)\n")
    for case in a.cases:
        c = CASES[case]
        print(f"case {case}: {c['n_out']} outputs x {c['n_in']} references, {c['n_lines']} lines")
        for order in a.orders:
            ours = run("modalab", case, order, cap=max(a.cap, 600.0))
            base = run("sdypy", case, order, cap=a.cap)
            print(f"  order {order:4d}  modalab (p={ours.get('model_order', '?')}) {_fmt(ours)}")
            print(f"  {'':10s}  sdypy-EMA (N={order})   {_fmt(base)}")
            if "time_s" in ours and "time_s" in base:
                print(f"  {'':10s}  speed-up {base['time_s'] / ours['time_s']:.1f}x, "
                      f"memory ratio {base['peak_mib'] / max(ours['peak_mib'], 1e-9):.2f}")
            elif "time_s" in ours and "capped" in base:
                print(f"  {'':10s}  speed-up > {base['capped'] / ours['time_s']:.1f}x (sdypy-EMA capped)")
            sys.stdout.flush()
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
