"""The update stage: one FE model updated to test modes or FRFs by any of eight methods."""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from modalab.core.errors import ModalabError, PlanError
from modalab.app.outputs import write_json, write_text
from modalab.app.stages._common import StageResult, check_band_lines, load_model, load_modes, load_parameters
from modalab.app.stages._correlate import (CorrelateOptions, DofMapping, _correlation, _correlation_figures, _freq_err, _n_analysis,
                         resolve_dof_map)
from updating.correlation.dofmap import as_dofmap
from updating.fe.bulk import read_bdf, to_bulk, write_bdf
from updating.fe import ParametricFEModel
from modalab.core.frf import FRF
from modalab.core.modes import ModeSet
from updating.correlation.expansion import kidder
from updating.methods.eigendynamic import EigendynamicConstraint
from updating.methods.eigensensitivity import InverseEigensensitivity
from updating.methods.mci import MCIUpdater
from updating.methods.mci_plots import plot_convergence
from updating.methods.rfm import ResponseFunctionMethod
from updating.methods import direct as dm
from updating.correlation.metrics import correlate as _correlate, shape_noise
from modalab.core.structure import Structure

log = logging.getLogger(__name__)


MODAL_METHODS = ("eigensensitivity", "eigendynamic")
FRF_METHODS = ("mci", "rfm")
DIRECT_METHODS = ("direct-lagrange", "direct-error-matrix", "direct-matrix", "direct-mixing")
UPDATE_METHODS = MODAL_METHODS + FRF_METHODS + DIRECT_METHODS

#: the largest relative frequency standard deviation accepted: a test frequency known to worse than ±50 % says
#: nothing, and 0.8 is a percentage given as a fraction
MAX_FREQ_SIGMA = 0.5


@dataclass(frozen=True)
class UpdateOptions:
    """``modalab update``: method (:data:`UPDATE_METHODS`), parameter file (default E and density per property),
    iteration limit, and for eigensensitivity the regularisation ('lcurve', 'gcv' or a number), use of mode
    shapes (never for a frequency-only test set), relative frequency standard deviation (one value or one per
    test mode; None: the covariance stored with the modes, else their identified freq_std_hz — for a UFF 55,
    which cannot carry them, those of the modes.json identify wrote beside it — else an assumed 1 %) and
    shape standard deviation (a floor, raised per mode to the noise its complexity shows); bands (Hz) for
    mci/rfm; correlation options (DOF map, frequency window: the pairing of every method)."""

    method: str = "eigensensitivity"
    parameters: str | None = None
    max_iter: int = 30
    regularisation: object = "lcurve"
    use_shapes: bool = True
    freq_sigma: object = None
    shape_sigma: float = 0.05
    bands: tuple | None = None
    correlation: CorrelateOptions = CorrelateOptions()

    def __post_init__(self):
        if self.method not in UPDATE_METHODS:
            raise PlanError(f"updating method {self.method!r}; expected one of {', '.join(UPDATE_METHODS)}")
        if isinstance(self.max_iter, bool) or not isinstance(self.max_iter, int) or self.max_iter < 1:
            raise PlanError(f"max_iter = {self.max_iter!r} (--max-iter): expected at least 1 iteration; give e.g. "
                            "max_iter = 30")
        if self.bands is not None:
            object.__setattr__(self, "bands", tuple(tuple(float(x) for x in b) for b in self.bands))
        if isinstance(self.freq_sigma, list):
            object.__setattr__(self, "freq_sigma", tuple(self.freq_sigma))
        if self.freq_sigma is not None:
            fs = np.atleast_1d(np.asarray(self.freq_sigma, float))
            bad = fs[~(np.isfinite(fs) & (fs > 0))]
            if bad.size:
                raise PlanError(f"--freq-sigma {bad[0]:g}: expected a relative standard deviation above 0 and up to "
                                f"{MAX_FREQ_SIGMA:g} (0.002 = 0.2 %); give e.g. --freq-sigma 0.002")
            big = fs[fs > MAX_FREQ_SIGMA]
            if big.size:
                raise PlanError(f"--freq-sigma {big[0]:g}: a relative standard deviation of {100 * big[0]:g} % of the "
                                f"frequency; expected a fraction up to {MAX_FREQ_SIGMA:g} (0.002 = 0.2 %). Give the "
                                f"fraction, e.g. --freq-sigma {big[0] / 100:g} for {big[0]:g} %")


def _on_model_dofs(modes, dofs, dofmap):
    """Test modes restricted to DOFs the updater can see (independent DOFs of the constrained model): a test
    DOF is kept when every model DOF the map puts it on is one of ``dofs``."""

    if not modes.has_shapes:
        return modes
    dm = as_dofmap(dofmap)
    have = {(m.node, m.axis) for m in dofs}
    keep = [d for d in modes.dofs if all((t.node, t.axis) in have for t, _ in dm.terms(d))]
    if len(keep) < len(modes.dofs):
        log.warning("%d test DOF(s) lie on dependent or constrained model DOFs and are left out of the updating "
                    "(kept in the correlation): %s", len(modes.dofs) - len(keep),
                    ", ".join(str(d) for d in modes.dofs if d not in keep))
    return modes.select_dofs(keep)


def _same_modes(a, b) -> bool:
    """True when two mode sets hold the same modes (frequencies, damping, DOFs and shapes as written)."""
    if a.n_modes != b.n_modes or [str(d) for d in a.dofs] != [str(d) for d in b.dofs]:
        return False
    if not np.allclose(a.freq_hz, b.freq_hz, rtol=1e-9, atol=0):
        return False
    if (a.damping is None) != (b.damping is None) or (a.damping is not None and
                                                       not np.allclose(a.damping, b.damping, rtol=1e-6, atol=1e-12)):
        return False
    if a.has_shapes != b.has_shapes:
        return False
    return not a.has_shapes or np.allclose(a.shapes, b.shapes, rtol=1e-6, atol=1e-12 * np.abs(b.shapes).max())


def _sibling_uncertainty(test, modes_path):
    """Frequency uncertainty for a UFF 55 mode set, which cannot carry it: taken from the ``modes.json`` that
    ``modalab identify`` wrote beside it (same name, ``.json``) when that file holds the same modes (frequencies,
    damping, DOFs, shapes: the same identification); else nothing.

    Returns ``(test, source)``: the mode set with ``freq_std_hz`` (and ``freq_cov``) of the JSON, and the JSON's
    path; or ``(test, None)`` unchanged."""
    if test is None or modes_path is None:
        return test, None
    p = Path(modes_path)
    if p.suffix.lower() not in (".uff", ".unv") or test.freq_cov is not None or \
            (test.indicators or {}).get("freq_std_hz") is not None:
        return test, None
    js = p.with_suffix(".json")
    if not js.is_file():
        return test, None
    try:
        other = ModeSet.from_json(js)
    except ModalabError as e:        # a file beside the input, not named by the user: say so, and use none
        log.warning("%s lies beside %s but is not a modes.json of modalab identify (%s): its frequency "
                    "uncertainties are not used", js, p, str(e).splitlines()[0] if str(e) else type(e).__name__)
        return test, None
    std = (other.indicators or {}).get("freq_std_hz")
    if other.freq_cov is None and std is None:
        return test, None
    if not _same_modes(test, other):
        log.warning("%s lies beside %s but holds other modes (not the same identification): its frequency "
                    "uncertainties are not used", js, p)
        return test, None
    test.indicators = dict(test.indicators or {})
    if std is not None:
        test.indicators["freq_std_hz"] = np.asarray(std, float)
    if other.freq_cov is not None:
        test.freq_cov = other.freq_cov
    log.info("frequency uncertainties of %s from %s (the same identification)", p, js)
    return test, js


def _freq_sigma(value, test, modes_path):
    """The relative frequency sigma: None, one positive value, or one per test mode (checked).

    Not given: the covariance stored with the modes (None here: the updater reads it), else the standard
    deviations ``modalab identify`` stored with each mode (indicator ``freq_std_hz``: FRF noise and spread over
    the model orders, coverage tested), relative to the frequency; a mode without one keeps 1 %.  With 1 % for
    frequencies identified to 0.01 %, the shape residuals' small biases outweighed the frequencies and moved an
    exact model's parameters by 1.4 % (issue 14)."""
    if test is None:
        return None
    if value is None:
        if test.freq_cov is not None or not test.n_modes:
            return None
        std = (test.indicators or {}).get("freq_std_hz")
        if std is None:
            log.warning("%s holds no frequency standard deviations (a UFF 55 cannot): every test frequency is "
                        "weighted with a relative sigma of 1 %%; the modes.json of modalab identify carries them, "
                        "or give --freq-sigma", modes_path)
            return None
        rel = np.asarray(std, float).ravel() / np.asarray(test.freq_hz, float)
        if rel.size != test.n_modes:
            return None
        ok = np.isfinite(rel) & (rel > 0)
        if not ok.any():
            return None
        if not ok.all():
            log.info("test mode(s) %s carry no frequency standard deviation: relative sigma 1 %%",
                     ", ".join(str(j + 1) for j in np.flatnonzero(~ok)))
        return np.where(ok, rel, 0.01)
    fs = np.atleast_1d(np.asarray(value, float))
    if fs.size not in (1, test.n_modes) or not np.all(np.isfinite(fs)) or np.any(fs <= 0):
        raise PlanError(f"--freq-sigma: got {fs.size} value(s); expected one positive relative sigma "
                        f"(e.g. 0.002) or one per test mode ({test.n_modes}) of {modes_path}")
    return fs if fs.size > 1 else float(fs[0])


def update(model_path, out_dir, opts: UpdateOptions = UpdateOptions(), *, modes_path=None,
           frf_path=None) -> StageResult:
    """Update the FE model to test modes (eigensensitivity, eigendynamic, direct methods) or FRFs (mci, rfm).

    Writes into ``out_dir``: ``updated.bdf`` (the user's deck with the updated values; direct methods change
    matrices, not parameters: ``updated_matrices.npz``), ``update.json`` (parameters with initial, updated and
    std, convergence history, correlation before and after), ``mac_before/after.png``,
    ``frequencies_after.png`` and ``convergence.png``.
    """


    out = Path(out_dir)
    method = opts.method
    model = load_model(model_path, opts.correlation.ignore_unsupported)
    test = load_modes(modes_path) if modes_path else None
    if method in MODAL_METHODS + DIRECT_METHODS and test is None:
        raise PlanError(f"method {method!r} needs test modes: pass --modes MODES.uff")
    if method in FRF_METHODS and frf_path is None:
        raise PlanError(f"method {method!r} needs measured FRFs: pass --frf FRF.uff")
    co = opts.correlation
    summary: dict = {"model": str(model_path), "method": method}
    mapping = DofMapping()
    if test is not None:
        mapping = resolve_dof_map(model, test, co, modes_path=modes_path)
        summary["dof_mapping"] = mapping.description
        if not test.has_shapes:
            if method != "eigensensitivity":
                raise PlanError(f"{modes_path} holds frequencies only (no mode shapes); method {method!r} needs "
                                "shapes: use --method eigensensitivity")
            summary["note"] = "frequency-only test set: frequencies only, modes paired by frequency order"
    test, unc_source = _sibling_uncertainty(test, modes_path)
    fsig = _freq_sigma(opts.freq_sigma, test, modes_path)
    if test is not None and method == "eigensensitivity":
        summary["frequency_weights"] = _weights_text(test, fsig, opts.freq_sigma, modes_path, unc_source)
    if method in FRF_METHODS and opts.bands:      # a band of a few lines (kHz for Hz) fails before any work
        measured = FRF.from_uff(frf_path)
        for b in opts.bands:
            check_band_lines(measured, b, frf_path)
    params = lo = hi = None
    if method not in DIRECT_METHODS:              # a bad parameter file fails before anything is written
        params, lo, hi = load_parameters(opts.parameters, model)
    out.mkdir(parents=True, exist_ok=True)
    files = []
    before = _correlation(model, test, co, mapping) if test is not None else None
    if method in DIRECT_METHODS:
        after = _update_direct(model, test, method, co, mapping, out, summary)
        files.append(out / "updated_matrices.npz")
    else:
        after, written = _update_parameters(model, model_path, opts, (params, lo, hi), test, frf_path, mapping, fsig,
                                            out, summary)
        files += written
    if before is not None:
        summary["correlation_before"] = before.to_dict()
        summary["correlation_after"] = after.to_dict()
        summary["table_before"] = before.table()
        # the test's DOFs are the same after: the MAC's DOF warning is said once, below the first table
        summary["table_after"] = after.table(mac_warning=not before.mac_warning())
        files += _correlation_figures(before, out, "before", "model before updating", frequencies=False)
        files += _correlation_figures(after, out, "after", "updated model")
    files.insert(0, write_json(out / "update.json", summary))
    short = {"parameters": {n: round(v["updated"], 4) for n, v in summary.get("parameters", {}).items()},
             "mean_abs_freq_error_pct": _freq_err(after) if before is not None else None}
    return StageResult(summary, tuple(files), short)


def _update_parameters(model, model_path, opts: UpdateOptions, declared, test, frf_path, mapping: DofMapping, fsig,
                       out: Path, summary: dict):
    """Fit the declared parameters (``declared``: parameters, lower and upper bounds) by ``opts.method``, write
    ``convergence.png`` and ``updated.bdf`` (the user's deck with the updated values) and fill ``summary``;
    returns the correlation of the updated model (None without test modes) and the files written."""
    params, lo, hi = declared
    pm = ParametricFEModel(model, params)
    up = _fit_parameters(pm, opts, lo, hi, test, frf_path, mapping.dofmap, fsig)
    if opts.method == "eigensensitivity":
        summary["identifiability"] = _identifiability(up, pm, summary["frequency_weights"])
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
    files = [plot_convergence(rows, out / "convergence.png", names=names, normalise=False)]
    updated = pm.model_at(p)
    files.append(write_text(out / "updated.bdf", write_bdf(to_bulk(updated, template=read_bdf(
        model_path, ignore_unsupported=opts.correlation.ignore_unsupported)))))
    summary["updated_model"] = str(out / "updated.bdf")
    after = _correlation(updated, test, opts.correlation, mapping) if test is not None else None
    return after, files


def _identifiability(up, pm, weights_text) -> dict:
    """Condition number, identifiability and unregularised standard deviations of an eigensensitivity fit."""
    names = [pm.parameter_names[i] for i in np.atleast_1d(up.params_)]
    return {"condition_number": float(up.condition_), "identifiable": bool(up.identifiable_),
            "std_unregularised": {n: (float(v) if np.isfinite(v) else None)
                                  for n, v in zip(names, np.atleast_1d(up.std_unregularised_))},
            "frequency_weights": weights_text,
            "residual_check": {g: {"chi2": float(v["chi2"]), "dof": float(v["dof"]), "n": int(v["n"]),
                                   "chi2_95": float(v["chi2_95"]) if np.isfinite(v["chi2_95"]) else None,
                                   "std_factor": float(np.sqrt(v["factor"]))}
                               for g, v in (getattr(up, "residual_check_", None) or {}).items()}}


def _weights_text(test, fsig, given, modes_path, source) -> str:
    """Where the frequency weights come from, said plainly (an assumed 1 % is called an assumption)."""
    name = Path(modes_path).name if modes_path is not None else "the test modes"
    src = f" of {Path(source).name} beside {name}, the same identification" if source is not None else \
        f" stored with {name}"
    if given is not None:
        if np.ndim(fsig) and np.size(fsig) > 1:
            return f"relative sigma per test mode {np.min(fsig):.3g}..{np.max(fsig):.3g} (--freq-sigma)"
        return f"relative sigma {float(fsig):g} (--freq-sigma)"
    if fsig is None:
        if test.freq_cov is not None:
            return "covariance of the test frequencies" + src
        return (f"relative sigma 0.01 for every test mode: an assumption, not a measurement ({name} carries no "
                "frequency uncertainty; the modes.json of modalab identify does, or give --freq-sigma)")
    if np.ndim(fsig) and np.size(fsig) > 1:
        return f"relative sigma per test mode {np.min(fsig):.3g}..{np.max(fsig):.3g} (freq_std_hz{src})"
    return f"relative sigma {float(fsig):g}"


def _shape_sigma(shape_sigma, test):
    """Per test mode, the relative standard deviation of a shape component in the eigensensitivity objective:
    the given ``shape_sigma`` (a floor), raised to the noise the identified shape carries by its complexity
    (:func:`updating.correlation.metrics.shape_noise`).  A weakly excited mode whose shape came out with MPC 0.64
    has a component noise near 45 %: weighted as if it were 5 %, its shape pulled an exact model's parameters
    by several % (issue 14); its frequency keeps its full weight."""
    if not test.has_shapes:
        return shape_sigma
    noise = shape_noise(test.shapes)
    sig = np.maximum(float(shape_sigma), noise)
    raised = np.flatnonzero(sig > float(shape_sigma))
    if raised.size:
        log.info("shape weights: test mode(s) %s carry more shape noise than %g (complexity): sigma %s",
                 ", ".join(str(j + 1) for j in raised), shape_sigma,
                 ", ".join(f"{sig[j]:.2g}" for j in raised))
    return sig


def _fit_parameters(pm, opts: UpdateOptions, lo, hi, test, frf_path, dofmap, fsig):
    pairing = {"max_freq_error": opts.correlation.freq_window}
    if opts.method == "eigensensitivity":
        kw = {} if fsig is None else {"freq_sigma": fsig, "freq_cov": None}
        est = InverseEigensensitivity(max_iter=opts.max_iter, regularisation=opts.regularisation,
                                      use_shapes=bool(opts.use_shapes and test.has_shapes),
                                      shape_sigma=_shape_sigma(opts.shape_sigma, test), bounds=(lo, hi),
                                      mac_min=opts.correlation.mac_min,
                                      pairing=pairing, **kw)
        return est.fit(pm, _on_model_dofs(test, pm.dofs, dofmap), dofmap=dofmap)
    if opts.method == "eigendynamic":
        return EigendynamicConstraint(pairing=pairing).fit(pm, _on_model_dofs(test, pm.dofs, dofmap), dofmap=dofmap)

    measured = FRF.from_uff(frf_path)
    bands = [tuple(b) for b in opts.bands] if opts.bands else None
    if opts.method == "mci":
        return MCIUpdater(bands=bands, max_iter=opts.max_iter).fit(pm, measured)

    return ResponseFunctionMethod(bands=bands, max_iter=opts.max_iter).fit(pm, measured)


def _update_direct(model, test, method, co: CorrelateOptions, mapping: DofMapping, out: Path, summary: dict):


    st = model.structure()
    if mapping.dofmap is None and all(any(d.same_axis(m) for m in test.dofs) for d in st.dofs):
        phi_x = test.select_dofs(st.dofs).real_shapes
    else:
        phi_x = kidder(st, _on_model_dofs(test, st.dofs, mapping.dofmap), dofmap=mapping.dofmap).real_shapes
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
    return _correlate(Structure(M=res.M, K=res.K, dofs=st.dofs), _on_model_dofs(test, st.dofs, mapping.dofmap),
                      dofmap=mapping.dofmap, n_analysis_modes=_n_analysis(co, test), mac_min=co.mac_min,
                      freq_weight=co.freq_weight, max_freq_error=co.freq_window, dof_mapping=mapping.description,
                      geometry=mapping.geometry)
