"""``modalab diagnose``: locate what an FE model leaves out, name the physics, model it, prove it."""
from __future__ import annotations

import difflib
from pathlib import Path
from updating.diagnosis.library import validate_kinds
from modalab.app.stages import DiagnoseOptions
from modalab.app._cli_console import _print
from modalab.app.stages import diagnose
from modalab.app.campaign import diagnose_many
from modalab.app.stages._diagnose import _read_measured as read_measured
from modalab.core.errors import ModalabError, PlanError
from updating.diagnosis.library import KINDS


def parse_kinds(values) -> tuple | None:
    """``--kinds`` as given (space- and/or comma-separated: ``added_mass,ground_spring`` or ``added_mass
    ground_spring``) as a sorted tuple of kinds; every misspelt item is named with its closest kind."""
    if not values:
        return None
    items = [k for v in values for k in str(v).replace(",", " ").split() if k]
    bad = []
    for k in items:
        try:
            validate_kinds([k])
        except ModalabError:
            m = difflib.get_close_matches(k, KINDS, n=1, cutoff=0.5) or [c for c in KINDS if k.lower() in c]
            bad.append(f"{k} (did you mean {m[0]}?)" if m else k)
    if bad:
        raise PlanError(f"--kinds: unknown kind{'s' if len(bad) > 1 else ''} of missing physics {', '.join(bad)}; "
                        f"expected some of {', '.join(KINDS)} (separated by spaces or commas)")
    return tuple(sorted(validate_kinds(items)))


def _options(a):

    kinds = parse_kinds(a.kinds)   # a misspelt kind fails before any file is read
    if a.jobs is not None and a.jobs < 1:
        raise PlanError(f"--jobs {a.jobs}: expected a positive number of processes (1: no parallel fits)")
    return DiagnoseOptions(parameters=a.params, criterion=a.criterion, dofmap=getattr(a, "map", None), kinds=kinds,
                           ignore_unsupported=a.ignore_unsupported, jobs=a.jobs)


def _pm(std) -> str:
    """One standard deviation as the findings print it; ``None`` (diagnosis.json's value for one the data do not
    determine: a flat direction, or a value on its bound) said in words, never as a number."""
    return "± not determined by these data" if std is None else f"± {std:.2g}"


def cmd_diagnose(a):

    measured = list(a.measured or [])
    if len(measured) > 1:
        return _campaign(a, measured)
    r = diagnose(a.model, frf_path=measured[0] if measured else None, modes_path=a.modes, opts=_options(a),
                 json_path=a.json, out_dir=a.report, progress=lambda m: _print(m))
    dd = r.result.to_dict()
    for f in dd["findings"]:
        vals = ", ".join(f"{v['name']} = {v['value']:.4g} {v['unit']} ({_pm(v['std'])})" for v in f["values"])
        vals += "".join(f"; with {p['value']:.4g} {p['unit']} at {', '.join(p['dofs']) or p['nodes']} "
                        f"({_pm(p['std'])})" for p in f.get("parts", []))
        _print(f"FINDING {f['physics']} at {', '.join(f['dofs']) or f['nodes']}: {vals}")
    for name, blk in dd["fit"].items():
        _print(f"{name:>16}: " + ", ".join(f"{k} = {v:.4g}" for k, v in blk.items() if isinstance(v, (int, float))))
    _print("")
    _print(dd["statement"])
    return 0


def _campaign(a, measured):
    """Several FRF files (configurations of a GVT): one folder per input under --report, in parallel."""

    if not a.report or a.json or a.modes:
        raise PlanError("with several MEASURED files give --report FOLDER (one sub-folder with diagnosis.json "
                        "per input; --json and --modes name one file and are for a single input)")
    for p in measured:          # a damaged input is refused before any is diagnosed (no partial campaign)
        read_measured(p)
    res = diagnose_many(a.model, measured, a.report, _options(a), dask=a.dask, workers=a.workers)
    for r in res:
        _print(f"{r['input']}: {len(r['findings'])} finding(s) -> {r['out']}")
        _print(f"  {r['statement']}")
    _print(f"campaign index: {Path(a.report) / 'campaign.json'}")
    return 0


def register(sub):

    s = sub.add_parser("diagnose", help="locate and name the physics a model leaves out, model it, prove it")
    s.add_argument("model", help="nominal FE model as Nastran bulk data (.bdf)")
    s.add_argument("measured", nargs="*", help="measured FRFs with coherence (UFF 58); node ids and directions "
                                               "refer to the model's grids and basic system; several files = a "
                                               "campaign (needs --report)")
    s.add_argument("--ignore-unsupported", action="store_true",
                   help="build the model without the structural cards modalab does not model (e.g. CTRIA6); "
                        "by default they are an error, since the model would be a different structure; also "
                        "keeps, unmodelled, a card whose name looks like a typo of a known card (e.g. CBAT)")
    s.add_argument("--modes", help="identified modes (UFF 55 or JSON); alone, a modes-only diagnosis")
    s.add_argument("--map", help="with --modes alone: DOF map file (TOML/CSV, as for correlate: test DOF -> model "
                                 "DOF with sign); default: test node ids are model grid ids")
    s.add_argument("--params", help="TOML [[parameter]] file (default: E and rho multipliers per property group)")
    s.add_argument("--json", help="diagnosis.json path (schema in the README)")
    s.add_argument("--report", help="folder for diagnosis.json, MCI maps, FRF overlays and the augmented model (diagnosed.bdf); "
                                     "with several inputs, one sub-folder per input")
    s.add_argument("--criterion", choices=("auto", "mci", "frf"), default="auto",
                   help="how candidate physics is judged with the parameters re-fitted: by the MCI (thesis 3.2.4) "
                        "or by the FRF fit; auto: MCI up to 200 DOFs, FRF fit above (default: auto)")
    s.add_argument("--dask", help="address of an existing Dask scheduler (tcp://host:port) for campaigns")
    s.add_argument("--workers", type=int, help="local processes for campaigns (default: the number of CPUs)")
    s.add_argument("--jobs", type=int, help="processes for one diagnosis' independent fits (default: the CPUs this "
                                            "process may use; 1: none in parallel; the findings are the same "
                                            "either way); a campaign's inputs run one process each")
    s.add_argument("--kinds", nargs="+", metavar="KIND",
                   help="kinds of missing physics to consider, among " + ", ".join(KINDS) + " (separated by "
                        "spaces or commas; default: all)")
    s.set_defaults(func=cmd_diagnose)
