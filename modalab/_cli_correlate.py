"""``modalab correlate``: test modes against an FE model (MAC, pairing, frequency errors)."""
from __future__ import annotations

from pathlib import Path


def cmd_correlate(a):
    from .cli import _print
    from .stages import CorrelateOptions, correlate

    opts = CorrelateOptions(mac_min=a.mac_min, dofmap=a.map, **({"n_modes": a.n_modes} if a.n_modes else {}))
    r = correlate(a.model, a.modes, opts, json_path=a.json, plots_dir=a.plots)
    _print(r.result.table())
    figs = [str(p) for p in r.files if Path(p).suffix == ".png"]
    if figs:
        _print("figures: " + ", ".join(figs))
    if a.json:
        _print(f"wrote {a.json}")
    return 0


def register(sub):
    s = sub.add_parser("correlate", help="correlate test modes with an FE model (MAC, MSF, COMAC, pairing)")
    s.add_argument("model", help="FE model as Nastran bulk data (.bdf)")
    s.add_argument("modes", help="test modes: UFF dataset 55 or JSON from 'modalab identify'")
    s.add_argument("--map", help="DOF map file (TOML/CSV: test DOF -> model DOF with sign); default same node ids")
    s.add_argument("--mac-min", type=float, default=0.5, help="lowest MAC for a pair (default 0.5)")
    s.add_argument("--n-modes", type=int, help="analysis modes to compute, at least (default 12; never fewer than 2 x test modes + 6)")
    s.add_argument("--plots", help="folder for the MAC matrix, frequency 45-degree plot and COMAC")
    s.add_argument("--json", help="JSON summary")
    s.set_defaults(func=cmd_correlate)
