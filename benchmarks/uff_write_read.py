"""Benchmark: write and read 500 FRFs x 8192 lines with modalab.core.uff and with pyuff.

Run ``python benchmarks/uff_write_read.py [--sets 500] [--lines 8192] [--pyuff-sets 100]``.
Both writers get the same data (binary 58b, complex double).  pyuff's
``write_sets`` is timed on ``--pyuff-sets`` sets and, when that is fewer than
``--sets``, extrapolated to the full count both linearly and quadratically
(pyuff's write time grows faster than linearly); the output says which numbers
are measured and which extrapolated.  pyuff has to write 58b in ``mode='add'``
to a new file: ``'overwrite'`` truncates binary files.
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time

import numpy as np


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sets", type=int, default=500, help="number of FRFs (sets) to write")
    ap.add_argument("--lines", type=int, default=8192, help="frequency lines per FRF")
    ap.add_argument("--pyuff-sets", type=int, default=100, help="sets pyuff writes (timed, then extrapolated)")
    args = ap.parse_args(argv)

    import pyuff
    from modalab import FRF
    from modalab.core.uff import read_frf, write_frf

    n_sets, n_lines = args.sets, args.lines
    n_ref = 5 if n_sets % 5 == 0 else 1
    n_out = n_sets // n_ref
    rng = np.random.default_rng(0)
    freq = np.arange(n_lines) * 0.125
    H = rng.normal(size=(n_out, n_ref, n_lines)) + 1j * rng.normal(size=(n_out, n_ref, n_lines))
    frf = FRF(freq_hz=freq, H=H, responses=[f"{i + 1}+Z" for i in range(n_out)],
              references=[f"{1000 + j}+Z" for j in range(n_ref)])

    with tempfile.TemporaryDirectory() as tmp:
        ours = os.path.join(tmp, "ours.uff")
        t0 = time.perf_counter()
        write_frf(ours, frf)
        t_w = time.perf_counter() - t0
        t0 = time.perf_counter()
        back = read_frf(ours)
        t_r = time.perf_counter() - t0
        assert np.array_equal(back.H, frf.H)
        size = os.path.getsize(ours)

        # pyuff on a bounded number of sets, same data
        n_py = min(args.pyuff_sets, n_sets)
        dsets = []
        for k in range(n_py):
            i, j = divmod(k, n_ref)
            dsets.append(pyuff.prepare_58(binary=1, func_type=4, rsp_node=i + 1, rsp_dir=3, ref_node=1000 + j,
                                          ref_dir=3, data=H[i, j].copy(), x=freq, id1=f"H {i + 1}+Z/{1000 + j}+Z",
                                          abscissa_spacing=1, abscissa_spec_data_type=18,
                                          ordinate_spec_data_type=12, orddenom_spec_data_type=13))
        theirs = os.path.join(tmp, "pyuff.uff")
        half = max(n_py // 2, 1)
        t0 = time.perf_counter()
        pyuff.UFF(theirs).write_sets(dsets[:half], mode="add")
        t_half = time.perf_counter() - t0
        t0 = time.perf_counter()
        pyuff.UFF(theirs).write_sets(dsets[half:], mode="add")
        t_py_w = t_half + (time.perf_counter() - t0)
        t0 = time.perf_counter()
        pyuff.UFF(theirs).read_sets()
        t_py_r = time.perf_counter() - t0

    print(f"data: {n_sets} FRFs x {n_lines} lines, complex double, binary 58b ({size / 1e6:.1f} MB)")
    print(f"modalab write_frf : {t_w:8.3f} s   ({n_sets} sets, measured)")
    print(f"modalab read_frf  : {t_r:8.3f} s   ({n_sets} sets, measured)")
    print(f"pyuff write_sets  : {t_py_w:8.3f} s   ({n_py} sets, measured; first half {t_half:.3f} s)")
    print(f"pyuff read_sets   : {t_py_r:8.3f} s   ({n_py} sets, measured)")
    if n_py < n_sets:
        scale = n_sets / n_py
        lin_w, quad_w = t_py_w * scale, t_py_w * scale ** 2
        lin_r = t_py_r * scale
        print(f"pyuff write_sets, {n_sets} sets: {lin_w:.2f} s if linear, {quad_w:.2f} s if quadratic "
              "(extrapolated, not measured)")
        print(f"pyuff read_sets,  {n_sets} sets: {lin_r:.2f} s if linear (extrapolated)")
        py_w_full, py_r_full = lin_w, lin_r
        note = " (against the linear, most favourable extrapolation of pyuff)"
    else:
        py_w_full, py_r_full, note = t_py_w, t_py_r, ""
    ratio_w = py_w_full / t_w
    print(f"write speed-up: {ratio_w:.1f}x{note}; target >= 20x: {'met' if ratio_w >= 20 else 'NOT met'}")
    print(f"read speed-up : {py_r_full / t_r:.1f}x{note}")


if __name__ == "__main__":
    main()
