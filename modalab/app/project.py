"""Project files for ``modalab run``: what to measure, which FE model, what to update (a TOML file).

A project names the test plan (or measured FRFs), the FE model as Nastran bulk data, the updating
parameters and the options of every stage.  Paths are relative to the project file.  Example (the
embedded demo, ``examples/demo_project/project.toml``)::

    [project]
    name = "GARTEUR-like frame"

    [test]
    plan = "plan.toml"            # acquisition.plan test plan (or: frf = "measured.uff", no acquisition)
    backend = "sim"               # 'sim' or 'nidaqmx'; --backend overrides
    # truth = "pkg.module:function"  # sim only: a Python builder of the structure on the bench

    [frf]
    estimator = "H1"              # H1 | H2 | Hv
    reciprocity = true            # roving hammer: reorder to the fixed accelerometers as references

    [identify]
    band_hz = [2.0, 80.0]
    max_order = 40

    [model]
    bulk = "nominal.bdf"          # the FE model

    [correlate]
    mac_min = 0.5
    # freq_window = 0.35          # largest relative frequency distance of a pair
    # map = "map.toml"            # test DOF -> model DOF; or geometry = "geometry.uff", or same_ids = true;
    #                             # default: the test geometry carried by the modes (from the FRF file)

    [update]
    parameters = "params.toml"    # [[parameter]] name, field, properties|materials|groups|elements, mode
    max_iter = 20

    [diagnose]
    max_lines = 120
    band_hz = [2.0, 80.0]
    # jobs = 2                    # processes for a diagnosis' independent fits (default: the CPUs available)

    [report]
    frf_dofs = ["218+Z", "200+Z"]  # FRF overlays at these response DOFs

A parameter file::

    [[parameter]]
    name = "E_wing"
    field = "E"                   # E, G, rho, h, b, mass, k, ... (updating.fe.parameters)
    properties = ["wing"]         # selector: properties | materials | groups | elements
    mode = "factor"               # p multiplies the nominal value ('value': p is the value)
    lower = 0.5                   # optional bounds (in p units)
    upper = 2.0

:func:`load_project` validates everything it can without running anything and raises
:class:`modalab.core.errors.ProjectError`-like :class:`modalab.core.errors.ModalabValueError` subclasses
(``PlanError``) naming the file, the key, the bad value and what to write instead.
"""
from __future__ import annotations

import difflib
import logging
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from acquisition.estimators import ESTIMATORS
from modalab.core.dof import Dof
from modalab.core.errors import ModalabError, PlanError
from updating.diagnosis.library import validate_kinds
from modalab.app.stages._common import load_parameters

log = logging.getLogger(__name__)

__all__ = ["Project", "load_project", "STAGES", "STAGE_OPTIONS"]

#: the stages of ``modalab run``, in order
STAGES = ("acquire", "frf", "identify", "correlate", "update", "diagnose", "report")

#: the options each stage accepts (key -> type, default); unknown keys are refused
STAGE_OPTIONS = {
    "test": {"plan": (str, None), "frf": (str, None), "backend": (str, "sim"), "truth": (str, None),
             "seed": (int, None), "hits": (int, None), "points": (list, None)},
    "frf": {"estimator": (str, "H1"), "reciprocity": (bool, True), "force_fraction": (float, None),
            "exp_end_level": (float, None)},
    "identify": {"band_hz": (list, None), "max_order": (int, None), "select": ((str, list), "auto"),
                 "weighting": (str, None)},
    "model": {"bulk": (str, None), "n_modes": (int, 20)},
    # correlate: the same defaults as ``modalab correlate`` (freq_weight None: the pairing rule's 1 with
    # frequencies; test DOFs mapped by the modes' geometry unless map, geometry or same_ids says otherwise)
    "correlate": {"mac_min": (float, 0.5), "freq_weight": (float, None), "freq_window": (float, 0.35),
                  "map": (str, None), "geometry": (str, None), "same_ids": (bool, False)},
    "update": {"parameters": (str, None), "max_iter": (int, 20), "regularisation": ((str, float), "lcurve"),
               "use_shapes": (bool, True), "freq_sigma": ((float, list), None), "shape_sigma": (float, 0.05)},
    "diagnose": {"parameters": (str, None), "max_lines": (int, 120), "band_hz": (list, None),
                 "max_findings": (int, 3), "max_nfev": (int, 30), "holdout": (str, None), "kinds": (list, None),
                 "enabled": (bool, True), "jobs": (int, None)},
    "report": {"frf_dofs": (list, None), "title": (str, None)},
    "project": {"name": (str, "modalab project")},
}


@dataclass
class Project:
    """A validated project: ``path`` (the TOML file), ``root`` (its folder) and one options dict per section."""

    path: Path
    root: Path
    options: dict = field(default_factory=dict)

    @property
    def name(self) -> str:
        return self.options["project"]["name"]

    def section(self, name: str) -> dict:
        return dict(self.options.get(name, {}))

    def resolve(self, p) -> Path:
        """A path from the project file, relative to the project folder."""
        q = Path(p)
        return q if q.is_absolute() else (self.root / q)

    @property
    def plan_path(self) -> Path | None:
        t = self.options["test"]
        return self.resolve(t["plan"]) if t.get("plan") else None

    @property
    def frf_path(self) -> Path | None:
        t = self.options["test"]
        return self.resolve(t["frf"]) if t.get("frf") else None

    @property
    def bulk_path(self) -> Path:
        return self.resolve(self.options["model"]["bulk"])

    @property
    def parameters_path(self) -> Path | None:
        p = self.options["update"].get("parameters")
        return self.resolve(p) if p else None


def _check_type(src, section, key, value, kind):
    kinds = kind if isinstance(kind, tuple) else (kind,)
    if float in kinds and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if not isinstance(value, kinds) or (bool not in kinds and isinstance(value, bool)):
        names = " or ".join(k.__name__ for k in kinds)
        raise PlanError(f"{src}: [{section}] {key} = {value!r}; expected {names}")
    return value


def _read_toml(path: Path, what: str) -> dict:
    if path.is_dir():
        raise PlanError(f"{what} {str(path)!r} is a folder; expected a TOML file")
    if not path.is_file():
        raise PlanError(f"{what} {str(path)!r} does not exist; check the path (relative paths are taken from the "
                        "project file's folder)")
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as e:
        raise PlanError(f"{what} {str(path)!r} is not valid TOML: {e}") from None


def _unknown(what: str, bad: list, valid: list) -> str:
    """``unknown key max_ordr (did you mean max_order?); expected one of band_hz, max_order, ...``: each unknown
    name with its closest valid name (difflib), the valid names as plain text."""

    items = []
    for b in bad:
        m = difflib.get_close_matches(b, list(valid), n=1, cutoff=0.6)
        items.append(f"{b} (did you mean {m[0]}?)" if m else b)
    return (f"unknown {what}{'s' if len(bad) > 1 else ''} {', '.join(items)}; expected one of "
            f"{', '.join(sorted(valid))}")


def load_project(path) -> Project:
    """Read and validate a project file (see the module docstring); fills in every default."""
    path = Path(path).resolve()
    raw = _read_toml(path, "project file")
    src = str(path)
    unknown = set(raw) - set(STAGE_OPTIONS)
    if unknown:
        raise PlanError(f"{src}: {_unknown('section', [f'[{u}]' for u in sorted(unknown)], [f'[{k}]' for k in STAGE_OPTIONS])}")
    opts = {}
    for sec, spec in STAGE_OPTIONS.items():
        given = raw.get(sec, {})
        if not isinstance(given, dict):
            raise PlanError(f"{src}: [{sec}] must be a table of keys")
        bad = set(given) - set(spec)
        if bad:
            raise PlanError(f"{src}: [{sec}] {_unknown('key', sorted(bad), sorted(spec))}")
        o = {}
        for key, (kind, default) in spec.items():
            o[key] = _check_type(src, sec, key, given[key], kind) if key in given else default
        opts[sec] = o
    proj = Project(path=path, root=path.parent, options=opts)
    t = opts["test"]
    if bool(t["plan"]) == bool(t["frf"]):
        raise PlanError(f"{src}: [test] needs exactly one of plan = 'test plan.toml' (acquire) or "
                        "frf = 'measured.uff' (FRFs measured already)")
    if t["backend"] not in ("sim", "nidaqmx"):
        raise PlanError(f"{src}: [test] backend = {t['backend']!r}; expected 'sim' or 'nidaqmx'")
    for p in (proj.plan_path, proj.frf_path):
        if p is not None and not p.is_file():
            raise PlanError(f"{src}: [test] file {str(p)!r} does not exist")
    if t["truth"] and ":" not in t["truth"]:
        raise PlanError(f"{src}: [test] truth = {t['truth']!r}; expected 'package.module:function'")
    if not opts["model"]["bulk"]:
        raise PlanError(f"{src}: [model] bulk = 'model.bdf' is missing; the FE model is needed to correlate, "
                        "update and diagnose")
    if not proj.bulk_path.is_file():
        raise PlanError(f"{src}: [model] bulk file {str(proj.bulk_path)!r} does not exist")
    for sec in ("identify", "diagnose"):
        b = opts[sec]["band_hz"]
        numbers = b is not None and len(b) == 2 and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                        and math.isfinite(x) for x in b)
        if b is not None and not (numbers and 0 <= b[0] < b[1]):
            raise PlanError(f"{src}: [{sec}] band_hz = {b!r}; expected [low, high]: two numbers in Hz with "
                            "0 <= low < high, e.g. band_hz = [5, 700]")
    for sec, key, low in (("update", "max_iter", 1), ("identify", "max_order", 1), ("diagnose", "max_findings", 0),
                          ("diagnose", "max_lines", 1), ("diagnose", "max_nfev", 1), ("diagnose", "jobs", 1)):
        v = opts.get(sec, {}).get(key)
        if v is not None and not (isinstance(v, int) and not isinstance(v, bool) and v >= low):
            raise PlanError(f"{src}: [{sec}] {key} = {v!r}; expected a whole number >= {low}")
    fs = opts["update"].get("freq_sigma")
    if fs is not None:
        vals = fs if isinstance(fs, list) else [fs]
        if not all(isinstance(x, (int, float)) and not isinstance(x, bool) and 0 < x <= 0.5 for x in vals):
            raise PlanError(f"{src}: [update] freq_sigma = {fs!r}; expected relative standard deviations above 0 and "
                            "up to 0.5 (0.002 = 0.2 %)")
    _check_values(src, opts)
    if proj.parameters_path is not None:
        load_parameters(proj.parameters_path)          # validate now, not after an hour of acquisition
    if opts["diagnose"]["parameters"] is None:
        opts["diagnose"]["parameters"] = opts["update"]["parameters"]
    return proj


def _check_values(src: str, opts: dict) -> None:
    """The values a stage would refuse, refused now (naming the file, section and key), not when the stage
    starts after an acquisition; the same rules as the stages' own checks."""
    def bad(sec, key, expected):
        raise PlanError(f"{src}: [{sec}] {key} = {opts[sec][key]!r}; expected {expected}")

    def number(v):
        return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)

    if opts["frf"]["estimator"] not in ESTIMATORS:
        m = difflib.get_close_matches(str(opts["frf"]["estimator"]), ESTIMATORS, n=1, cutoff=0.5)
        bad("frf", "estimator", f"one of {', '.join(ESTIMATORS)}" + (f" (did you mean {m[0]}?)" if m else ""))
    ff, end = opts["frf"]["force_fraction"], opts["frf"]["exp_end_level"]
    if ff is not None and not (number(ff) and 0 < ff <= 1):
        bad("frf", "force_fraction", "a fraction of the record in (0, 1]")
    if end is not None and not (number(end) and 0 <= end < 1):
        bad("frf", "exp_end_level", "a level in [0, 1) at the record end (0.01 = 1 %; 0 = no window)")
    if opts["identify"]["weighting"] not in (None, "coherence", "variance"):
        bad("identify", "weighting", "'coherence' or 'variance' (or leave it out)")
    sel = opts["identify"]["select"]
    if isinstance(sel, list) and not (sel and all(number(x) and x > 0 for x in sel)):
        bad("identify", "select", "'auto' or frequencies in Hz, e.g. select = [12.5, 40.2]")
    c = opts["correlate"]
    if not (number(c["mac_min"]) and 0 <= c["mac_min"] <= 1):
        bad("correlate", "mac_min", "a value in [0, 1] such as 0.5")
    if not (number(c["freq_window"]) and c["freq_window"] > 0):
        bad("correlate", "freq_window", "a relative frequency distance above 0, e.g. 0.35")
    if c["freq_weight"] is not None and not (number(c["freq_weight"]) and c["freq_weight"] >= 0):
        bad("correlate", "freq_weight", "a weight >= 0")
    u = opts["update"]
    r = u["regularisation"]
    if not ((isinstance(r, str) and r in ("lcurve", "gcv")) or (number(r) and r >= 0)):
        bad("update", "regularisation", "'lcurve', 'gcv' or a factor >= 0")
    if not (number(u["shape_sigma"]) and u["shape_sigma"] > 0):
        bad("update", "shape_sigma", "a relative standard deviation above 0, e.g. 0.05")
    kinds = opts["diagnose"]["kinds"]
    if kinds is not None:
        try:
            validate_kinds([str(k) for k in kinds])
        except ModalabError as e:
            raise PlanError(f"{src}: [diagnose] kinds: {e}") from None
    dofs = opts["report"]["frf_dofs"]
    if dofs is not None:
        for d in dofs:
            try:
                Dof.parse(d)
            except ModalabError as e:
                raise PlanError(f"{src}: [report] frf_dofs: {e}") from None
