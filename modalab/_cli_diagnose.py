"""``modalab diagnose``: locate what an FE model leaves out, name the physics, model it, prove it."""
from __future__ import annotations

import json
from pathlib import Path


def _priors(path) -> dict:
    """``prior`` of each ``[[parameter]]`` of a parameter file: a relative standard deviation (0.05 = ±5 %) or
    ``"free"``; parameters without it keep the defaults (E, G ±5 %, density ±3 %, sections ±5 %, damping free)."""
    import tomllib

    from .errors import PlanError

    try:
        d = tomllib.loads(Path(path).read_text())
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise PlanError(f"cannot read parameter file {str(path)!r}: {e}") from None
    out = {}
    for it in d.get("parameter") or d.get("parameters") or []:
        if isinstance(it, dict) and "prior" in it and "name" in it:
            v = it["prior"]
            if not (v == "free" or (isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0)):
                raise PlanError(f"{path}: parameter {it['name']!r}: prior = {v!r}; expected a relative standard "
                                "deviation > 0 (0.05 = ±5 %) or \"free\"")
            out[str(it["name"])] = v
    return out


def diagnose_files(model_path, measured_path, *, modes=None, params=None, json_path=None, report_dir=None,
                   progress=None, criterion: str = "auto", kinds=None):
    """Diagnose one configuration from files; returns the :class:`~updating.diagnosis.Diagnosis`."""
    from updating.diagnosis import diagnose
    from updating.diagnosis.library import validate_kinds

    from .frf import FRF
    from .pipeline import load_model, load_modes, load_params

    kinds = validate_kinds(kinds)                  # a misspelt kind fails before any file is read
    model = load_model(model_path)
    plist = load_params(params, model) if params else None
    kw = {}
    priors = _priors(params) if params else None
    if priors:
        kw["priors"] = priors
    if modes:
        kw["test_modes"] = load_modes(modes)
    if measured_path is None:
        from updating.diagnosis import diagnose_modes

        d = diagnose_modes(model, kw["test_modes"], parameters=plist)
    else:
        measured = FRF.from_uff(measured_path)
        d = diagnose(model, measured, parameters=plist, progress=progress, criterion=criterion, kinds=kinds, **kw)
    if report_dir is not None:
        if hasattr(d, "save"):
            d.save(report_dir)
        else:
            Path(report_dir).mkdir(parents=True, exist_ok=True)
            (Path(report_dir) / "diagnosis.json").write_text(json.dumps(d.to_dict(), indent=1, default=str))
    if json_path is not None:
        Path(json_path).parent.mkdir(parents=True, exist_ok=True)
        Path(json_path).write_text(json.dumps(d.to_dict(), indent=1, default=str))
    return d


def cmd_diagnose(a):
    from .cli import _print

    if a.measured is None and a.modes is None:
        from .errors import PlanError

        raise PlanError("give measured FRFs (MEASURED.uff) or --modes MODES.uff (a GVT's modes alone)")
    d = diagnose_files(a.model, a.measured, modes=a.modes, params=a.params, json_path=a.json,
                       report_dir=a.report, progress=lambda m: _print(m), criterion=a.criterion,
                       kinds=a.kinds)
    dd = d.to_dict()
    for f in dd["findings"]:
        vals = ", ".join(f"{v['name']} = {v['value']:.4g} {v['unit']} (± {v['std']:.2g})" for v in f["values"])
        _print(f"FINDING {f['physics']} at {', '.join(f['dofs']) or f['nodes']}: {vals}")
    for name, blk in dd["fit"].items():
        _print(f"{name:>16}: " + ", ".join(f"{k} = {v:.4g}" for k, v in blk.items() if isinstance(v, (int, float))))
    _print("")
    _print(dd["statement"])
    return 0


def register(sub):
    from updating.diagnosis.library import KINDS

    s = sub.add_parser("diagnose", help="locate and name the physics a model leaves out, model it, prove it")
    s.add_argument("model", help="nominal FE model as Nastran bulk data (.bdf)")
    s.add_argument("measured", nargs="?", help="measured FRFs with coherence (UFF 58); node ids and directions "
                                               "refer to the model's grids and basic system")
    s.add_argument("--modes", help="identified modes (UFF 55 or JSON); alone, a modes-only diagnosis")
    s.add_argument("--params", help="TOML [[parameter]] file (default: E and rho multipliers per property group)")
    s.add_argument("--json", help="diagnosis.json path (schema in the README)")
    s.add_argument("--report", help="folder for diagnosis.json, MCI maps, FRF overlays and the augmented model")
    s.add_argument("--criterion", choices=("auto", "mci", "frf"), default="auto",
                   help="how candidate physics is judged with the parameters re-fitted: by the MCI (thesis 3.2.4) "
                        "or by the FRF fit; auto: MCI up to 200 DOFs, FRF fit above (default: auto)")
    s.add_argument("--kinds", nargs="+", metavar="KIND",
                   help="kinds of missing physics to consider, among " + ", ".join(KINDS) + " (default: all)")
    s.set_defaults(func=cmd_diagnose)
