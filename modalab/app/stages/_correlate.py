"""The correlate stage: test modes against the FE model.

Test DOFs are put on model DOFs by a DOF map (``dofmap``), or by geometry when both the test and the model
carry node coordinates (the test geometry from dataset 2411 in the modes file or a ``geometry`` file: nearest
model node after a best-fit rigid transform, distances reported), or by equal node numbers only when asked
(``same_ids``).  Otherwise the stage refuses: test node numbers are not model grid numbers unless someone
says so.  Pairs follow the one rule of :func:`updating.correlation.metrics.pair_modes` inside the frequency window.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from modalab.core.errors import PlanError
from modalab.app.outputs import write_json
from modalab.app.stages._common import StageResult, load_model, load_modes
from updating.correlation.dofmap import geometry_map
from updating.correlation.metrics import correlate as _correlate
from updating.correlation.plots import plot_frequencies, plot_mac
from modalab.core.uff import read_geometry
from updating.correlation.plots import plot_comac


@dataclass(frozen=True)
class CorrelateOptions:
    """``modalab correlate``: lowest MAC of a pair, weight of the frequency in pairing (None: the pairing
    rule's default, 1 with frequencies), analysis modes (at least this many, and never fewer than 2 × test
    modes + 6, more when needed to cover the test band and its window), how test DOFs go onto model DOFs
    (``dofmap`` file, ``geometry`` UFF file, ``same_ids``; default: the modes file's own geometry) and the
    frequency window (largest relative frequency distance of a pair)."""

    mac_min: float = 0.5
    freq_weight: float | None = None
    n_modes: int = 12
    dofmap: str | None = None
    geometry: str | None = None
    same_ids: bool = False
    freq_window: float | None = 0.35
    ignore_unsupported: bool = False     # build the model without structural cards it cannot model

    def __post_init__(self):
        given = [n for n, v in (("a DOF map", self.dofmap), ("a geometry file", self.geometry),
                                ("same ids", self.same_ids)) if v]
        if len(given) > 1:
            raise PlanError(f"give one of --map, --geometry and --same-ids, not {' and '.join(given)}")
        if self.freq_window is not None and not (np.isfinite(self.freq_window) and self.freq_window > 0):
            raise PlanError(f"--freq-window {self.freq_window}: expected a positive relative distance, e.g. 0.35")


@dataclass(frozen=True)
class DofMapping:
    """How test DOFs go onto model DOFs: ``dofmap`` (for :func:`updating.correlation.dofmap.as_dofmap`), ``description``
    (said in the results) and ``geometry`` (the report of a geometry map, else None)."""

    dofmap: object = None
    description: str = ""
    geometry: dict | None = None


def _geometry_source(path) -> str:
    """Where a file keeps its node coordinates, in words: a UFF's dataset 2411 (or 15), a modes.json's
    ``coordinates``."""
    return "its coordinates" if Path(str(path)).suffix.lower() == ".json" else "dataset 2411"


def resolve_dof_map(model, test, opts: CorrelateOptions = CorrelateOptions(), *,
                    modes_path="the modes file", tol=None) -> DofMapping:
    """The test DOFs on ``model``'s DOFs; see the module docstring."""

    if not test.has_shapes:
        return DofMapping(None, "none (no test shapes)", None)
    if opts.dofmap:
        return DofMapping(opts.dofmap, f"DOF map {opts.dofmap}", None)
    if opts.same_ids:
        return DofMapping(None, "same node ids (--same-ids): test node n is model grid n", None)
    coords = dict(test.coordinates)
    src = f"{modes_path} ({_geometry_source(modes_path)})"
    if opts.geometry:
        coords = read_geometry(opts.geometry)
        src = f"{opts.geometry} ({_geometry_source(opts.geometry)})"
    if not coords:
        raise PlanError(f"{modes_path} carries no node coordinates, so its node numbers cannot be matched with the "
                        "model's grids. Give --geometry FILE (a UFF with the test geometry, dataset 2411: e.g. the "
                        "FRF file), --map MAP.toml (test DOF -> model DOF), or --same-ids if the test nodes are "
                        "numbered like the model grids")
    nodes = sorted({d.node for d in test.dofs})
    model_xyz = {int(n): tuple(node.xyz) for n, node in model.nodes.items()}
    dm, rep = geometry_map(coords, model_xyz, nodes, tol=tol)
    moved = {k: v for k, v in rep["nodes"].items() if int(k) != v["model_node"]}
    how = (f"by geometry from {src}: {len(nodes)} test node{'s' if len(nodes) != 1 else ''} on their nearest "
           "model grid, max distance "
           f"{rep['max_distance_m']:.3g} m (tolerance {rep['tol_m']:.3g} m)")
    if rep["rotation"] != [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]] or any(rep["translation"]):
        how += f", after a rigid transform (translation {[round(v, 6) for v in rep['translation']]} m)"
    if moved:
        how += "; renumbered: " + ", ".join(f"{k}->{v['model_node']}" for k, v in list(moved.items())[:12]) + \
               (" ..." if len(moved) > 12 else "")
    return DofMapping(dm, how, rep)


def analysis_modes_covering(model, test, n, window):
    """The model's modes on every DOF (rigid-link dependents filled in), enough of them to cover the test band
    and its frequency window."""
    an = model.modes(n, full=True)
    top = float(max(test.freq_hz, default=0.0)) * (1 + (window or 0.0))
    n_dof = len(model.system().dofs)
    while an.n_modes and an.freq_hz[-1] < top and n < n_dof - 1:
        n = min(2 * n, n_dof - 1)
        an = model.modes(n, full=True)
    return an


def _n_analysis(opts: CorrelateOptions, test) -> int:
    return max(int(opts.n_modes), 2 * test.n_modes + 6)


def _correlation(model, test, opts: CorrelateOptions, mapping: DofMapping):
    """Correlation on every test DOF (the model's modes on every DOF, rigid-link dependents filled in)."""

    n = _n_analysis(opts, test)
    an = analysis_modes_covering(model, test, n, opts.freq_window) if hasattr(model, "modes") else model
    return _correlate(an, test, dofmap=mapping.dofmap, mac_min=opts.mac_min, freq_weight=opts.freq_weight,
                      max_freq_error=opts.freq_window, n_analysis_modes=n, dof_mapping=mapping.description,
                      geometry=mapping.geometry)


def _correlation_figures(res, d: Path, tag: str, title: str, frequencies: bool = True) -> list:
    """MAC matrix (test sets with shapes only) and the frequency 45° plot."""

    d.mkdir(parents=True, exist_ok=True)
    files = []
    if res.has_shapes:
        files.append(plot_mac(res.mac, d / f"mac_{tag}.png", analysis_freq_hz=res.analysis.freq_hz,
                              test_freq_hz=res.test.freq_hz, pairs=res.pairs, title=f"MAC, {title}"))
    if frequencies:
        ia, jx = res.pairing.analysis_index, res.pairing.test_index
        files.append(plot_frequencies(res.test.freq_hz[jx], res.analysis.freq_hz[ia], d / f"frequencies_{tag}.png",
                                      title=f"Natural frequencies, {title}"))
    return [Path(p) for p in files]


def _freq_err(res):
    return float(np.mean(np.abs(res.freq_error_pct))) if len(res.pairs) else None


def correlate(model_path, modes_path, opts: CorrelateOptions = CorrelateOptions(), *, json_path=None,
              plots_dir=None) -> StageResult:
    """Test modes against the FE model: MAC, pairing, frequency errors (``correlation.json``, MAC and 45° plots)."""
    model, test = load_model(model_path, opts.ignore_unsupported), load_modes(modes_path)
    mapping = resolve_dof_map(model, test, opts, modes_path=modes_path)
    res = _correlation(model, test, opts, mapping)
    files = []
    if json_path is not None:
        files.append(write_json(json_path, res.to_dict()))
    if plots_dir is not None:
        files += _correlation_figures(res, Path(plots_dir), "before", "nominal model")
        if res.pairs and res.has_shapes:
            files.append(Path(plot_comac(res.comac, res.test.dofs, Path(plots_dir) / "comac.png")))
    return StageResult(res, tuple(files), {"pairs": len(res.pairs), "mean_abs_freq_error_pct": _freq_err(res),
                                           "dof_mapping": mapping.description})
