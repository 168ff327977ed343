"""Score ``modalab diagnose`` on generated discovery cases (issue 13) and print the table and the summary.

    python benchmarks/discovery/generate.py --seeds odd --out /tmp/disc
    python benchmarks/discovery/score.py /tmp/disc --seeds odd --jobs 1 --out /tmp/disc/score

Every case is run through the project's single diagnose entry point exactly as a user runs it
(``python -m modalab.app.cli diagnose nominal.bdf measured.uff --params params.toml --json ...`` in a subprocess,
with this checkout first on PYTHONPATH), so a crash is caught with its message and counted as a failure.
``truth.json`` is read only here.  Writes ``score.md`` (table + summary) and ``score.json`` into ``--out``.

Per case: kind right (a finding of the concealed kind within one node of the truth, distance measured along
the nominal mesh graph), location distance in nodes (of the closest finding of the right kind, else of the
closest finding), value error, held-out FRF error of the nominal / parameters-only / with-physics fits, wall
time; the distance is marked "(alt)" when only an ambiguous finding's alternative (not its best-fitting
explanation) is of the right kind and place, and the summary counts those.  Findings that are neither the
match nor the suspension cords of a suspended frame (ground springs at a cord node: present in the truth,
allowed but not required) are spurious.  The value error is reported (median, share within 25 %) but is not
part of the targets.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import time
from collections import deque
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

TARGETS = {"right_within_one_node": 0.90, "finding_on_control": 0.05, "spurious_extra": 0.10,
           "heldout_ratio": 3.0, "seconds_per_case": 60.0}


# ------------------------------------------------------------------ diagnosis.json (one place to adapt)
def parse_diagnosis(doc: dict) -> dict:
    """The parts of ``diagnosis.json`` the score needs, as written by ``Diagnosis.to_dict`` today:

    ``{"findings": [{"physics", "nodes", "elements", "dofs", "value", "unit", "alternatives": [...]}],
    "heldout": {"nominal", "parameters_only", "with_physics"}, "statement"}``.  An ambiguous finding (a future
    schema: ``"alternatives"``/``"candidates"`` list) is kept as one finding whose alternatives all count for
    the location and the kind.
    """
    out = []
    for f in doc.get("findings", []):
        vals = f.get("values") or [{}]
        alts = [f] + list(f.get("alternatives", []) or f.get("candidates", []) or [])
        out.append({"physics": f.get("physics"), "nodes": [int(n) for n in f.get("nodes", [])],
                    "elements": [int(e) for e in f.get("elements", [])], "dofs": list(f.get("dofs", [])),
                    "value": vals[0].get("value"), "unit": vals[0].get("unit", ""),
                    "alternatives": [{"physics": a.get("physics"), "nodes": [int(n) for n in a.get("nodes", [])],
                                      "elements": [int(e) for e in a.get("elements", [])]} for a in alts]})
    fit = doc.get("fit", {})
    held = {k: (fit.get(k) or {}).get("frf_error_held_out") for k in ("nominal", "parameters_only", "with_physics")}
    return {"findings": out, "heldout": held, "statement": doc.get("statement", "")}


# ------------------------------------------------------------------ graph distances on the nominal mesh
def _distances(edges, sources):
    adj: dict = {}
    for a, b in edges:
        adj.setdefault(a, set()).add(b)
        adj.setdefault(b, set()).add(a)
    dist = {s: 0 for s in sources if s in adj}
    q = deque(dist)
    while q:
        n = q.popleft()
        for m in adj.get(n, ()):
            if m not in dist:
                dist[m] = dist[n] + 1
                q.append(m)
    return dist


def _nodes_of(item, truth):
    """Nodes of a finding/truth entry: its elements' end nodes when elements are given, else its nodes."""
    els = truth["nominal"]["elements"]
    if item.get("elements"):
        return {n for e in item["elements"] for n in els.get(str(e), [])} or set(item.get("nodes", []))
    return set(item.get("nodes", []))


def node_distance(finding, target, truth):
    """Smallest number of nominal-mesh edges between the finding's and the target's nodes (None: unreachable)."""
    tn = _nodes_of(target, truth)
    d = _distances(truth["nominal"]["edges"], tn)
    best = None
    for alt in finding.get("alternatives") or [finding]:
        for n in _nodes_of(alt, truth):
            if n in d and (best is None or d[n] < best):
                best = d[n]
    return best


# ------------------------------------------------------------------ one case
# ``modalab <args>`` (modalab.app.cli.main, the console script's function), then the CPU seconds of the process and
# its children on stderr: wall time on a shared machine says little, CPU time says what the case costs
_WRAPPER = """import resource, sys
from modalab.app.cli import main
try:
    rc = main(sys.argv[1:])
finally:
    u = [resource.getrusage(w) for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)]
    print("CPU_SECONDS %.1f" % sum(x.ru_utime + x.ru_stime for x in u), file=sys.stderr)
sys.exit(rc)
"""


def run_case(case_dir: Path, out_dir: Path, timeout: float, verbose: bool = False) -> dict:
    case_dir = Path(case_dir)
    truth = json.loads((case_dir / "truth.json").read_text())
    js = out_dir / f"{case_dir.name}.diagnosis.json"
    if js.exists():
        js.unlink()
    args = ["diagnose", str(case_dir / "nominal.bdf"), str(case_dir / "measured.uff"), "--json", str(js)]
    if (case_dir / "params.toml").exists():
        args += ["--params", str(case_dir / "params.toml")]
    cmd = [sys.executable, "-c", _WRAPPER, *(["-v"] if verbose else []), *args]
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    t0 = time.perf_counter()
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env, cwd=str(ROOT))
        rc, err = p.returncode, (p.stderr or "") + (p.stdout if p.returncode else "")
    except subprocess.TimeoutExpired:
        rc, err = -1, f"timeout after {timeout:.0f} s"
    wall = time.perf_counter() - t0
    cpu = None
    m = re.search(r"^CPU_SECONDS ([0-9.]+)$", err, re.MULTILINE)
    if m:
        cpu = float(m.group(1))
        err = err.replace(m.group(0), "").rstrip()
    (out_dir / f"{case_dir.name}.log").write_text("modalab " + " ".join(args) + f"\nexit {rc}\n" + err)
    res = {"case": case_dir.name, "seed": truth["seed"], "topology": truth["topology"],
           "truth": "control" if truth["control"] else truth["concealed"][0]["physics"], "wall_s": wall,
           "cpu_s": cpu, "error": None, "effect_to_noise": _visibility(case_dir)}
    if rc != 0 or not js.exists():
        lines = [ln for ln in err.strip().splitlines() if ln.strip()]
        res["error"] = (lines[-1] if lines else f"exit code {rc}, no output")[:300]
        return score_case(truth, None, res)
    return score_case(truth, parse_diagnosis(json.loads(js.read_text())), res)


def _visibility(case_dir: Path):
    """The effect's size against the noise at the case's sensors (``visibility.py``), None when not computed."""
    v = Path(case_dir) / "visibility.json"
    return json.loads(v.read_text()).get("effect_to_noise") if v.exists() else None


def rescore_case(case_dir: Path, out_dir: Path, previous: dict | None) -> dict:
    """Score the ``diagnosis.json`` a previous run left in ``out_dir`` again (after a change to the scoring or
    new ``visibility.json`` files), keeping that run's times and crash message; diagnose is not run."""
    truth = json.loads((Path(case_dir) / "truth.json").read_text())
    prev = previous or {}
    res = {"case": case_dir.name, "seed": truth["seed"], "topology": truth["topology"],
           "truth": "control" if truth["control"] else truth["concealed"][0]["physics"],
           "wall_s": prev.get("wall_s", 0.0), "cpu_s": prev.get("cpu_s"), "error": prev.get("error"),
           "effect_to_noise": _visibility(case_dir)}
    js = out_dir / f"{case_dir.name}.diagnosis.json"
    if res["error"] or not js.exists():
        res["error"] = res["error"] or "no diagnosis.json from the previous run"
        return score_case(truth, None, res)
    return score_case(truth, parse_diagnosis(json.loads(js.read_text())), res)


def score_case(truth: dict, diag: dict | None, res: dict) -> dict:
    res["truth_where"] = "" if truth["control"] else _where(truth["concealed"][0], truth)
    res["truth_value"] = None if truth["control"] else truth["concealed"][0]["value"]
    if diag is None:
        res.update(findings=[], kind_right=False, distance=None, value_error=None, spurious=None, right=False,
                   heldout={})
        return res
    env = truth.get("environment", [])
    fnd = diag["findings"]
    res["findings"] = [f"{f['physics']} at {_where(f, truth)} = {_num(f['value'])} {f['unit']}" + _alt_text(f, truth)
                       for f in fnd]
    res["heldout"] = diag["heldout"]
    allowed = set()
    for i, f in enumerate(fnd):
        for e in env:
            d = node_distance(f, e, truth)
            if f["physics"] == e["physics"] and d is not None and d <= 1:
                allowed.add(i)
    if truth["control"]:
        real = [i for i in range(len(fnd)) if i not in allowed]
        res.update(kind_right=None, distance=None, value_error=None, right=not real, spurious=len(real))
        return res
    t = truth["concealed"][0]
    same = [(node_distance(f, t, truth), i) for i, f in enumerate(fnd)
            if t["physics"] in {a["physics"] for a in f["alternatives"]}]
    same = [(d if d is not None else 99, i) for d, i in same]
    anyd = [(node_distance(f, t, truth), i) for i, f in enumerate(fnd) if i not in allowed]
    anyd = [(d if d is not None else 99, i) for d, i in anyd]
    match = min(same) if same else None
    res["kind_right"] = bool(same)
    res["distance"] = match[0] if match else (min(anyd)[0] if anyd else None)
    res["right"] = bool(match and match[0] <= 1)
    # right only through an ambiguous finding's alternative: the primary (best-fitting) explanation is of
    # another kind or more than one node away
    res["via_alternative"] = False
    if res["right"]:
        primary = dict(fnd[match[1]], alternatives=None)
        pd = node_distance(primary, t, truth)
        res["via_alternative"] = not (fnd[match[1]]["physics"] == t["physics"] and pd is not None and pd <= 1)
    res["value_error"] = None
    if res["right"]:
        f = fnd[match[1]]
        tv = _comparable_truth_value(t, f["unit"])
        if f["value"] is not None and tv:
            res["value_error"] = (float(f["value"]) - tv) / tv
    used = {match[1]} if res["right"] else set()
    res["spurious"] = len([i for i in range(len(fnd)) if i not in used and i not in allowed])
    return res


def _alt_text(f: dict, truth: dict) -> str:
    """' (or <physics> at <where>; ...)' for an ambiguous finding's other explanations."""
    others = (f.get("alternatives") or [])[1:]
    if not others:
        return ""
    return " (or " + "; ".join(f"{a['physics']} at {_where(a, truth)}" for a in others) + ")"


def _unit_key(u: str) -> str:
    u = (u or "").replace("·", "*").replace(" ", "").lower()
    return {"": "eta", "-": "eta", "1": "eta", "lossfactor": "eta"}.get(u, u)


def _comparable_truth_value(t: dict, unit: str):
    """The truth value in the finding's unit, or None when they measure different things (a rotary inertia
    against a point mass, a dashpot against a loss factor).  A clamp: kr (N*m/rad) or kt (N/m)."""
    fu = _unit_key(unit)
    if t["physics"] == "boundary_flexibility" and fu == "n/m":
        return t.get("k_translation")
    return t["value"] if fu == _unit_key(t.get("unit", "")) else None


def _num(v):
    return "?" if v is None else f"{v:.3g}"


def _where(item, truth):
    if item.get("dofs"):
        return ",".join(item["dofs"][:3]) + ("..." if len(item["dofs"]) > 3 else "")
    if item.get("elements"):
        return "el " + ",".join(str(e) for e in item["elements"])
    return "n " + ",".join(str(n) for n in item.get("nodes", []))


# ------------------------------------------------------------------ table and summary
def _fmt_err(v):
    return "-" if v is None else f"{v:.3g}"


def table(results) -> str:
    head = ("| case | topology | truth | effect / noise | finding(s) | kind right | dist (nodes) | value err | "
            "held-out err nominal / params / physics | wall / CPU (s) |")
    lines = [head, "|" + "---|" * 10]
    for r in results:
        h = r.get("heldout") or {}
        if r["error"]:
            fnd = f"**CRASH**: {r['error']}"
        else:
            fnd = "; ".join(r["findings"]) or "none"
        kr = "-" if r["kind_right"] is None else ("yes" if r["kind_right"] else "no")
        if r["truth"] == "control":
            kr = "ok" if r["right"] else "FALSE FINDING"
        ve = "-" if r["value_error"] is None else f"{100 * r['value_error']:+.0f} %"
        cpu = "-" if r.get("cpu_s") is None else f"{r['cpu_s']:.0f}"
        truth = r["truth"] + (f" at {r['truth_where']} = {_num(r['truth_value'])}" if r["truth"] != "control" else "")
        en = r.get("effect_to_noise")
        lines.append(f"| {r['case']} | {r['topology']} | {truth} | {'-' if en is None else f'{en:.3g}'} | {fnd} | {kr} | "
                     f"{'-' if r['distance'] is None else r['distance']}{' (alt)' if r.get('via_alternative') else ''} | {ve} | {_fmt_err(h.get('nominal'))} / "
                     f"{_fmt_err(h.get('parameters_only'))} / {_fmt_err(h.get('with_physics'))} | {r['wall_s']:.0f} / "
                     f"{cpu} |")
    return "\n".join(lines)


def summary(results) -> tuple[str, dict]:
    eff = [r for r in results if r["truth"] != "control"]
    ctl = [r for r in results if r["truth"] == "control"]
    crashes = [r for r in results if r["error"]]
    n_right = sum(1 for r in eff if r["right"])
    n_alt = sum(1 for r in eff if r["right"] and r.get("via_alternative"))
    verr = sorted(abs(r["value_error"]) for r in eff if r["right"] and r.get("value_error") is not None)
    n_ctl_find = sum(1 for r in ctl if not r["right"])           # a crash on a control counts as a failure
    n_spur = sum(1 for r in eff if r["error"] or (r["spurious"] or 0) > 0)
    ratios = []
    for r in eff:
        h = r.get("heldout") or {}
        if h.get("parameters_only") and h.get("with_physics"):
            ratios.append(h["parameters_only"] / h["with_physics"])
    n_ratio3 = sum(1 for x in ratios if x >= TARGETS["heldout_ratio"])
    walls = sorted(r["wall_s"] for r in results)
    cpus = sorted(r["cpu_s"] for r in results if r.get("cpu_s") is not None)
    n_fast = sum(1 for w in walls if w <= TARGETS["seconds_per_case"])
    s = {"cases": len(results), "effect_cases": len(eff), "controls": len(ctl), "crashes": len(crashes),
         "right_within_one_node": n_right / len(eff) if eff else None,
         "right_via_alternative": n_alt,
         "value_error_abs_median": verr[len(verr) // 2] if verr else None,
         "value_error_within_25pct": sum(1 for v in verr if v <= 0.25), "value_error_compared": len(verr),
         "finding_on_control": n_ctl_find / len(ctl) if ctl else None,
         "spurious_extra": n_spur / len(eff) if eff else None,
         "heldout_ratio_ge_3": n_ratio3 / len(eff) if eff else None,
         "heldout_ratio_median": sorted(ratios)[len(ratios) // 2] if ratios else None,
         "wall_median_s": walls[len(walls) // 2] if walls else None, "wall_max_s": walls[-1] if walls else None,
         "within_60_s": n_fast / len(walls) if walls else None,
         "cpu_median_s": cpus[len(cpus) // 2] if cpus else None, "cpu_max_s": cpus[-1] if cpus else None}
    by_kind: dict = {}
    for r in eff:
        k = by_kind.setdefault(r["truth"], [0, 0])
        k[0] += bool(r["right"])
        k[1] += 1

    def pct(x):
        return "-" if x is None else f"{100 * x:.0f} %"
    L = [f"cases {len(results)} (effects {len(eff)}, controls {len(ctl)}), diagnose crashes {len(crashes)}",
         f"kind right and within one node: {n_right}/{len(eff)} = {pct(s['right_within_one_node'])} "
         f"(target >= 90 %); of these, {n_alt} only through an ambiguous finding's alternative",
         "value of the right findings (same unit as the truth; not part of the targets): "
         + (f"{len(verr)} compared, median |error| {100 * s['value_error_abs_median']:.0f} %, within 25 %: "
            f"{s['value_error_within_25pct']}/{len(verr)}" if verr else "none compared"),
         f"finding on a control: {n_ctl_find}/{len(ctl)} = {pct(s['finding_on_control'])} (target <= 5 %)",
         f"effect cases with a spurious extra finding (or a crash): {n_spur}/{len(eff)} = "
         f"{pct(s['spurious_extra'])} (target <= 10 %)",
         f"held-out FRF error parameters-only / with physics >= 3: {n_ratio3}/{len(eff)} = "
         f"{pct(s['heldout_ratio_ge_3'])}; median ratio " + ("-" if s["heldout_ratio_median"] is None
                                                             else f"{s['heldout_ratio_median']:.2f}"),
         f"wall time per case: median {s['wall_median_s']:.0f} s, max {s['wall_max_s']:.0f} s, "
         f"<= 60 s: {pct(s['within_60_s'])} (target: all); CPU time (process and children) median "
         f"{s['cpu_median_s'] or 0:.0f} s, max {s['cpu_max_s'] or 0:.0f} s" if walls else "no case ran",
         "right by kind: " + ", ".join(f"{k} {a}/{b}" for k, (a, b) in sorted(by_kind.items()))]
    vis = [r for r in eff if r.get("effect_to_noise") is not None]
    if vis:
        seen = [r for r in vis if r["effect_to_noise"] >= 1.0]
        hidden = [r for r in vis if r["effect_to_noise"] < 1.0]
        s["right_within_one_node_visible"] = sum(1 for r in seen if r["right"]) / len(seen) if seen else None
        L.append(f"effects at least the noise at the sensors (visibility.py: effect / noise >= 1): right "
                 f"{sum(1 for r in seen if r['right'])}/{len(seen)} = {pct(s['right_within_one_node_visible'])}; "
                 f"below the noise: {len(hidden)} case(s)"
                 + (f" ({', '.join(r['case'] for r in hidden)}), right {sum(1 for r in hidden if r['right'])}"
                    if hidden else ""))
    return "\n".join(L), s


def select_cases(root: Path, seeds: str, pattern: str | None) -> list:
    out = []
    for d in sorted(p for p in Path(root).iterdir() if (p / "truth.json").exists()):
        seed = json.loads((d / "truth.json").read_text())["seed"]
        if seeds == "even" and seed % 2:
            continue
        if seeds == "odd" and not seed % 2:
            continue
        if pattern and not re.search(pattern, d.name):
            continue
        out.append(d)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", help="folder of generated cases (generate.py --out)")
    ap.add_argument("--seeds", choices=("even", "odd", "all"), default="odd")
    ap.add_argument("--cases", help="regular expression on the case folder names (e.g. 'portal|t_joint')")
    ap.add_argument("--jobs", type=int, default=1, help="cases run at the same time (default 1)")
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds before a case counts as failed")
    ap.add_argument("--follow", type=int, metavar="N", help="score cases as generate.py writes them, until N are "
                                                              "scored (one at a time, in seed order)")
    ap.add_argument("--out", help="folder for score.md, score.json and the per-case logs (default ROOT/score)")
    ap.add_argument("--log", action="store_true", help="run diagnose with -v: every decision and test statistic "
                    "in the per-case logs (the score is the same)")
    ap.add_argument("--rescore", action="store_true", help="do not run diagnose: score the diagnosis.json files a "
                                                           "previous run left in --out again (times kept)")
    a = ap.parse_args(argv)
    cases = select_cases(Path(a.root), a.seeds, a.cases)
    if not cases and not a.follow:
        print(f"no cases in {a.root} for --seeds {a.seeds} --cases {a.cases}", file=sys.stderr)
        return 2
    out = Path(a.out or Path(a.root) / "score")
    out.mkdir(parents=True, exist_ok=True)
    results = []

    def done(r):
        results.append(r)
        status = "CRASH " + r["error"] if r["error"] else ("; ".join(r["findings"]) or "no finding")
        print(f"[{len(results)}/{a.follow or len(cases)}] {r['case']}: truth {r['truth']} {r['truth_where']} -> {status} "
              f"({r['wall_s']:.0f} s)", flush=True)
        partial = sorted(results, key=lambda x: x["seed"])
        (out / "score.json").write_text(json.dumps({"results": partial, "summary": summary(partial)[1]},
                                                   indent=1, default=str))

    if a.rescore:
        prev_file = out / "score.json"
        prev = {r["case"]: r for r in json.loads(prev_file.read_text())["results"]} if prev_file.exists() else {}
        for c in cases:
            done(rescore_case(c, out, prev.get(c.name)))
    elif a.follow:
        # score cases while generate.py is still writing them (truth.json is written last), in seed order
        seen = set()
        while len(seen) < a.follow:
            todo = [c for c in select_cases(Path(a.root), a.seeds, a.cases) if c.name not in seen]
            if not todo:
                time.sleep(20)
                continue
            seen.add(todo[0].name)
            done(run_case(todo[0], out, a.timeout, a.log))
    elif a.jobs > 1:
        from concurrent.futures import ThreadPoolExecutor
        with ThreadPoolExecutor(a.jobs) as ex:
            for r in ex.map(lambda c: run_case(c, out, a.timeout, a.log), cases):
                done(r)
    else:
        for c in cases:
            done(run_case(c, out, a.timeout, a.log))
    results.sort(key=lambda x: x["seed"])
    tab = table(results)
    summ, _ = summary(results)
    text = f"{tab}\n\n{summ}\n"
    (out / "score.md").write_text(text)
    print()
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
