"""``modalab correlate``: test modes against an FE model (MAC, pairing, frequency errors)."""
from __future__ import annotations

import json


def cmd_correlate(a):
    from updating.correlation import correlate
    from updating.correlation_plots import save_correlation_plots

    from .cli import _print
    from .pipeline import load_model, load_modes

    model = load_model(a.model)
    test = load_modes(a.modes)
    n = a.n_modes or max(2 * test.n_modes + 6, 12)
    # modes on every model DOF (rigid-link dependents filled in), so test DOFs on linked nodes correlate too
    res = correlate(model.modes(n, full=True), test, dofmap=a.map, mac_min=a.mac_min, n_analysis_modes=n)
    _print(res.table())
    if a.plots:
        figs = save_correlation_plots(res, a.plots)
        _print("figures: " + ", ".join(str(v) for v in figs.values()))
    if a.json:
        from ._output import write_text

        write_text(a.json, json.dumps(res.to_dict(), indent=1, default=str))
        _print(f"wrote {a.json}")
    return 0


def register(sub):
    s = sub.add_parser("correlate", help="correlate test modes with an FE model (MAC, MSF, COMAC, pairing)")
    s.add_argument("model", help="FE model as Nastran bulk data (.bdf)")
    s.add_argument("modes", help="test modes: UFF dataset 55 or JSON from 'modalab identify'")
    s.add_argument("--map", help="DOF map file (TOML/CSV: test DOF -> model DOF with sign); default same node ids")
    s.add_argument("--mac-min", type=float, default=0.5, help="lowest MAC for a pair (default 0.5)")
    s.add_argument("--n-modes", type=int, help="analysis modes to compute (default 2 x test modes + 6)")
    s.add_argument("--plots", help="folder for MAC matrix, frequency 45-degree plot and COMAC")
    s.add_argument("--json", help="JSON summary")
    s.set_defaults(func=cmd_correlate)
