"""``modalab update``: update an FE model to test modes or FRFs.

Methods: ``eigensensitivity`` (thesis 3.2.2, modes), ``eigendynamic`` (3.2.1, modes), ``mci`` (3.2.4, FRFs),
``rfm`` (3.2.3, FRFs) and the direct methods (3.1, modes; they change the matrices, not parameters):
``direct-lagrange``, ``direct-error-matrix``, ``direct-matrix``, ``direct-mixing``.
"""
from __future__ import annotations

import math

from modalab.app._cli_console import _print
from modalab.core.errors import PlanError
from modalab.app._cli_correlate import correlate_options
from modalab.app.stages import UpdateOptions, update
from modalab.app.stages import UPDATE_METHODS
from modalab.app._cli_correlate import add_map_arguments


def _digits(a: float, b: float, std) -> int:
    """Significant digits that show the change from ``a`` to ``b`` and the standard deviation (5 at least)."""

    scale = max(abs(a), abs(b))
    if scale == 0 or not math.isfinite(scale):
        return 5
    steps = [abs(b - a)] + ([abs(std)] if std else [])
    steps = [x for x in steps if x > 0 and math.isfinite(x)]
    if not steps:
        return 5
    return int(min(12, max(5, math.ceil(math.log10(scale / min(steps))) + 2)))


def parameter_change(initial, updated, std=None) -> str:
    """``1 -> 1.00003 (+0.003 %) ± 2.91e-05``: enough digits that a small change shows."""
    n = _digits(float(initial), float(updated), std)
    rel = "" if initial == 0 else f" ({100 * (updated - initial) / abs(initial):+.3g} %)"
    sd = "" if std is None else f" ± {std:.3g}"
    return f"{initial:.{n}g} -> {updated:.{n}g}{rel}{sd}"


def cmd_update(a):
    if a.max_iter < 1:
        raise PlanError(f"--max-iter {a.max_iter}: expected at least 1 iteration; give e.g. --max-iter 30")

    opts = UpdateOptions(method=a.method, parameters=a.params, max_iter=a.max_iter,
                         bands=[tuple(b) for b in a.band] if a.band else None, freq_sigma=a.freq_sigma,
                         correlation=correlate_options(a))
    s = update(a.model, a.output, opts, modes_path=a.modes, frf_path=a.frf).result
    if s.get("note"):
        _print(s["note"])
    if "table_before" in s:
        _print("before:\n" + s["table_before"])
        _print("after:\n" + s["table_after"])
    if s.get("frequency_weights"):
        _print(f"frequency weights: {s['frequency_weights']}")
    idf = s.get("identifiability")
    for name, v in (s.get("parameters") or {}).items():
        sd = " ± inf (not determined by these data)" if (v["std"] is None and idf
                                                          and name in idf["std_unregularised"]) else ""
        _print(f"{name:>20}: {parameter_change(v['initial'], v['updated'], v['std'])}{sd}")
    if idf:
        for g, c in idf.get("residual_check", {}).items():
            if c["std_factor"] > 1:
                _print(f"the {g} residuals are {c['std_factor']:.3g} times their stated standard deviations "
                       f"(chi2 {c['chi2']:.4g} for {c['dof']:.3g} degrees of freedom): the ± above are raised by that "
                       "factor. Either the stated sigma are too small, or the model leaves out physics that the "
                       "parameters absorb (modalab diagnose); in that case the ± do not bound the parameters' bias")
        un = ", ".join(f"{k} ± {v:.3g}" if v is not None else f"{k} ± inf"
                       for k, v in idf["std_unregularised"].items())
        _print(f"condition number {idf['condition_number']:.3g}; unregularised std: {un}")
        if not idf["identifiable"]:
            _print("WARNING: the parameters are not identifiable from these data (condition number above 1e3): "
                   "some combination of them is poorly determined, and its ± is large")
    _print(f"results in {a.output}")
    return 0


def register(sub):

    s = sub.add_parser("update", help="update an FE model to test modes or FRFs")
    s.add_argument("model", help="FE model as Nastran bulk data (.bdf)")
    g = s.add_mutually_exclusive_group(required=True)
    g.add_argument("--modes", help="test modes (UFF dataset 55 or JSON from 'modalab identify')")
    g.add_argument("--frf", help="measured FRFs (UFF dataset 58) for mci / rfm")
    s.add_argument("--method", default="eigensensitivity", choices=UPDATE_METHODS,
                   help="updating method (default eigensensitivity)")
    s.add_argument("--params", help="TOML file of [[parameter]] entries (default: E and rho multipliers per "
                                    "property group)")

    add_map_arguments(s)
    s.add_argument("--freq-sigma", type=float, nargs="+",
                   help="relative standard deviation of each test frequency, a fraction above 0 and up to 0.5 "
                        "(0.002 = 0.2 %%; one value, or one per mode); default: "
                        "the covariance stored with the modes, else the standard deviations modalab identify "
                        "stored in modes.json (freq_std_hz; for modes.uff, the modes.json of the same identify run "
                        "beside it), else an assumed 1 %%")
    s.add_argument("--band", nargs=2, type=float, action="append", metavar=("LO", "HI"),
                   help="updating band in Hz for mci/rfm (repeatable)")
    s.add_argument("--max-iter", type=int, default=30, help="iteration limit (default 30)")
    s.add_argument("-o", "--output", required=True, help="output folder (updated.bdf, update.json, figures)")
    s.set_defaults(func=cmd_update)
