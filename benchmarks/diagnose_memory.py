"""Peak memory and time of ``modalab diagnose`` against a baseline revision, side by side.

Run ``python benchmarks/diagnose_memory.py [--baseline REV] [--cap-gb 6] [--case DIR ...]``.

Each diagnosis runs in a child process (``python -c main(...)``) on the code of this checkout and, beside it, on
the code of ``--baseline`` (``git archive`` of that revision into a temporary folder); the child's peak resident
set size is sampled from ``/proc`` (every 50 ms) and read from ``wait4``'s ``ru_maxrss``, with its CPU time (user
+ system) and wall time.  A child whose RSS passes ``--cap-gb`` is stopped and its peak reported as ``> cap``
(the ratio then a bound): the baseline of 2026-11-29 needs ~20 GB on the demo, more than a shared machine
has to spare.  The diagnosis JSONs of the two runs are compared: findings by label, parameters' updated values
by their largest relative difference.  Nothing is asserted.

Cases: the exact demo chain (``examples/demo_project/nominal.bdf`` simulated by ``modalab sim`` at the 13 points
and 3 references of ``tests/cli/test_exact_chain.py``, ``frf --exp-end 0.01``: 13 x 3 FRFs, 3201 lines), built
in a temporary folder, and any ``--case`` folder of the discovery benchmark (``nominal.bdf``, ``measured.uff``,
``params.toml``), diagnosed with the arguments of ``benchmarks/discovery/score.py``.

Measured 2026-11-29 on the shared 2-core machine (load 4-7, one BLAS thread).  The exact demo chain: the
baseline b55df4c passes 6 GB after 36 s and grows ~1 GB per 5.5 s (20.8 GB and ~2 min reported for the whole run,
one run killed by the OOM killer; not run to its end here): the damping screening
(``updating.diagnosis.dampscreen``) kept, for each of its 124 local-damping candidates, the stacked terms of its
fit, (1 + 15 parameters) x lines x 68² modes, complex (~0.19 GB a candidate).  Not keeping them: 0.52 GB peak;
with each term as two modes x modes matrices ``A0 + s² A2`` (never the lines x modes x modes array) 0.37 GB,
57 s CPU, 61 s wall (peak ratio < 0.062: the baseline's peak is a lower bound), diagnosis.json identical to
the version that only stopped keeping the stacks (which does the baseline's arithmetic).  Discovery cases
(``generate.py --seeds 1002,1010``): case1002_planar_frame 0.36 -> 0.24 GB (0.66), CPU 50.1 -> 51.4 s (1.03),
case1010_clamped_post 0.24 -> 0.16 GB (0.70), CPU 21.7 -> 22.4 s (1.03); findings the same, parameters within
1.2e-10 relative.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._baseline import ROOT, checkout, measure  # noqa: E402

DEMO = ROOT / "examples" / "demo_project"
POINTS = "200+Z 204+Z 208+Z 213+Z 217+Z 218+Z 100+Z 115+Z 308+Z 408+Z 508+Y 600+Z 608+Z".split()
REFS = "218+Z 200+Z 508+Y".split()
#: the last revision before the damping screening stopped keeping every candidate's stacked terms
BEFORE_REV = "b55df4c"
_MAIN = "import sys; from modalab.app.cli import main; sys.exit(main(sys.argv[1:]))"


def run(src: Path, args: list, cwd: Path, cap_gb: float) -> dict:
    """``modalab ARGS`` on the code in ``src``, measured by :func:`benchmarks._baseline.measure`."""
    return measure(src, ["-c", _MAIN, *args], cwd, cap_gb)


def demo_chain(d: Path) -> list:
    """The exact demo chain's ``diagnose`` arguments (hits and FRFs built in ``d`` by this checkout's code)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    for a in (["sim", "--structure", str(DEMO / "nominal.bdf"), "--points", *POINTS, "--references", *REFS,
               "-o", "hits.uff", "--no-plot"], ["frf", "hits.uff", "--exp-end", "0.01", "-o", "frf.uff", "--no-plot"]):
        subprocess.run([sys.executable, "-c", _MAIN, *a], cwd=d, env=env, check=True, stdout=subprocess.DEVNULL)
    return ["diagnose", str(DEMO / "nominal.bdf"), str(d / "frf.uff")]


def case_args(case: Path) -> list:
    args = ["diagnose", str(case / "nominal.bdf"), str(case / "measured.uff")]
    return args + (["--params", str(case / "params.toml")] if (case / "params.toml").exists() else [])


def compare(a: Path, b: Path) -> str:
    if not (a.exists() and b.exists()):
        return "(no JSON to compare)"
    da, db = json.loads(a.read_text()), json.loads(b.read_text())
    fa = [f.get("description") for f in da["findings"]]
    fb = [f.get("description") for f in db["findings"]]
    rel = max((abs(da["parameters"][k]["updated"] - db["parameters"][k]["updated"])
               / max(abs(db["parameters"][k]["updated"]), 1e-300) for k in db["parameters"]), default=0.0)
    return f"findings {'same' if fa == fb else 'DIFFER'} {fa}; parameters max rel. difference {rel:.1e}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", default=BEFORE_REV, help="git revision of the baseline (default %(default)s)")
    ap.add_argument("--cap-gb", type=float, default=6.0, help="stop a run whose RSS passes this (GB)")
    ap.add_argument("--case", type=Path, nargs="*", default=[], help="discovery case folders to run too")
    ap.add_argument("--no-demo", action="store_true", help="only the --case folders")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="diagmem_") as tmp:
        tmp = Path(tmp)
        base_src = checkout(a.baseline, tmp / "baseline")
        cases = []
        if not a.no_demo:
            (tmp / "demo").mkdir()
            cases.append(("exact demo chain", demo_chain(tmp / "demo")))
        cases += [(c.name, case_args(c.resolve())) for c in a.case]
        print(f"baseline {a.baseline} against this checkout; cap {a.cap_gb:g} GB; MODALAB_BLAS_THREADS="
              f"{os.environ.get('MODALAB_BLAS_THREADS', '1')}")
        print(f"{'case':<28} {'code':<9} {'peak GB':>8} {'CPU s':>7} {'sys s':>6} {'wall s':>7}  "
              f"{'peak ratio':>10} {'CPU ratio':>9}")
        for name, args in cases:
            res = {}
            for code, src in (("baseline", base_src), ("now", ROOT)):
                js = tmp / f"{code}.json"
                js.unlink(missing_ok=True)
                res[code] = run(src, args + ["--json", str(js)], tmp, a.cap_gb)
            b = res["baseline"]
            for code in ("baseline", "now"):
                r = res[code]
                peak = f"{'>' if r['capped'] else ''}{r['peak_gb']:.2f}"
                bound = "<" if b["capped"] and code == "now" else ""
                note = " stopped at the cap" if r["capped"] else (f" exit {r['rc']} {r['err']}" if r["rc"] else "")
                print(f"{name:<28} {code:<9} {peak:>8} {r['cpu_s']:>7.1f} {r['sys_s']:>6.1f} {r['wall_s']:>7.1f}  "
                      f"{bound + format(r['peak_gb'] / b['peak_gb'], '.3f'):>10} "
                      f"{bound + format(r['cpu_s'] / b['cpu_s'], '.2f'):>9}{note}")
            print(f"{'':<28} {compare(tmp / 'now.json', tmp / 'baseline.json')}")


if __name__ == "__main__":
    main()
