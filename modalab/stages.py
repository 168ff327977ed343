"""The stages of modalab, one function each: ``modalab <verb>``, ``modalab run`` and campaigns all call these.

=============  =====================================  ============================================================
stage          function                               writes
=============  =====================================  ============================================================
sim            :func:`sim` (:class:`SimOptions`)      raw hits (UFF 58), ``first_hit.png``; ``model.bdf`` and
                                                      ``params.toml`` of the structure with ``export_model``
frf            :func:`frf` (:class:`FRFOptions`)      FRFs + coherence (UFF 58), figure; with ``details_dir``:
                                                      ``frf.json``, ``reciprocity.json``, ``coherence.png``
identify       :func:`identify` (:class:`IdentifyOptions`)  modes (UFF 55), ``modes.json``, ``identification.json``,
                                                      stabilisation diagram, synthesis, AutoMAC
correlate      :func:`correlate` (:class:`CorrelateOptions`)  ``correlation.json``, ``mac_before.png``,
                                                      ``frequencies_before.png``, ``comac.png``
update         :func:`update` (:class:`UpdateOptions`)  ``updated.bdf`` (or ``updated_matrices.npz``),
                                                      ``update.json``, MAC/frequency plots, ``convergence.png``
diagnose       :func:`diagnose` (:class:`DiagnoseOptions`)  ``diagnosis.json``; with ``out_dir``: MCI maps,
                                                      figures, ``diagnosed.bdf``, ``frf_overlay.png``
report         :func:`report`                         ``report.html``, ``summary.json``
=============  =====================================  ============================================================

Each function takes its input files, its output locations and one frozen options dataclass, and returns a
:class:`StageResult`: the product (an FRF, a ModeSet, a correlation, a summary dict, a Diagnosis), the files it
wrote and a short JSON-ready summary.  Every text/JSON file goes through :mod:`modalab.outputs` (one writer,
umask permissions, atomic replace); ``modes.json``, ``diagnosis.json`` and ``summary.json`` follow the schemas
shipped in ``modalab/schemas``.  Library code logs; ``progress`` callables let the CLI show progress.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from .errors import ModalabValueError, PlanError
from .outputs import write_json, write_text

log = logging.getLogger(__name__)

__all__ = ["StageResult", "SimOptions", "FRFOptions", "IdentifyOptions", "CorrelateOptions", "UpdateOptions",
           "DiagnoseOptions", "sim", "frf", "identify", "correlate", "update", "diagnose", "report",
           "load_model", "load_modes", "load_parameters", "mode_table", "UPDATE_METHODS"]


@dataclass(frozen=True)
class StageResult:
    """What a stage produced: ``result`` (the product), ``files`` (written, in order) and ``summary``."""

    result: object
    files: tuple = ()
    summary: dict = field(default_factory=dict)


def _tuple(x):
    return None if x is None else tuple(x)


# ============================================================================ shared inputs
def load_model(path):
    """An FE model from Nastran bulk data (``.bdf``, ``.dat``, ``.nas``, ``.blk``)."""
    from updating.bulk import build_model, read_bdf

    p = Path(path)
    if not p.is_file():
        raise PlanError(f"model file {str(p)!r} does not exist; give a Nastran bulk-data file (.bdf)")
    return build_model(read_bdf(p))


def load_modes(path):
    """Test modes from a UFF (dataset 55) or a ``modes.json`` written by ``modalab identify``."""
    from .modes import ModeSet

    p = Path(path)
    if p.suffix.lower() == ".json":
        return ModeSet.from_json(p)
    return ModeSet.from_uff(p)


def load_parameters(path, model) -> tuple[list, np.ndarray, np.ndarray]:
    """Updating parameters and their bounds: the TOML ``[[parameter]]`` file, or (``path`` None) the default
    E and density multipliers per property group without bounds."""
    if path is None:
        from updating.diagnosis.workflow import default_parameters

        params = default_parameters(model)
        return params, np.full(len(params), -np.inf), np.full(len(params), np.inf)
    from .project import load_parameters as _load

    params, lo, hi = _load(path)
    return (params, np.array([-np.inf if v is None else float(v) for v in lo]),
            np.array([np.inf if v is None else float(v) for v in hi]))


# ============================================================================ sim
@dataclass(frozen=True)
class SimOptions:
    """``modalab sim``: the structure ('demo' or a bulk-data file), hammer points, fixed accelerometers, hits
    per point, random seed, peak force (N), double-hit probability, sampling rate (Hz), samples per record."""

    structure: str = "demo"
    points: tuple | None = None
    references: tuple | None = None
    hits: int = 3
    seed: int = 1
    force_n: float | None = None
    double_hit_probability: float = 0.0
    sample_rate_hz: float | None = None
    n_samples: int | None = None

    def __post_init__(self):
        object.__setattr__(self, "points", _tuple(self.points))
        object.__setattr__(self, "references", _tuple(self.references))


def _sim_structure(structure):
    """The structure to simulate: the demo grillage, or the FE model of a bulk-data file; and that model."""
    from hardware_sim import demo as hdemo

    if structure in (None, "demo"):
        return hdemo.demo_structure(), None
    path = Path(structure)
    if path.suffix.lower() in (".bdf", ".dat", ".nas", ".blk"):
        model = load_model(path)
        return model.structure(), model
    raise PlanError(f"structure {structure!r}: expected 'demo' or a Nastran bulk-data file (.bdf/.dat)")


def demo_fe_model():
    """The demo aeroplane cross (:mod:`hardware_sim.demo`) as an FE model for bulk data: the same grillage of
    aluminium bars as 3-D beams (CBAR/PBAR, out-of-plane bending and torsion; in-plane DOFs held by SPC),
    the four bungees as springs to ground and the structural damping as PARAM G = 0.01."""
    from hardware_sim.demo import _demo_geometry
    from updating.fe import Beam3D, BeamProperty, FEModel, GeneralSection, Material, Spring

    coords, members, springs = _demo_geometry()
    m = FEModel("modalab demo aeroplane", coupled_mass=True, global_ge=0.01)
    for n, xyz in sorted(coords.items()):
        m.add_node(n, tuple(float(v) for v in xyz))
        m.add_spc(n, "126")
    sections = {}
    for eid, (a, b, sec) in enumerate(members, start=1):
        if id(sec) not in sections:
            pid = len(sections) + 1
            m.add_material(Material(pid, E=sec.E, G=sec.G, nu=sec.E / (2 * sec.G) - 1, rho=sec.rho))
            # v = Z: local y (plane 1) is global Z, so out-of-plane bending uses I1 = Iz; in-plane Iy = Ip - I
            m.add_property(BeamProperty(pid, pid, GeneralSection(A=sec.A, Iy=sec.Ip - sec.I, Iz=sec.I, J=sec.J),
                                        name="fuselage" if pid == 1 else "wing"))
            sections[id(sec)] = pid
        m.add_element(Beam3D(eid, a, b, sections[id(sec)], orientation=(0.0, 0.0, 1.0)))
    for k, (n, kz) in enumerate(sorted(springs.items()), start=100):
        m.add_element(Spring(k, a=(n, 3), b=None, k=float(kz), group="bungee"))
    return m


def _export_model(folder: Path, model) -> list:
    """``model.bdf`` and ``params.toml`` (E and density multipliers per property, bounded 0.5-2) in ``folder``."""
    from updating.bulk import to_bulk, write_bdf
    from updating.diagnosis.workflow import default_parameters

    folder.mkdir(parents=True, exist_ok=True)
    bdf = write_text(folder / "model.bdf", "$ " + (model.name or "modalab model") + " (modalab sim --export-model)\n"
                     + write_bdf(to_bulk(model)))
    lines = ["# Updating parameters of model.bdf: multipliers of the nominal values (1 = nominal)."]
    for p in default_parameters(model):
        sel = ", ".join(f'"{s}"' if isinstance(s, str) else str(s) for s in p.properties)
        lines += ["", "[[parameter]]", f'name = "{p.name}"', f'field = "{p.field}"', f"properties = [{sel}]",
                  "lower = 0.5", "upper = 2.0"]
    toml = write_text(folder / "params.toml", "\n".join(lines) + "\n")
    return [bdf, toml]


def sim(out_uff, opts: SimOptions = SimOptions(), *, plot_dir=None, export_model=None,
        progress: Callable | None = None) -> StageResult:
    """Simulate a roving-hammer test and write its raw hits (UFF 58 time records, one per channel per hit).

    plot_dir : folder for ``first_hit.png`` (None: no figure).
    export_model : folder for ``model.bdf`` and ``params.toml`` of the simulated structure (the demo
        structure's FE model, :func:`demo_fe_model`, or the given bulk data), ready for correlate/update/diagnose.
    progress : callable ``(points done, points in all, point)``.
    """
    from hardware_sim.demo import DEMO_POINTS, DEMO_REFERENCES, demo_channels, demo_setup
    from hardware_sim.lab import SimulatedLab, simulate_roving_test
    from hardware_sim.setup import FaultConfig

    from . import uff

    st, model = _sim_structure(opts.structure)
    pts = list(opts.points or DEMO_POINTS)
    refs = list(opts.references or DEMO_REFERENCES)
    setup_kw = {}
    if opts.sample_rate_hz:
        setup_kw["sample_rate_hz"] = float(opts.sample_rate_hz)
    if opts.n_samples:
        setup_kw["n_samples"] = int(opts.n_samples)
    p2 = opts.double_hit_probability
    faults = FaultConfig(double_hit_probability=p2) if p2 else None
    lab = SimulatedLab(st, demo_channels(pts[0], refs), demo_setup(**setup_kw), faults=faults,
                       rng=np.random.default_rng(opts.seed))
    lab.prepare(pts)                       # exact FRF columns of every point in one batch
    recs = []
    for k, pt in enumerate(pts):           # point by point (the same random stream as one call) for progress
        recs += simulate_roving_test(lab, [pt], hits_per_point=opts.hits, force_n=opts.force_n)
        if progress:
            progress(k + 1, len(pts), pt)
    for i, r in enumerate(recs, start=1):
        r.hit_id = i
    out = Path(out_uff)
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.exists():
        out.unlink()
    if getattr(st, "coords", None):
        uff.write_geometry(out, st.coords)
        uff.write_records(out, recs, append=True)
    else:
        uff.write_records(out, recs)
    files = [out]
    if plot_dir is not None:
        from .plots import plot_hit

        plot_hit(recs[0], path=Path(plot_dir) / "first_hit.png", title=f"hit 1 at {recs[0].force_dofs[0]}")
        files.append(Path(plot_dir) / "first_hit.png")
    if export_model is not None:
        files += _export_model(Path(export_model), demo_fe_model() if model is None else model)
    return StageResult(recs, tuple(files), {"hits": len(recs) // max(len(pts), 1), "points": len(pts),
                                            "channels": recs[0].n_channels})


# ============================================================================ frf
@dataclass(frozen=True)
class FRFOptions:
    """``modalab frf``: estimator (H1, H2, Hv), force window (fraction of the record after the trigger; 0 or None
    = off), exponential window (level at the record end, or decay rate beta in 1/s), reciprocity reordering of
    roving-hammer data, highest line kept (Hz; default fs/2.56)."""

    estimator: str = "H1"
    force_fraction: float | None = 0.05
    exp_end_level: float | None = None
    exp_beta: float | None = None
    reciprocity: bool = True
    bandwidth_hz: float | None = None


def _geometry(path) -> dict:
    from . import uff

    try:
        return dict(uff.read_geometry(path))
    except Exception:  # noqa: BLE001 - a file without geometry is fine
        return {}


def frf(in_uff, out_uff, opts: FRFOptions = FRFOptions(), *, plot_path=None, details_dir=None, exact=None,
        measured: bool = False) -> StageResult:
    """Raw hits in a UFF → H1 (H2, Hv) FRFs + coherence in a UFF; roving-hammer data reordered by reciprocity.

    measured : ``in_uff`` holds FRFs already (a project's measured FRFs): they are copied, with the geometry.
    plot_path : the FRF figure (``exact``: an exact FRF drawn over it).
    details_dir : also write ``frf.json`` (summary), ``reciprocity.json`` and ``coherence.png`` there.
    """
    from . import uff

    out = Path(out_uff)
    if measured:
        H = uff.read_frf(in_uff)
    else:
        H = _estimate(in_uff, opts)
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.exists():
        out.unlink()
    geometry = _geometry(in_uff)
    if geometry:
        uff.write_geometry(out, geometry)
    uff.write_frf(out, H, append=bool(geometry))
    files = [out]
    if plot_path is not None:
        from .plots import plot_frf

        plot_frf(H, path=plot_path, others={"exact": exact} if exact is not None else None,
                 title=f"{H.metadata.get('estimator', opts.estimator)} FRFs")
        files.append(Path(plot_path))
    coh = H.coherence
    summary = {"responses": len(H.responses), "references": [str(r) for r in H.references], "lines": int(H.n_freq),
               "band_hz": [float(H.freq_hz[0]), float(H.freq_hz[-1])],
               "median_coherence": float(np.nanmedian(coh)) if coh is not None else None}
    if details_dir is not None:
        from acquisition.reciprocity import reciprocity_check

        from .report import plot_coherence_map

        d = Path(details_dir)
        try:
            rep = reciprocity_check(H)
            rec = {"max_rel_diff": float(rep.max_rel_diff), **rep.to_dict()}
        except ModalabValueError as e:       # no reciprocal pair measured: said, not scored
            rec = {"note": str(e)}
        summary["reciprocity_max_rel_diff"] = rec.get("max_rel_diff")
        files += [write_json(d / "reciprocity.json", rec), plot_coherence_map(H, d / "coherence.png"),
                  write_json(d / "frf.json", summary)]
    return StageResult(H, tuple(files), summary)


def _estimate(in_uff, opts: FRFOptions):
    from acquisition.reciprocity import reorder_by_reciprocity
    from acquisition.spectral import estimate_frf_roving
    from acquisition.windows import ExponentialWindow, ForceWindow

    from . import uff

    recs = uff.read_records(in_uff)
    if not recs:
        raise ModalabValueError(f"{in_uff}: no time records (dataset 58, function type 1) to turn into FRFs; "
                                "run 'modalab info' to see what the file holds")
    fw = ForceWindow(fraction=opts.force_fraction) if opts.force_fraction else None
    ew = None
    if opts.exp_beta:
        ew = ExponentialWindow(beta=opts.exp_beta)
    elif opts.exp_end_level:
        ew = ExponentialWindow(end_level=opts.exp_end_level)
    H = estimate_frf_roving(recs, estimator=opts.estimator, force_window=fw, exp_window=ew)
    H = H.band(0.0, opts.bandwidth_hz or recs[0].sample_rate_hz / 2.56)
    if opts.reciprocity and len(H.references) > len(H.responses):
        H = reorder_by_reciprocity(H)
    return H


# ============================================================================ identify
@dataclass(frozen=True)
class IdentifyOptions:
    """``modalab identify``: band (Hz; default all lines above 0 Hz), highest model order, pole selection
    ('auto', a selection file, or frequencies in Hz), references to use, frequency weighting."""

    band_hz: tuple | None = None
    max_order: int | None = None
    select: object = "auto"
    references: tuple | None = None
    weighting: str | None = None

    def __post_init__(self):
        object.__setattr__(self, "band_hz", _tuple(self.band_hz))
        object.__setattr__(self, "references", _tuple(self.references))
        if isinstance(self.select, list):
            object.__setattr__(self, "select", tuple(self.select))


def _band(H, band):
    if band:
        return H.band(float(band[0]), float(band[1]))
    f = H.freq_hz
    return H.band(float(f[f > 0][0]), float(f[-1]))


def mode_table(modes) -> list:
    """One row per mode: ``mode``, ``freq_hz``, ``damping_pct`` and every scalar indicator."""
    rows = []
    ind = getattr(modes, "indicators", None) or {}
    for k in range(modes.n_modes):
        r = {"mode": k + 1, "freq_hz": float(modes.freq_hz[k]),
             "damping_pct": 100 * float(modes.damping[k]) if modes.damping is not None else None}
        for name, v in ind.items():
            try:
                r[name] = float(np.asarray(v)[k])
            except (TypeError, ValueError, IndexError):
                pass
        rows.append(r)
    return rows


def identify(frf_path, out_uff, opts: IdentifyOptions = IdentifyOptions(), *, json_path=None, plots_dir=None,
             report_path=None) -> StageResult:
    """FRFs in a UFF → modes (UFF 55) by poly-reference PolyMAX (:func:`identification.identify`).

    json_path : ``modes.json`` (schema ``modalab/schemas/modes.schema.json``).
    plots_dir : stabilisation diagram, synthesis and AutoMAC figures.
    report_path : ``identification.json`` (settings, stabilisation, timings).
    """
    from identification import identify as _identify

    from . import uff

    H = _band(uff.read_frf(frf_path), opts.band_hz)
    sel = list(opts.select) if isinstance(opts.select, tuple) else opts.select
    modes, rep = _identify(H, max_order=opts.max_order, select=sel,
                           references=list(opts.references) if opts.references else None,
                           weighting=opts.weighting, plots_dir=plots_dir)
    if modes.n_modes == 0:
        raise ModalabValueError(f"{frf_path}: identification found no modes in "
                                f"{H.freq_hz[0]:g}-{H.freq_hz[-1]:g} Hz; widen the band or raise the model order")
    out = Path(out_uff)
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.exists():
        out.unlink()
    uff.write_modes(out, modes)
    files = [out]
    table = mode_table(modes)
    if json_path is not None:
        files.append(write_json(json_path, {"input": str(frf_path), "table": table, **modes.to_dict()}))
    if report_path is not None:
        files.append(write_json(report_path, rep.to_dict()))
    files += [Path(p) for p in rep.figures.values()]
    return StageResult((modes, rep), tuple(files),
                       {"modes": modes.n_modes, "freq_hz": [round(float(f), 3) for f in modes.freq_hz]})


# ============================================================================ correlate
@dataclass(frozen=True)
class CorrelateOptions:
    """``modalab correlate``: lowest MAC of a pair, weight of the frequency in pairing, analysis modes (at least
    this many, and never fewer than 2 × test modes + 6), DOF map file."""

    mac_min: float = 0.5
    freq_weight: float = 0.0
    n_modes: int = 12
    dofmap: str | None = None


def _correlation(model, test, opts: CorrelateOptions):
    """Correlation on every test DOF (the model's modes on every DOF, rigid-link dependents filled in)."""
    from updating.correlation import correlate as _correlate

    n = max(int(opts.n_modes), 2 * test.n_modes + 6)
    an = model.modes(n, full=True) if hasattr(model, "modes") else model
    return _correlate(an, test, dofmap=opts.dofmap, mac_min=opts.mac_min, freq_weight=opts.freq_weight,
                      n_analysis_modes=n)


def _correlation_figures(res, d: Path, tag: str, title: str, frequencies: bool = True) -> list:
    from updating.correlation_plots import plot_frequencies, plot_mac

    d.mkdir(parents=True, exist_ok=True)
    files = [plot_mac(res.mac, d / f"mac_{tag}.png", analysis_freq_hz=res.analysis.freq_hz,
                      test_freq_hz=res.test.freq_hz, pairs=res.pairs, title=f"MAC, {title}")]
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
    res = _correlation(load_model(model_path), load_modes(modes_path), opts)
    files = []
    if json_path is not None:
        files.append(write_json(json_path, res.to_dict()))
    if plots_dir is not None:
        from updating.correlation_plots import plot_comac

        files += _correlation_figures(res, Path(plots_dir), "before", "nominal model")
        if res.pairs:
            files.append(Path(plot_comac(res.comac, res.test.dofs, Path(plots_dir) / "comac.png")))
    return StageResult(res, tuple(files), {"pairs": len(res.pairs), "mean_abs_freq_error_pct": _freq_err(res)})


# ============================================================================ update
MODAL_METHODS = ("eigensensitivity", "eigendynamic")
FRF_METHODS = ("mci", "rfm")
DIRECT_METHODS = ("direct-lagrange", "direct-error-matrix", "direct-matrix", "direct-mixing")
UPDATE_METHODS = MODAL_METHODS + FRF_METHODS + DIRECT_METHODS


@dataclass(frozen=True)
class UpdateOptions:
    """``modalab update``: method (:data:`UPDATE_METHODS`), parameter file (default E and density per property),
    iteration limit, and for eigensensitivity the regularisation ('lcurve', 'gcv' or a number), use of mode
    shapes, relative frequency and shape standard deviations; bands (Hz) for mci/rfm; correlation options."""

    method: str = "eigensensitivity"
    parameters: str | None = None
    max_iter: int = 30
    regularisation: object = "lcurve"
    use_shapes: bool = True
    freq_sigma: float = 0.01
    shape_sigma: float = 0.05
    bands: tuple | None = None
    correlation: CorrelateOptions = CorrelateOptions()

    def __post_init__(self):
        if self.method not in UPDATE_METHODS:
            raise PlanError(f"updating method {self.method!r}; expected one of {', '.join(UPDATE_METHODS)}")
        if self.bands is not None:
            object.__setattr__(self, "bands", tuple(tuple(float(x) for x in b) for b in self.bands))


def _on_model_dofs(modes, dofs, dofmap):
    """Test modes restricted to DOFs the updater can see (independent DOFs of the constrained model)."""
    if dofmap is not None:
        return modes
    keep = [d for d in modes.dofs if any(d.same_axis(m) for m in dofs)]
    if len(keep) < len(modes.dofs):
        log.warning("%d test DOF(s) lie on dependent or constrained model DOFs and are left out of the updating "
                    "(kept in the correlation): %s", len(modes.dofs) - len(keep),
                    ", ".join(str(d) for d in modes.dofs if d not in keep))
    return modes.select_dofs(keep)


def update(model_path, out_dir, opts: UpdateOptions = UpdateOptions(), *, modes_path=None,
           frf_path=None) -> StageResult:
    """Update the FE model to test modes (eigensensitivity, eigendynamic, direct methods) or FRFs (mci, rfm).

    Writes into ``out_dir``: ``updated.bdf`` (the user's deck with the updated values; direct methods change
    matrices, not parameters: ``updated_matrices.npz``), ``update.json`` (parameters with initial, updated and
    std, convergence history, correlation before and after), ``mac_before/after.png``,
    ``frequencies_after.png`` and ``convergence.png``.
    """
    from updating.bulk import read_bdf, to_bulk, write_bdf
    from updating.fe import ParametricFEModel

    from .report import plot_convergence

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    method = opts.method
    model = load_model(model_path)
    test = load_modes(modes_path) if modes_path else None
    if method in MODAL_METHODS + DIRECT_METHODS and test is None:
        raise PlanError(f"method {method!r} needs test modes: pass --modes MODES.uff")
    if method in FRF_METHODS and frf_path is None:
        raise PlanError(f"method {method!r} needs measured FRFs: pass --frf FRF.uff")
    co = opts.correlation
    summary: dict = {"model": str(model_path), "method": method}
    files = []
    before = _correlation(model, test, co) if test is not None else None
    if method in DIRECT_METHODS:
        after = _update_direct(model, test, method, co, out, summary)
        files.append(out / "updated_matrices.npz")
    else:
        params, lo, hi = load_parameters(opts.parameters, model)
        pm = ParametricFEModel(model, params)
        up = _fit_parameters(pm, opts, lo, hi, test, frf_path)
        p = np.asarray(up.p_, float)
        std = np.full(p.size, np.nan)
        if getattr(up, "std_", None) is not None and np.size(up.std_) == p.size:
            std = np.asarray(up.std_, float)
        elif getattr(up, "covariance_", None) is not None and np.size(up.covariance_):
            idx = np.atleast_1d(getattr(up, "params_", np.arange(p.size)))
            std[idx] = np.sqrt(np.clip(np.diag(np.atleast_2d(up.covariance_)), 0, None))
        names = list(pm.parameter_names)
        hist = [h for h in (getattr(up, "history_", None) or []) if "p" in h]
        summary["parameters"] = {n: {"initial": float(pm.p0[k]), "updated": float(p[k]),
                                     "std": float(std[k]) if np.isfinite(std[k]) else None,
                                     "mode": params[k].mode} for k, n in enumerate(names)}
        summary["converged"] = bool(getattr(up, "converged_", True))
        summary["iterations"] = int(getattr(up, "n_iter_", 0) or 0)
        summary["history"] = [{k: v for k, v in h.items() if k in ("iteration", "p", "cost", "freq_error_pct")}
                              for h in hist]
        rows = np.vstack([np.asarray(pm.p0, float)[None, :]] + [np.asarray(h["p"], float)[None, :] for h in hist])
        files.append(plot_convergence(rows, names, out / "convergence.png"))
        updated = pm.model_at(p)
        files.append(write_text(out / "updated.bdf", write_bdf(to_bulk(updated, template=read_bdf(model_path)))))
        summary["updated_model"] = str(out / "updated.bdf")
        after = _correlation(updated, test, co) if test is not None else None
    if before is not None:
        summary["correlation_before"] = before.to_dict()
        summary["correlation_after"] = after.to_dict()
        summary["table_before"] = before.table()
        summary["table_after"] = after.table()
        files += _correlation_figures(before, out, "before", "model before updating", frequencies=False)
        files += _correlation_figures(after, out, "after", "updated model")
    files.insert(0, write_json(out / "update.json", summary))
    short = {"parameters": {n: round(v["updated"], 4) for n, v in summary.get("parameters", {}).items()},
             "mean_abs_freq_error_pct": _freq_err(after) if before is not None else None}
    return StageResult(summary, tuple(files), short)


def _fit_parameters(pm, opts: UpdateOptions, lo, hi, test, frf_path):
    dofmap = opts.correlation.dofmap
    if opts.method == "eigensensitivity":
        from updating.eigensensitivity import InverseEigensensitivity

        est = InverseEigensensitivity(max_iter=opts.max_iter, regularisation=opts.regularisation,
                                      use_shapes=opts.use_shapes, freq_sigma=opts.freq_sigma,
                                      shape_sigma=opts.shape_sigma, bounds=(lo, hi), mac_min=opts.correlation.mac_min)
        return est.fit(pm, _on_model_dofs(test, pm.dofs, dofmap), dofmap=dofmap)
    if opts.method == "eigendynamic":
        from updating.eigendynamic import EigendynamicConstraint

        return EigendynamicConstraint().fit(pm, _on_model_dofs(test, pm.dofs, dofmap), dofmap=dofmap)
    from .frf import FRF

    measured = FRF.from_uff(frf_path)
    bands = [tuple(b) for b in opts.bands] if opts.bands else None
    if opts.method == "mci":
        from updating.mci import MCIUpdater

        return MCIUpdater(bands=bands, max_iter=opts.max_iter).fit(pm, measured)
    from updating.rfm import ResponseFunctionMethod

    return ResponseFunctionMethod(bands=bands, max_iter=opts.max_iter).fit(pm, measured)


def _update_direct(model, test, method, co: CorrelateOptions, out: Path, summary: dict):
    from updating import direct as dm
    from updating.correlation import correlate as _correlate

    from .structure import Structure

    st = model.structure()
    if all(any(d.same_axis(m) for m in test.dofs) for d in st.dofs):
        phi_x = test.select_dofs(st.dofs).real_shapes
    else:
        from updating.expansion import kidder

        phi_x = kidder(st, _on_model_dofs(test, st.dofs, co.dofmap), dofmap=co.dofmap).real_shapes
    K, M = st.K.toarray(), st.M.toarray()
    w_x = test.omega
    w_a, phi_a = st.normal_modes(test.n_modes)
    fn = {"direct-lagrange": lambda: dm.lagrange_mass_stiffness(K, M, phi_x, w_x),
          "direct-error-matrix": lambda: dm.error_matrix(K, M, phi_a, w_a, phi_x, w_x),
          "direct-matrix": lambda: dm.direct_matrix_updating(K, M, phi_x, w_x),
          "direct-mixing": lambda: dm.matrix_mixing(K, M, phi_a, w_a, phi_x, w_x)}[method]
    res = fn()
    np.savez(out / "updated_matrices.npz", K=res.K, M=res.M, dK=res.dK, dM=res.dM,
             dofs=np.array([str(d) for d in st.dofs]))
    summary.update({"equations": res.equations, "matrices": str(out / "updated_matrices.npz")})
    n = max(int(co.n_modes), 2 * test.n_modes + 6)
    return _correlate(Structure(M=res.M, K=res.K, dofs=st.dofs), _on_model_dofs(test, st.dofs, co.dofmap),
                      n_analysis_modes=n, mac_min=co.mac_min)


# ============================================================================ diagnose
@dataclass(frozen=True)
class DiagnoseOptions:
    """``modalab diagnose``: parameter file (default E and density per property), band (Hz), and the engine's
    settings (None: the engine's default): lines used, findings at most, function evaluations per fit,
    held-out DOFs, candidate kinds, criterion ('auto', 'mci', 'frf'); ``overlay_dofs``: response DOFs of the
    FRF overlay figure (default the first four)."""

    parameters: str | None = None
    band_hz: tuple | None = None
    max_lines: int | None = None
    max_findings: int | None = None
    max_nfev: int | None = None
    holdout: str | None = None
    kinds: tuple | None = None
    criterion: str = "auto"
    overlay_dofs: tuple | None = None

    def __post_init__(self):
        for k in ("band_hz", "kinds", "overlay_dofs"):
            object.__setattr__(self, k, _tuple(getattr(self, k)))


def diagnose(model_path, *, frf_path=None, modes_path=None, opts: DiagnoseOptions = DiagnoseOptions(),
             json_path=None, out_dir=None, updated_model=None, progress: Callable | None = None) -> StageResult:
    """Locate what the FE model leaves out, name the physics, model it, prove it on held-out FRF rows.

    From measured FRFs (``frf_path``; the identified ``modes_path`` then give the frequency and MAC columns of
    the fit), or from identified modes alone (a GVT). ``json_path``: ``diagnosis.json`` (schema
    ``modalab/schemas/diagnosis.schema.json``). ``out_dir``: ``diagnosis.json`` there too, the MCI maps, the engine's figures (``figures/``), ``diagnosed.bdf`` (the augmented, updated model) and
    ``frf_overlay.png`` (measured, nominal, diagnosed and, given ``updated_model``, the parameter-updated model).
    """
    from updating.diagnosis import diagnose as _diagnose
    from updating.diagnosis import diagnose_modes

    if frf_path is None and modes_path is None:
        raise PlanError("give measured FRFs (MEASURED.uff) or --modes MODES.uff (a GVT's modes alone)")
    model = load_model(model_path)
    params = load_parameters(opts.parameters, model)[0] if opts.parameters else None
    test_modes = load_modes(modes_path) if modes_path else None
    H = None
    if frf_path is None:
        kw = {k: getattr(opts, k) for k in ("max_findings",) if getattr(opts, k) is not None}
        if opts.kinds:
            kw["kinds"] = list(opts.kinds)
        diag = diagnose_modes(model, test_modes, parameters=params, progress=progress, **kw)
    else:
        from . import uff

        H = _band(uff.read_frf(frf_path), opts.band_hz) if opts.band_hz else uff.read_frf(frf_path)
        kw = {k: getattr(opts, k) for k in ("max_lines", "max_findings", "max_nfev", "holdout")
              if getattr(opts, k) is not None}
        if opts.kinds:
            kw["kinds"] = list(opts.kinds)
        diag = _diagnose(model, H, parameters=params, test_modes=test_modes, criterion=opts.criterion,
                         progress=progress, **kw)
    files = []
    doc = diag.to_dict()
    for jp in dict.fromkeys(p for p in (json_path, Path(out_dir) / "diagnosis.json" if out_dir is not None else None)
                            if p is not None):
        files.append(write_json(jp, doc))
    if out_dir is not None:
        files += _diagnosis_files(diag, model, H, Path(out_dir), opts, updated_model)
    return StageResult(diag, tuple(files), {"statement": diag.statement, "findings": len(diag.findings)})


def _diagnosis_files(diag, model, H, d: Path, opts: DiagnoseOptions, updated_model) -> list:
    from updating.bulk import to_bulk, write_bdf
    from updating.diagnosis.report import write_figures

    from .report import plot_mci_maps

    files = []
    try:
        files += [Path(p) for p in write_figures(diag, d / "figures")]
    except Exception as e:  # noqa: BLE001 - the engine's own figures are extras; the diagnosis stands
        log.warning("diagnosis figures failed: %s", e)
    if diag.maps:
        files.append(plot_mci_maps(diag.maps, d / "mci_maps.png"))
    files.append(write_text(d / "diagnosed.bdf", write_bdf(to_bulk(diag.model))))
    if H is not None:
        files.append(_frf_overlays(H, model, diag, d, opts.overlay_dofs, updated_model))
    return files


def _frf_overlays(H, model, diag, d: Path, want, updated_model) -> Path:
    """Measured, nominal, diagnosed (and parameter-updated) FRFs at the chosen DOFs, first reference."""
    from .report import plot_frf_overlays

    resp = [r for r in H.responses if want is None or str(r) in {str(w) for w in want}][:4] or H.responses[:4]
    ref = H.references[0]
    lines = H.freq_hz[H.freq_hz > 0]
    f = lines[::max(1, len(lines) // 600)]
    curves = {"measured": H.select(responses=resp, references=[ref]).band(f[0], f[-1])}
    models = {"nominal": model, "diagnosed + updated": diag.model}
    if updated_model is not None and Path(updated_model).is_file():
        models["updated (parameters)"] = load_model(updated_model)
    eta = diag.parameters.get("eta_global", {}).get("updated")
    for name, m in models.items():
        try:
            mm = m.copy()
            if eta is not None and not mm.global_ge:
                mm.global_ge = float(eta)
            curves[name] = mm.frf(f, responses=resp, references=[ref])
        except Exception as e:  # noqa: BLE001 - an overlay curve must not fail the stage
            log.warning("FRF of the %s model failed: %s", name, e)
    return plot_frf_overlays(curves, d / "frf_overlay.png", responses=resp, reference=ref)


# ============================================================================ report
def report(run_dir, report_dir=None, *, project=None, title: str | None = None) -> StageResult:
    """The self-contained HTML report of a run folder and its ``summary.json`` (:mod:`modalab.report`)."""
    from .report import build_report

    html, summary = build_report(run_dir, report_dir, project=project, title=title)
    return StageResult(html, (html, summary), {"report": str(html)})
