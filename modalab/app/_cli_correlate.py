"""``modalab correlate``: test modes against an FE model (MAC, pairing, frequency errors).

Test DOFs are put on model DOFs by a DOF map (``--map``), or by geometry when both the test
and the model carry node coordinates (the test geometry from dataset 2411 in the modes file or
``--geometry FILE``), or by equal node numbers only when asked (``--same-ids``); otherwise the
command refuses (:func:`modalab.app.stages.resolve_dof_map`).
"""
from __future__ import annotations

from pathlib import Path
from modalab.app.stages import CorrelateOptions
from modalab.app._cli_console import _print
from modalab.app.stages import correlate
from modalab.core.errors import PlanError


def correlate_options(a, **kw):
    """The :class:`~modalab.app.stages.CorrelateOptions` of parsed ``correlate``/``update`` arguments."""

    if not 0 < a.freq_window < 1:
        raise PlanError(f"--freq-window {a.freq_window:g}: expected the largest relative frequency distance of a "
                        "pair as a fraction between 0 and 1 (0.35 = ±35 %); give e.g. --freq-window "
                        f"{a.freq_window / 100:g} for ±{a.freq_window:g} %" if 1 <= a.freq_window < 1e4 else
                        f"--freq-window {a.freq_window:g}: expected a fraction between 0 and 1 (0.35 = ±35 %); "
                        "give e.g. --freq-window 0.35")
    return CorrelateOptions(dofmap=a.map, geometry=a.geometry, same_ids=a.same_ids, freq_window=a.freq_window,
                            ignore_unsupported=a.ignore_unsupported, **kw)


def cmd_correlate(a):

    if not 0 <= a.mac_min <= 1:
        raise PlanError(f"--mac-min {a.mac_min:g}: expected the lowest MAC of a pair, from 0 to 1; give e.g. "
                        "--mac-min 0.5")
    if a.n_modes is not None and a.n_modes < 1:
        raise PlanError(f"--n-modes {a.n_modes}: expected a positive number of analysis modes; give e.g. --n-modes 30 "
                        "(or leave it out)")
    opts = correlate_options(a, mac_min=a.mac_min, **({"n_modes": a.n_modes} if a.n_modes else {}))
    r = correlate(a.model, a.modes, opts, json_path=a.json, plots_dir=a.plots)
    _print(r.result.table())
    figs = [str(p) for p in r.files if Path(p).suffix == ".png"]
    if figs:
        _print("figures: " + ", ".join(figs))
    if a.json:
        _print(f"wrote {a.json}")
    return 0


def add_map_arguments(s):
    """--map / --geometry / --same-ids / --freq-window, shared by correlate and update."""
    s.add_argument("--map", help="DOF map file (TOML/CSV: test DOF -> model DOF with sign)")
    s.add_argument("--geometry", help="UFF file with the test geometry (dataset 2411), when the modes file has none: "
                                      "test nodes are mapped onto the nearest model grids")
    s.add_argument("--same-ids", action="store_true",
                   help="test node n is model grid n (only when you know the numbering is shared)")
    s.add_argument("--ignore-unsupported", action="store_true",
                   help="build the model without the structural cards modalab does not model (e.g. CTRIA6); "
                        "by default they are an error, since the model would be a different structure; also "
                        "keeps, unmodelled, a card whose name looks like a typo of a known card (e.g. CBAT)")
    s.add_argument("--freq-window", type=float, default=0.35,
                   help="largest relative frequency distance of a pair (default 0.35 = ±35 %%)")


def register(sub):
    s = sub.add_parser("correlate", help="correlate test modes with an FE model (MAC, MSF, COMAC, pairing)")
    s.add_argument("model", help="FE model as Nastran bulk data (.bdf)")
    s.add_argument("modes", help="test modes: UFF dataset 55 or JSON from 'modalab identify'")
    add_map_arguments(s)
    s.add_argument("--mac-min", type=float, default=0.5, help="lowest MAC for a pair (default 0.5)")
    s.add_argument("--n-modes", type=int, help="analysis modes to compute, at least (default 12; never fewer than "
                                               "2 x test modes + 6, more to cover the test band and its window)")
    s.add_argument("--plots", help="folder for the MAC matrix, frequency 45-degree plot and COMAC")
    s.add_argument("--json", help="JSON summary")
    s.set_defaults(func=cmd_correlate)
