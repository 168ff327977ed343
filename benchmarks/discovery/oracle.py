"""Where does the diagnosis lose the truth?  A stage-by-stage account of the TRUE candidate of one case.

    PYTHONPATH=$PWD python benchmarks/discovery/oracle.py /tmp/disc/case036_suspended_frame [--json out.json]

For one generated case (tuning seeds only: the oracle reads ``truth.json``, so running it on a held-out case
spoils that case), the case is loaded exactly as ``modalab diagnose`` loads it (the CLI stage's own loaders:
bulk data, ``params.toml`` with its priors, the UFF) and the library's own :class:`~updating.diagnosis.
workflow.Diagnoser` is driven step by step.  Nothing of the pipeline is re-implemented: the oracle calls the
steps and the per-candidate methods the steps use themselves.  After :meth:`Diagnoser.baseline` and
:meth:`Diagnoser.localise` it asks the first screening (:meth:`Diagnoser._options`, as :meth:`Diagnoser.screen`
does) and reports, for every library candidate of the concealed kind at the concealed place (a clamp gives
its translation and rotation groups and single components, a joint its member ends):

* **ranking** — rank and explained fraction in the linear MCI ranking, and in each exact FRF screening
  (around the nominal and the updated parameters), with the screening's best value; whether it is among the
  options the first step tries;
* **MCI route** — the candidate fitted with the parameters on the MCI (:meth:`Diagnoser._try`) and the
  acceptance tests of that route (:meth:`Diagnoser._judge`): which one rejects it and by how much;
* **FRF route** — the candidate fitted with the parameters on the training FRFs from the screening's value
  and from the true value (:meth:`Diagnoser._fit_pick`), its fitted value against the truth, the held-out FRF
  error with it against parameters-only, and the tests of the screening-pick route
  (:meth:`Diagnoser._judge_pick`);
* **outcome** — the rest of the pipeline run as ``diagnose`` runs it (screen, model, prove): the findings.

This separates a ranking problem (the truth is not tried), a fitting problem (tried, but the fit does not
reach the truth's value or the parameters/damping absorb it) and an acceptance problem (fitted well, rejected
by a test; the message says which test and the numbers).
"""
from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from modalab.app.stages import load_model, load_parameters  # noqa: E402
from modalab.core import uff  # noqa: E402
from updating.diagnosis.fit import frf_error, model_frf  # noqa: E402
from updating.diagnosis.workflow import Diagnoser, DiagnoserConfig  # noqa: E402


def truth_candidates(lib: list, concealed: dict) -> list:
    """Library candidates of the concealed kind at the concealed place: same physics and (for element
    effects) the same elements, else a shared node and (when both name DOFs) a shared DOF."""
    kind, nodes = concealed["physics"], set(concealed.get("nodes", []))
    els, dofs = set(concealed.get("elements", [])), set(concealed.get("dofs", []))
    out = []
    for c in lib:
        if c.physics != kind:
            continue
        if els and c.elements and kind == "local_damping":
            if set(c.elements) == els or (c.matrix == "D" and set(c.elements) >= els and len(c.elements) <= 3):
                out.append(c)
            continue
        if not set(c.nodes) & nodes:
            continue
        if dofs and c.dofs and not set(c.dofs) & dofs:
            continue
        if kind == "added_mass" and c.value_name == "J":
            continue                                  # the truth's masses are point masses
        out.append(c)
    return out


def _rank(listing, key):
    for i, t in enumerate(listing):
        if t[0].key == key:
            return i + 1, float(t[2]), t[1]
    return None, None, None


def load_case(case: Path):
    """The model, measured FRFs, parameters and priors as ``modalab diagnose`` loads them."""
    model = load_model(case / "nominal.bdf")
    params, priors = None, None
    if (case / "params.toml").exists():
        from updating.fe.parameter_file import read_priors
        params = load_parameters(case / "params.toml", model)[0]
        priors = read_priors(case / "params.toml") or None
    return model, uff.read_frf(case / "measured.uff"), params, priors


def oracle(case: Path, *, run_rest: bool = True) -> dict:
    case = Path(case)
    truth = json.loads((case / "truth.json").read_text())
    model, H, params, priors = load_case(case)
    d = Diagnoser(DiagnoserConfig(parameters=params, priors=priors, criterion="auto"))
    d._t0 = time.perf_counter()
    d.timings = {}
    d.baseline(model, H)
    d.localise()
    held = d.held

    def held_err(pm, p):
        return float(frf_error(model_frf(pm.structure(p), held), held))

    rep = {"case": case.name, "truth": truth["concealed"], "criterion": "mci" if d.use_mci else "frf",
           "frf_error": {"nominal_train": float(d.nom.error), "parameters_only_train": float(d.upd.error),
                         "nominal_held_out": held_err(d.pm, d.p_nomd),
                         "parameters_only_held_out": held_err(d.pm, d.upd.p)},
           "parameters_only": {p.name: round(float(v), 4) for p, v in zip(d.params, d.upd.p)}}
    options = d._options(0)                            # the first screening, exactly as screen(0) asks it
    opt_keys = {c.key for c, _ in options}
    ranking = d.ranking or []
    rep["ranking_top"] = [(c.label, round(g, 4)) for c, _, g in ranking[:5]]
    rep["screens_top"] = [[(c.label, round(float(g), 4)) for c, _, g in scr[:5]] for scr, _ in d._screens]
    lib = sorted({c.key: c for scr, _ in d._screens for c, _, _ in scr}.values(), key=lambda c: c.key)
    lib += [c for c, _, _ in ranking if c.key not in {x.key for x in lib}]
    n_eq = (d.W.size * len(d.train.responses) * 2) if d.use_mci else d.train.H.size * 2
    rep["candidates"] = []
    for conc in truth["concealed"]:
        for c in truth_candidates(lib, conc):
            r = {"candidate": c.label, "key": c.key, "tried_first_step": c.key in opt_keys}
            rk, g, th = _rank(ranking, c.key)
            r["mci_rank"], r["mci_explained"] = rk, g
            r["screens"] = []
            best_scr = None
            for k, (scr, p_scr) in enumerate(d._screens):
                rk2, g2, v2 = _rank(scr, c.key)
                r["screens"].append({"around": ("nominal", "updated")[k] if k < 2 else k, "rank": rk2,
                                     "explained": g2, "value": v2, "of": len(scr)})
                if g2 is not None and (best_scr is None or g2 > best_scr[0]):
                    best_scr = (g2, v2, p_scr)
            if d.use_mci:
                t = d._try(c, th if th is not None else (best_scr[1] if best_scr else None), 0)
                if t is not None:
                    ok, why = d._judge(t[:6], n_eq)
                    r["mci_route"] = {"mci_rss": float(t[1]), "current_rss": float(d.rss_cur),
                                      "value": float(t[3][-1] * t[6]), "accepted": bool(ok), "tests": why,
                                      "held_out_error": held_err(t[2], t[3])}
            starts = []
            if best_scr is not None:
                starts.append(("screening value", best_scr[1], best_scr[2]))
            tv = conc.get("value")
            # the truth's value is the candidate's own where the units agree (a spring, a point mass, a loss
            # factor on the elements); a clamp's or a joint's is split over components in the truth
            if tv is not None and (c.physics in ("ground_spring", "added_mass") or c.matrix == "D"):
                starts.append(("true value", float(tv), d.upd.p))
            r["frf_route"] = []
            for name, v, p_scr in starts:
                pm_aug, fr, clo, chi, _ = d._fit_pick(c, v, p_scr)
                ok, why = d._judge_pick(c, pm_aug, fr, clo, chi)
                r["frf_route"].append({"start": name, "start_value": float(v),
                                       "fitted_value": float(fr.p[-1]) * _scale(d, c),
                                       "train_error": float(fr.error), "held_out_error": held_err(pm_aug, fr.p),
                                       "parameters": [round(float(x), 4) for x in fr.p[:len(d.params)]],
                                       "accepted": bool(ok), "tests": why})
            rep["candidates"].append(r)
    if run_rest:
        for it in range(d.config.max_findings):
            if not d.screen(it):
                break
        d.timings["3-4 localise+name"] = time.perf_counter() - d._t1
        d.model()
        diag = d.prove()
        rep["findings"] = [f.label for f in diag.findings]
        rep["statement"] = diag.statement
    return rep


def _scale(d, c) -> float:
    from updating.diagnosis.terms import _augment
    return float(_augment(d.model0, [c])[2][-1])


def _text(rep: dict) -> str:
    fe = rep["frf_error"]
    L = [f"{rep['case']}: truth {rep['truth']}", f"criterion {rep['criterion']}; FRF error train nominal "
         f"{fe['nominal_train']:.4g}, parameters-only {fe['parameters_only_train']:.4g}; held-out nominal "
         f"{fe['nominal_held_out']:.4g}, parameters-only {fe['parameters_only_held_out']:.4g}",
         f"parameters-only: {rep['parameters_only']}",
         f"MCI ranking top: {rep['ranking_top']}"]
    for k, s in enumerate(rep["screens_top"]):
        L.append(f"FRF screening {k} top: {s}")
    if not rep["candidates"]:
        L.append("NO library candidate matches the truth")
    for r in rep["candidates"]:
        L.append(f"-- {r['candidate']}: tried in the first step {r['tried_first_step']}; MCI rank {r['mci_rank']} "
                 f"explained {r['mci_explained']}")
        for s in r["screens"]:
            L.append(f"   screening around {s['around']}: rank {s['rank']}/{s['of']} explained {s['explained']} "
                     f"value {s['value']}")
        if "mci_route" in r:
            m = r["mci_route"]
            L.append(f"   MCI route: rss {m['mci_rss']:.4g} (current {m['current_rss']:.4g}) value {m['value']:.4g} "
                     f"held-out {m['held_out_error']:.4g} accepted {m['accepted']}: {m['tests']}")
        for f in r["frf_route"]:
            L.append(f"   FRF route from the {f['start']} {f['start_value']:.4g}: value {f['fitted_value']:.4g}, train "
                     f"{f['train_error']:.4g}, held-out {f['held_out_error']:.4g}, accepted {f['accepted']}: "
                     f"{f['tests']}")
    if "findings" in rep:
        L.append(f"findings: {rep['findings']}")
        L.append(f"statement: {rep['statement']}")
    return "\n".join(L)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("case", type=Path, help="a generated case folder (tuning seeds only)")
    ap.add_argument("--json", type=Path, help="also write the report as JSON")
    ap.add_argument("--no-rest", action="store_true", help="stop after the first step (no findings)")
    ap.add_argument("-v", action="store_true", help="log the diagnosis")
    a = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO if a.v else logging.WARNING, format="%(message)s")
    rep = oracle(a.case, run_rest=not a.no_rest)
    print(_text(rep))
    if a.json:
        a.json.write_text(json.dumps(rep, indent=1, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
