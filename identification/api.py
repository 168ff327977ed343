"""One call from FRFs to modes: :func:`identify`.

The CLI (``modalab identify``) and notebooks call this; it wraps
:class:`~identification.polymax.PolyMAX` (estimation, stabilisation,
selection, LSFD) and writes the figures.
"""
from __future__ import annotations

import logging
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from acquisition.reciprocity import reorder_by_reciprocity
from modalab.core.errors import ModalabValueError, fmt_error
from modalab.core.frf import FRF, ROVING_RATIO, roving_hammer_layout as _roving_layout
from modalab.core.modes import ModeSet
from .lsfd import LSFDResult
from .plots import plot_automac, plot_stabilisation, plot_synthesis
from .polymax import PolyMAX
from .selection import SelectedPoles, SelectionOptions, unresolved_modes
from .stabilisation import StabilisationCriteria, StabilisationDiagram

log = logging.getLogger(__name__)

__all__ = ["identify", "IdentificationReport", "default_max_order", "roving_hammer_layout", "resolve_window",
           "ROVING_RATIO"]


#: with the default order, a mode that still resolves into a close pair at the top orders
#: (:func:`~identification.selection.unresolved_modes`) is identified again up to this times the order
EXTEND_ORDER = 1.5


def default_max_order(n_in: int) -> int:
    """Default highest order: about 120 poles in all, between orders 20 and 100."""
    return int(min(100, max(20, math.ceil(120 / max(int(n_in), 1)))))


@dataclass
class IdentificationReport:
    """What :func:`identify` learnt besides the modes.

    diagram : the stabilisation diagram (all orders, flags).
    selected : the selected poles as estimated (before window correction).
    lsfd : the LSFD modal model (residues, residuals) used for synthesis.
    synthesis : synthesised FRFs on the measured lines.
    frf_correlation, synthesis_error : (n_out, n_in) FRAC and relative error per FRF.
    figures : name -> saved file.
    settings : the parameters used.
    elapsed_s : wall time of the identification.
    modes : per-mode summary of the identified (window-corrected) modes: ``freq_hz``, ``damping``
        and, with ``uncertainty=True``, their standard deviations ``freq_std_hz``, ``damping_std``
        (FRF noise and spread over orders, :func:`~identification.polymax.combined_std`), those two
        parts (``*_noise``, ``*_orders``), the chi-square ratio ``chi2_ratio`` of the local fit and ``std_source``
        (the FRF noise model: 'H_variance', 'coherence' or 'residual'; see
        :func:`~identification.lsfd.pole_uncertainty`).  NaN is written as null.
    """

    diagram: StabilisationDiagram
    selected: SelectedPoles
    lsfd: LSFDResult
    synthesis: FRF
    frf_correlation: np.ndarray
    synthesis_error: np.ndarray
    figures: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    elapsed_s: float = 0.0
    modes: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """JSON-ready summary (the diagram is summarised per order, not pole by pole): the content of
        ``identification.json``, which the identify stage (:func:`modalab.app.stages.identify`) writes."""
        d = self.diagram
        per_order = {int(n): {"poles": int(np.sum(d.order == n)), "stable": int(np.sum(d.stable & (d.order == n)))}
                     for n in d.orders}
        return {
            "settings": self.settings, "elapsed_s": self.elapsed_s,
            "selected": {"freq_hz": self.selected.freq_hz.tolist(), "damping": self.selected.damping.tolist(),
                         "order": self.selected.order.tolist(), "cluster_size": self.selected.cluster_size.tolist(),
                         "source": self.selected.source},
            "stabilisation": {"orders": d.orders.tolist(), "per_order": per_order,
                              "criteria": d.to_dict()["criteria"]},
            "frf": {"responses": [str(x) for x in self.synthesis.responses],
                    "references": [str(x) for x in self.synthesis.references],
                    "correlation": np.round(self.frf_correlation, 6).tolist(),
                    "synthesis_error": np.round(self.synthesis_error, 6).tolist(),
                    "mean_correlation": float(np.nanmean(self.frf_correlation))},
            "modes": self.modes,
            "figures": {k: str(v) for k, v in self.figures.items()},
        }


def roving_hammer_layout(frf: FRF) -> bool:
    """True when ``frf`` looks like a roving-hammer export: references far more than responses.

    An analyser stores a roving-hammer test with the fixed accelerometers as responses and the hit
    points as references (e.g. 3 x 74).  Poly-reference identification wants the opposite: few
    references (the accelerometers) and many responses, which Maxwell–Betti reciprocity gives by
    transposing (thesis section 5.3).  The test: ``n_in >= ROVING_RATIO · n_out`` and ``n_in >= 2`` (3 hit
    points x 1 accelerometer is a roving-hammer test too): :func:`modalab.core.frf.roving_hammer_layout`, the rule
    ``modalab info`` and ``modalab correlate`` apply too.
    """
    return _roving_layout(frf.n_in, frf.n_out)


def resolve_window(frf: FRF, exp_beta: float | None = None, *, force: bool = False) -> tuple[float, str]:
    """The exponential-window decay β (1/s) to remove, and where it comes from.

    ``frf.window_beta_per_s`` is what the file (or the acquisition) says.  ``exp_beta`` is the
    analyst's value: used when the FRF carries none; when the FRF carries a different non-zero β
    the call is refused unless ``force`` (then ``exp_beta`` wins and the source says so).

    Returns ``(beta, source)`` with ``source`` one of ``'none'``, ``'file'``, ``'option'``,
    ``'option (overrides the file's beta=...)'``.
    """
    carried = float(frf.window_beta_per_s)
    if force and exp_beta is None:
        raise ModalabValueError("force_window (--force-window) needs exp_beta (--exp-beta B): the beta to use "
                                "instead of the file's")
    if exp_beta is None:
        return carried, ("file" if carried > 0 else "none")
    b = float(exp_beta)
    if not np.isfinite(b) or b < 0:
        raise ModalabValueError(fmt_error("exp_beta", exp_beta, "the window's decay rate >= 0 in 1/s",
                                          "e.g. --exp-beta 0.139 (the analyser's exponential window)"))
    if carried > 0 and not np.isclose(b, carried, rtol=1e-6, atol=0.0):
        if not force:
            raise ModalabValueError(
                f"the FRF already carries an exponential window beta={carried:g} 1/s but exp_beta={b:g} was given; "
                "pass force_window=True (--force-window) to use the given value, or drop exp_beta")
        return b, f"option (overrides the file's beta={carried:g} 1/s)"
    if carried > 0:
        return b, "file"
    return b, ("option" if b > 0 else "none")


def identify(frf: FRF, *, band_hz=None, max_order: int | None = None, select="auto", references=None,
             plots_dir=None, weighting=None, criteria: StabilisationCriteria | None = None,
             selection: SelectionOptions | None = None, min_order: int = 1, order_step: int = 1,
             lower_residual: bool = True, upper_residual: bool = True, window_correction: bool = True,
             refine: bool = True, uncertainty: bool = True, reciprocity: bool | None = None,
             exp_beta: float | None = None, force_window: bool = False):
    """Identify modes from FRFs with poly-reference pLSCF, stabilisation, pole selection and LSFD.

    Parameters
    ----------
    frf : modalab.FRF
        Receptance, mobility or accelerance, ``(n_out, n_in, n_freq)``.
    band_hz : (lo, hi) or None
        Band to identify in; the whole FRF by default (lines at 0 Hz are dropped).
    max_order : int or None
        Highest model order (order n gives n·n_in poles); default :func:`default_max_order`.  With the
        default and automatic selection, when a selected mode still resolves into a close pair at the top
        orders (:func:`~identification.selection.unresolved_modes`) the identification runs once more up
        to ``EXTEND_ORDER`` times that order, kept if it resolves one of them into several modes
        (``settings['max_order_extended']``: from, to, the modes, kept); a mode still unresolved is logged
        as a warning.
    select : 'auto' | sequence of Hz | path
        Automatic clustering, the analyst's frequencies, or a JSON/TOML selection file.
    references : DOF labels or None
        Use only these references (columns of H; after a reciprocity transpose, the accelerometers).
    plots_dir : path or None
        Folder for ``stabilisation.png``, ``synthesis.png``, ``automac.png``.
    weighting : None | 'coherence' | 'variance'
    criteria, selection : stabilisation tolerances and selection settings (defaults if None).
    min_order, order_step : orders evaluated.
    lower_residual, upper_residual : residual terms of LSFD.
    window_correction : remove the exponential window's decay β from the poles
        (:func:`acquisition.windows.correct_poles`): β from ``frf.window_beta_per_s`` or ``exp_beta``.
    exp_beta, force_window : the window's β (1/s) when the file does not carry it; ``force_window``
        lets ``exp_beta`` override a different β the FRF carries (:func:`resolve_window`).  The
        correction applied is in ``report.settings['window_correction']``.
    reciprocity : None (default) transposes a roving-hammer layout (:func:`roving_hammer_layout`:
        references far more than responses) by Maxwell–Betti reciprocity, with a log message, so that
        the accelerometers become the references; True always transposes; False never does.
        What was done is in ``report.settings['reciprocity']``.
    refine : refine the selected poles by local variable-projection least squares (default True).
    uncertainty : standard deviations of the refined frequencies and damping ratios (default True; about
        one Jacobian per mode, a few % of the fit): the spread of the pole over the stable orders combined
        with the first-order noise propagation (:func:`~identification.polymax.combined_std`), the noise from
        ``frf.variance`` (variance across averages, shape of H), else from coherence
        and ``metadata['n_averages']``, else from the residual of the local fit
        (:func:`~identification.lsfd.pole_uncertainty`; first order, noise uncorrelated across
        lines, references and outputs).

    Returns
    -------
    modes : modalab.ModeSet
        Natural frequencies (Hz, undamped), damping ratios, complex shapes on the
        response DOFs (unit modal mass when a driving point exists, else unit
        maximum), participation on the references (``A_r = φ_r L_rᵀ``) and per-mode
        indicators MPC, MPD, MCF, MOV, contribution, cluster_size, order and, with
        ``uncertainty``, freq_std_hz, damping_std, chi2_ratio (noise model in
        ``metadata['pole_std_source']``).
    report : IdentificationReport

    Example
    -------
    >>> modes, report = identify(frf, band_hz=(5, 200), plots_dir="out")   # doctest: +SKIP
    >>> modes.to_json("modes.json")                                         # doctest: +SKIP
    """
    # long by its docstring (every keyword of the public entry point documented); the body is ~40 lines
    if not isinstance(frf, FRF):
        raise ModalabValueError(fmt_error("frf", type(frf).__name__, "a modalab.FRF",
                                          "Read one with FRF.from_uff(path)"))
    t0 = time.perf_counter()
    frf, recip = _reciprocity(frf, reciprocity)
    beta, beta_source = resolve_window(frf, exp_beta, force=force_window)
    if not window_correction:
        beta_source = "not applied (window_correction=False)"
    if beta != frf.window_beta_per_s:
        frf = frf._replace(window_beta_per_s=beta)
    data = frf if references is None else frf.select(references=references)
    n_order = default_max_order(data.n_in) if max_order is None else max_order

    def _fit(p):
        return PolyMAX(max_order=p, min_order=min_order, order_step=order_step, weighting=weighting,
                       band_hz=band_hz, criteria=criteria, select=select, selection=selection,
                       lower_residual=lower_residual, upper_residual=upper_residual,
                       window_correction=window_correction, refine=refine, uncertainty=uncertainty).fit(data)

    pm = _fit(n_order)
    extended = None
    if isinstance(select, str) and select == "auto":
        pm, n_order, extended = _resolve_close_pairs(_fit, pm, n_order, selection, order_given=max_order is not None)
    modes: ModeSet = pm.modes_
    synth = pm.lsfd_.synthesise(pm.frf_)
    report = IdentificationReport(
        diagram=pm.stabilisation_, selected=pm.selected_, lsfd=pm.lsfd_, synthesis=synth,
        frf_correlation=pm.lsfd_.metadata["frf_correlation"], synthesis_error=pm.lsfd_.metadata["synthesis_error"],
        settings=_settings(pm, n_order, select, min_order=min_order, order_step=order_step, weighting=weighting,
                           refine=refine, uncertainty=uncertainty,
                           window={"beta_per_s": float(beta) if window_correction else 0.0, "source": beta_source},
                           reciprocity=recip, extended=extended))
    if plots_dir is not None:
        report.figures.update(_write_figures(pm, synth, modes, Path(plots_dir)))
    report.modes = _modes_summary(modes, uncertainty)
    report.elapsed_s = time.perf_counter() - t0
    log.info("identified %d modes in %.2f s (mean FRF correlation %.4f)", modes.n_modes, report.elapsed_s,
             float(np.nanmean(report.frf_correlation)) if report.frf_correlation.size else float("nan"))
    return modes, report


def _settings(pm, n_order: int, select, *, min_order, order_step, weighting, refine, uncertainty, window,
              reciprocity, extended) -> dict:
    """``report.settings``: the parameters the identification used, as JSON-ready values."""
    return {"band_hz": [float(pm.frf_.freq_hz[0]), float(pm.frf_.freq_hz[-1])], "max_order": int(n_order),
            "min_order": int(min_order), "order_step": int(order_step), "weighting": weighting or "none",
            "refine": bool(refine), "uncertainty": bool(uncertainty),
            "select": (str(select) if isinstance(select, (str, os.PathLike))
                       else [float(x) for x in np.atleast_1d(select)]),
            "references": [str(r) for r in pm.frf_.references], "n_responses": pm.frf_.n_out,
            "n_lines": pm.frf_.n_freq, "quantity": pm.frf_.quantity, "window_correction": window,
            "reciprocity": reciprocity, "max_order_extended": extended,
            "criteria": pm.stabilisation_.to_dict()["criteria"]}


def _reciprocity(frf: FRF, reciprocity):
    """``(frf, record)``: a roving-hammer layout transposed by Maxwell–Betti reciprocity (or as forced or
    refused by ``reciprocity``), and what was done (``settings['reciprocity']``)."""
    if reciprocity not in (None, True, False):
        raise ModalabValueError(fmt_error("reciprocity", reciprocity, "None (automatic), True or False",
                                          "Leave it None: a roving-hammer layout is transposed"))
    roving = roving_hammer_layout(frf)
    transpose = roving if reciprocity is None else bool(reciprocity)
    if transpose:
        why = ("forced" if reciprocity else
               f"{frf.n_out} responses x {frf.n_in} references looks like a roving-hammer export")
        log.info("reciprocity: %s; transposed to %d responses x %d references (the accelerometers are the "
                 "references)", why, frf.n_in, frf.n_out)
        return reorder_by_reciprocity(frf), {"applied": True, "reason": why, "measured_shape": [frf.n_out, frf.n_in]}
    recip = {"applied": False, "measured_shape": [frf.n_out, frf.n_in],
             "reason": "refused (reciprocity=False)" if roving else "layout already has few references"}
    if roving:
        log.warning("%d responses x %d references identified as given (reciprocity refused): every "
                    "reference adds poles to each order; expect a slow, poor fit", frf.n_out, frf.n_in)
    return frf, recip


def _resolve_close_pairs(fit, pm, n_order: int, selection, *, order_given: bool):
    """``(pm, order, record)``: with automatic selection, a mode still resolving into a close pair at the top
    orders (:func:`~identification.selection.unresolved_modes`) is identified once more up to
    ``EXTEND_ORDER`` times the default order (only when the analyst left the order to us, ``order_given``
    False), kept if it resolves one of them into several modes; ``record`` is
    ``settings['max_order_extended']`` (None when not tried).  A mode still unresolved is a warning."""
    extended = None
    band = (float(pm.frf_.freq_hz[0]), float(pm.frf_.freq_hz[-1]))
    unres = unresolved_modes(pm.stabilisation_, pm.selected_, selection, band_hz=band)
    if unres.size and not order_given:
        # a close pair still being resolved at the top orders (a merged pole below, two above): once,
        # with EXTEND_ORDER times the default order (only when the analyst left the order to us); the
        # higher order is kept only if it resolves one of them into several modes
        first = pm.selected_.freq_hz[unres]
        p2 = int(math.ceil(EXTEND_ORDER * n_order))
        log.info("mode(s) at %s Hz still resolving at order %d (a second pole appears beside them at the "
                 "top orders): identifying again up to order %d",
                 ", ".join(f"{x:.5g}" for x in first), n_order, p2)
        pm2 = fit(p2)
        tol = 0.5 * (selection or SelectionOptions()).distance
        split = [int(np.sum(np.abs(pm2.selected_.freq_hz - x) <= tol * x)) >= 2 for x in first]
        extended = {"from": int(n_order), "to": p2, "modes_hz": [float(x) for x in first], "kept": any(split)}
        if any(split):
            pm, n_order = pm2, p2
            unres = unresolved_modes(pm.stabilisation_, pm.selected_, selection, band_hz=band)
        else:
            log.info("order %d did not resolve them: the identification at order %d is kept", p2, n_order)
    if unres.size:
        log.warning("mode(s) at %s Hz may hide a close pair not resolved by order %d (a second pole keeps "
                    "appearing beside them at the top orders); raise --max-order or pick them with --select",
                    ", ".join(f"{x:.5g}" for x in pm.selected_.freq_hz[unres]), n_order)
    return pm, n_order, extended


def _write_figures(pm, synth: FRF, modes: ModeSet, out: Path) -> dict:
    """``stabilisation.png``, ``synthesis.png``, ``automac.png`` in ``out``; name -> file."""
    out.mkdir(parents=True, exist_ok=True)
    figures = {"stabilisation": out / "stabilisation.png", "synthesis": out / "synthesis.png",
               "automac": out / "automac.png"}
    plot_stabilisation(pm.stabilisation_, pm.frf_, selected_hz=pm.selected_.freq_hz, path=figures["stabilisation"])
    plot_synthesis(pm.frf_, synth, path=figures["synthesis"])
    plot_automac(modes, path=figures["automac"])
    return figures


def _modes_summary(modes: ModeSet, uncertainty: bool) -> dict:
    """``report.modes``: per-mode frequencies and damping ratios and, with ``uncertainty``, their standard
    deviations and the close-pair test (NaN as None)."""
    def _list(v):
        return [None if not np.isfinite(x) else float(x) for x in np.asarray(v, float)]

    out = {"freq_hz": _list(modes.freq_hz), "damping": _list(modes.damping)}
    if uncertainty:
        out.update({k: _list(modes.indicators[k]) for k in (
            "freq_std_hz", "damping_std", "freq_std_noise_hz", "damping_std_noise", "freq_std_orders_hz",
            "damping_std_orders", "chi2_ratio")})
        out["std_source"] = modes.metadata.get("pole_std_source")
        if "may_be_pair" in modes.indicators:
            # a mode whose residues are not of rank one: possibly a close pair merged into one pole
            out["may_be_pair"] = [bool(x) for x in modes.indicators["may_be_pair"]]
            out["rank2_fraction"] = _list(modes.indicators["rank2_fraction"])
    return out
