"""The quick demo's simulated acquisition (``modalab demo --quick`` up to the acquire stage), against a baseline.

The demo's plan roves a hammer over 13 points of the GARTEUR-like frame on its suspension (3 fixed
accelerometers, 512 Hz, 4 s records); the simulated lab synthesises every hit exactly on a grid long enough for
the suspension's 0.1 Hz mode to decay (capped at 300 s: 153 601 lines at 1 024 Hz) from the exact FRF columns of
the hit point and of the rotations a miss loads (``hardware_sim.synthesis``), a sum over the model's 1 566 poles
at every line.

Runs the acquisition on the code of this checkout and, beside it, on the code of ``--baseline`` (``git archive``
of that revision, default :data:`BEFORE_REV`), each in a child process, one after the other
(``benchmarks/_baseline.py``), and prints their wall and CPU times and peak memory with the ratios (now /
baseline), and whether the two sessions took the same hits (every hit's status and the SHA-256 of its file in the
session's journal).  Nothing is asserted.  Run: ``python benchmarks/demo_acquire.py [--baseline REV]``.

Measured 2026-12-07 (quiet 2-core machine; ``run_demo`` leaves BLAS its threads): baseline 0cc7802 (each point's
columns computed when it is first hit: 13 passes over the grid) wall 49.3 s, CPU 81.6 s, peak 1.11 GB; with the
plan's hammer points computed in one pass at the first hit (``SimulatedLab(hammer_points=...)``) wall 13.1 s
(ratio 0.27), CPU 18.8 s (0.23), peak 1.06 GB (0.95); the same 43 hits (statuses and stored files).
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._baseline import measure, side_by_side  # noqa: E402

#: the default baseline: main before the hammer points were computed in one pass (2026-12-07)
BEFORE_REV = "0cc7802"
#: what each child runs on its own code (``PYTHONPATH``): the quick demo up to its acquisition, into ARGV[1]
_DRIVER = """
import sys
from modalab.app.demo_project import run_demo
run_demo(sys.argv[1], quick=True, until_stage="acquire")
"""


def hit_hashes(out: Path) -> list:
    """Every hit the session's journal lists: its status and the SHA-256 of its file (None: rejected, not stored)."""
    journal = out / "acquire" / "session" / "journal.jsonl"
    lines = [json.loads(x) for x in journal.read_text().splitlines() if x.strip()] if journal.exists() else []
    return [(e["status"], e.get("sha256")) for e in lines if e.get("event") == "hit"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", default=BEFORE_REV, help="git revision of the baseline (default %(default)s)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="demoacq_") as tmp:
        tmp = Path(tmp)
        srcs = side_by_side(a.baseline, tmp, "run")
        res, hashes = {}, {}
        for code, src in srcs.items():
            res[code] = measure(src, ["-c", _DRIVER, str(tmp / code)], tmp)
            if res[code]["rc"]:
                print(f"{code}: exit {res[code]['rc']} after {res[code]['wall_s']:.1f} s: {res[code]['err']}")
            hashes[code] = hit_hashes(tmp / code)
        rb, rn = res["baseline"], res["now"]
        print(f"{'':<18} {'baseline':>10} {'now':>8} {'ratio':>6}")
        for what, key in (("wall (s)", "wall_s"), ("CPU (s)", "cpu_s"), ("peak memory (GB)", "peak_gb")):
            ratio = f"{rn[key] / rb[key]:6.2f}" if not (rb["rc"] or rn["rc"]) else f"{'-':>6}"
            print(f"{what:<18} {rb[key]:>10.2f} {rn[key]:>8.2f} {ratio}")
        hb, hn = hashes["baseline"], hashes["now"]
        print(f"hits: baseline {len(hb)}, now {len(hn)}; "
              + ("the same decisions and files" if hb == hn and hb else "DIFFERENT decisions or files"))
    return 0 if not res["now"]["rc"] else 1


if __name__ == "__main__":
    sys.exit(main())
