"""``modalab correlate``: test modes against an FE model (MAC, pairing, frequency errors).

Test DOFs are put on model DOFs by a DOF map (``--map``), or by geometry when both the test
and the model carry node coordinates (the test geometry from dataset 2411 in the modes file or
``--geometry FILE``: nearest model node after a best-fit rigid transform, distances reported),
or by equal node numbers only when asked (``--same-ids``).  Otherwise the command refuses:
test node numbers are not model grid numbers unless someone says so.
"""
from __future__ import annotations

import json
from pathlib import Path


def resolve_dof_map(model, test, *, map_path=None, geometry_path=None, same_ids=False, modes_path="the modes file",
                    tol=None):
    """(dofmap, description, geometry report) for the test DOFs on ``model``; see the module docstring."""
    from updating.dofmap import geometry_map

    from .errors import PlanError

    if not test.has_shapes:
        return None, "none (no test shapes)", None
    given = [n for n, v in (("--map", map_path), ("--geometry", geometry_path), ("--same-ids", same_ids)) if v]
    if len(given) > 1:
        raise PlanError(f"give one of --map, --geometry and --same-ids, not {' and '.join(given)}")
    if map_path:
        return map_path, f"DOF map {map_path}", None
    if same_ids:
        return None, "same node ids (--same-ids): test node n is model grid n", None
    coords = dict(test.coordinates)
    src = f"{modes_path} (dataset 2411)"
    if geometry_path:
        from .uff import read_geometry

        coords = read_geometry(geometry_path)
        src = f"{geometry_path} (dataset 2411)"
    if not coords:
        raise PlanError(f"{modes_path} carries no node coordinates, so its node numbers cannot be matched with the "
                        "model's grids. Give --geometry FILE (a UFF with the test geometry, dataset 2411: e.g. the "
                        "FRF file), --map MAP.toml (test DOF -> model DOF), or --same-ids if the test nodes are "
                        "numbered like the model grids")
    nodes = sorted({d.node for d in test.dofs})
    model_xyz = {int(n): tuple(node.xyz) for n, node in model.nodes.items()}
    dm, rep = geometry_map(coords, model_xyz, nodes, tol=tol)
    moved = {k: v for k, v in rep["nodes"].items() if int(k) != v["model_node"]}
    how = (f"by geometry from {src}: {len(nodes)} test nodes on their nearest model grid, max distance "
           f"{rep['max_distance_m']:.3g} m (tolerance {rep['tol_m']:.3g} m)")
    if rep["rotation"] != [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]] or any(rep["translation"]):
        how += f", after a rigid transform (translation {[round(v, 6) for v in rep['translation']]} m)"
    if moved:
        how += "; renumbered: " + ", ".join(f"{k}->{v['model_node']}" for k, v in list(moved.items())[:12]) + \
               (" ..." if len(moved) > 12 else "")
    return dm, how, rep


def analysis_modes_covering(model, test, n, window):
    """The model's modes on every DOF, enough of them to cover the test band and its frequency window."""
    an = model.modes(n, full=True)
    top = float(max(test.freq_hz, default=0.0)) * (1 + (window or 0.0))
    n_dof = len(model.system().dofs)
    while an.n_modes and an.freq_hz[-1] < top and n < n_dof - 1:
        n = min(2 * n, n_dof - 1)
        an = model.modes(n, full=True)
    return an


def cmd_correlate(a):
    from updating.correlation import correlate
    from updating.correlation_plots import save_correlation_plots

    from .cli import _print
    from .pipeline import load_model, load_modes

    model = load_model(a.model)
    test = load_modes(a.modes)
    dofmap, how, rep = resolve_dof_map(model, test, map_path=a.map, geometry_path=a.geometry, same_ids=a.same_ids,
                                       modes_path=a.modes)
    n = a.n_modes or max(2 * test.n_modes + 6, 12)
    # modes on every model DOF (rigid-link dependents filled in), so test DOFs on linked nodes correlate too
    analysis = analysis_modes_covering(model, test, n, a.freq_window)
    res = correlate(analysis, test, dofmap=dofmap, mac_min=a.mac_min, n_analysis_modes=n,
                    max_freq_error=a.freq_window, dof_mapping=how, geometry=rep)
    _print(res.table())
    if a.plots and res.has_shapes:
        figs = save_correlation_plots(res, a.plots)
        _print("figures: " + ", ".join(str(v) for v in figs.values()))
    if a.json:
        Path(a.json).write_text(json.dumps(res.to_dict(), indent=1, default=str))
        _print(f"wrote {a.json}")
    return 0


def add_map_arguments(s):
    """--map / --geometry / --same-ids / --freq-window, shared by correlate and update."""
    s.add_argument("--map", help="DOF map file (TOML/CSV: test DOF -> model DOF with sign)")
    s.add_argument("--geometry", help="UFF file with the test geometry (dataset 2411), when the modes file has none: "
                                      "test nodes are mapped onto the nearest model grids")
    s.add_argument("--same-ids", action="store_true",
                   help="test node n is model grid n (only when you know the numbering is shared)")
    s.add_argument("--freq-window", type=float, default=0.35,
                   help="largest relative frequency distance of a pair (default 0.35 = ±35 %%)")


def register(sub):
    s = sub.add_parser("correlate", help="correlate test modes with an FE model (MAC, MSF, COMAC, pairing)")
    s.add_argument("model", help="FE model as Nastran bulk data (.bdf)")
    s.add_argument("modes", help="test modes: UFF dataset 55 or JSON from 'modalab identify'")
    add_map_arguments(s)
    s.add_argument("--mac-min", type=float, default=0.5, help="lowest MAC for a pair (default 0.5)")
    s.add_argument("--n-modes", type=int, help="analysis modes to compute (default 2 x test modes + 6)")
    s.add_argument("--plots", help="folder for MAC matrix, frequency 45-degree plot and COMAC")
    s.add_argument("--json", help="JSON summary")
    s.set_defaults(func=cmd_correlate)
