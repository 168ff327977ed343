"""The diagnose stage: locate, name, model and prove the physics the FE model leaves out."""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from modalab.core.errors import PlanError
from modalab.app.outputs import write_json, write_text
from modalab.app.stages._common import (StageResult, _band, _tuple, check_band_lines, load_model, load_modes,
                                        load_parameters)
from updating.diagnosis import diagnose as _diagnose
from updating.diagnosis import diagnose_modes
from updating.fe.bulk import to_bulk, write_bdf
from updating.fe.damping import own_loss_exempt
from updating.diagnosis.report import write_figures
from modalab.app.figures import plot_frf_overlays
from updating.fe.parameter_file import read_priors
from updating.diagnosis.modes import map_test_modes
from modalab.core import uff
from modalab.core.errors import UffError

log = logging.getLogger(__name__)

#: the stage's own figure (the engine's figures go to ``figures/``, named by :mod:`updating.diagnosis.report`)
OVERLAY_NAME = "frf_overlay_models.png"


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
    dofmap: str | None = None              # modes-only: DOF map file (test DOF -> model DOF), as for correlate
    ignore_unsupported: bool = False       # build the model without structural cards it cannot model
    band_option: str = "band_hz"           # how the band was given, for messages (a project key)
    band_source: str | None = None         # the file that gave it (a project file)
    jobs: int | None = None                # processes for the diagnosis' independent fits (None: the cores)

    def __post_init__(self):
        for k in ("band_hz", "kinds", "overlay_dofs"):
            object.__setattr__(self, k, _tuple(getattr(self, k)))


def diagnose(model_path, *, frf_path=None, modes_path=None, opts: DiagnoseOptions = DiagnoseOptions(),
             json_path=None, out_dir=None, updated_model=None, progress: Callable | None = None) -> StageResult:
    """Locate what the FE model leaves out, name the physics, model it, prove it on held-out FRF rows.

    From measured FRFs (``frf_path``; the identified ``modes_path`` then give the frequency and MAC columns of
    the fit), or from identified modes alone (a GVT). ``json_path``: ``diagnosis.json`` (schema
    ``modalab/app/schemas/diagnosis.schema.json``). ``out_dir``: ``diagnosis.json`` there too, the engine's figures (``figures/``: MCI maps, FRF overlays at the
    located DOFs, frequencies), ``diagnosed.bdf`` (the augmented, updated model) and ``frf_overlay_models.png``
    (measured, nominal, diagnosed and, given ``updated_model``, the parameter-updated model at the chosen DOFs;
    models at ``s = iω + β`` of the measurement's window).
    """

    if frf_path is None and modes_path is None:
        raise PlanError("give measured FRFs (MEASURED.uff) or --modes MODES.uff (a GVT's modes alone)")
    if opts.dofmap is not None and frf_path is not None:
        raise PlanError("--map applies to a modes-only diagnosis (--modes without MEASURED.uff); remove --map or the "
                        "measured FRFs")
    model = load_model(model_path, opts.ignore_unsupported)
    params = load_parameters(opts.parameters, model)[0] if opts.parameters else None
    priors = None
    if opts.parameters:
        priors = read_priors(opts.parameters) or None
    test_modes = load_modes(modes_path) if modes_path else None
    H = None
    if frf_path is None:
        kw = {k: getattr(opts, k) for k in ("max_findings",) if getattr(opts, k) is not None}
        if opts.kinds:
            kw["kinds"] = list(opts.kinds)
        if opts.dofmap is not None:
            test_modes = map_test_modes(test_modes, model, opts.dofmap)
        diag = diagnose_modes(model, test_modes, parameters=params, progress=progress, **kw)
    else:
        H = _read_measured(frf_path)
        if opts.band_hz:
            check_band_lines(H, opts.band_hz, frf_path, option=opts.band_option, source=opts.band_source)
        H = _band(H, opts.band_hz) if opts.band_hz else H
        kw = {k: getattr(opts, k) for k in ("max_lines", "max_findings", "max_nfev", "holdout", "jobs")
              if getattr(opts, k) is not None}
        if opts.kinds:
            kw["kinds"] = list(opts.kinds)
        if priors:
            kw["priors"] = priors
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


def _read_measured(frf_path):
    """The measured FRFs; a file of identified modes given in their place is pointed to ``--modes``."""
    try:
        return uff.read_frf(frf_path)
    except UffError:
        if "55" in uff.info(frf_path).get("datasets", {}):
            raise PlanError(f"'{frf_path}' holds identified modes (dataset 55), not measured FRFs (dataset 58); "
                            f"for a diagnosis from modes alone give it with --modes: modalab diagnose MODEL.bdf "
                            f"--modes {frf_path}") from None
        raise


def _diagnosis_files(diag, model, H, d: Path, opts: DiagnoseOptions, updated_model) -> list:


    files = []
    try:
        files += [Path(p) for p in write_figures(diag, d / "figures")]
    except Exception as e:  # noqa: BLE001 - the engine's own figures are extras; the diagnosis stands
        log.warning("diagnosis figures failed: %s", e)
    files.append(write_text(d / "diagnosed.bdf", write_bdf(_with_loss_factor_notes(to_bulk(diag.model), diag))))
    if H is not None:
        files.append(_frf_overlays(H, model, diag, d, opts.overlay_dofs, updated_model))
    return files


def _with_loss_factor_notes(bulk, diag):
    """``bulk`` with comment cards that give each property group's loss factor in all: a group's GE (its
    ``eta_<group>``) is an offset added to PARAM G (``eta_global``), as Nastran adds them, so the GE on its
    MAT1 alone misleads (it may be negative; the total never is)."""
    totals = {n: v["total"] for n, v in (diag.parameters or {}).items() if isinstance(v, dict) and "total" in v}
    if not totals:
        return bulk
    g = float(diag.model.global_ge or 0.0)
    if "G" in bulk.params:
        bulk.params["G"].comment = list(bulk.params["G"].comment or []) + [
            f"$ PARAM G {g:.4g}: the model-wide loss factor (eta_global); each MAT1 GE below adds to it (the "
            "group's loss factor in all is on its MAT1)"]
    for name, t in totals.items():
        mids = set()                       # the deck's own material ids (the export may renumber them)
        for x in t["properties"]:
            prop = bulk.properties.get(int(x) if str(x).isdigit() else x)
            if prop is not None and getattr(prop, "mid", None) is not None:
                mids.add(prop.mid)
        for mid in sorted(mids):
            card = bulk.materials.get(mid)
            if card is None:
                continue
            ge = float(card.ge or 0.0)
            card.comment = list(card.comment or []) + [
                f"$ {name}: loss factor in all {g + ge:.4g} = PARAM G {g:.4g} + GE {ge:.4g} of this MAT1"]
    return bulk


def _frf_overlays(H, model, diag, d: Path, want, updated_model) -> Path:
    """Measured, nominal, diagnosed (and parameter-updated) FRFs at the chosen DOFs, first reference.

    The measured FRFs keep their exponential window; every model FRF is evaluated where the window puts the
    data, at ``s = iω + β`` (β: the FRF's ``window_beta_per_s``), as the diagnosis itself compares them."""

    measured = {str(r) for r in H.responses}
    wanted = [str(w) for w in want or ()]
    missing = [w for w in wanted if w not in measured]
    resp = [r for r in H.responses if want is None or str(r) in wanted][:4] or H.responses[:4]
    if missing:
        log.warning("FRF overlay: %s not among the measured responses (%s%s); the figure shows %s",
                    ", ".join(missing), ", ".join(sorted(measured)[:8]), ", ..." if len(measured) > 8 else "",
                    ", ".join(str(r) for r in resp))
    ref = H.references[0]
    lines = H.freq_hz[H.freq_hz > 0]
    f = lines[::max(1, len(lines) // 600)]
    beta = float(H.window_beta_per_s)
    curves = {"measured": H.select(responses=resp, references=[ref]).band(f[0], f[-1])}
    models = {"nominal": model, "diagnosed + updated": diag.model}
    if updated_model is not None and Path(updated_model).is_file():
        models["updated (parameters)"] = load_model(updated_model)
    eta = diag.parameters.get("eta_global", {}).get("updated")
    for name, m in models.items():
        try:
            mm = m.copy()
            if eta is not None and not mm.global_ge:      # as the diagnosis fitted it: mounts keep their own GE
                mm = own_loss_exempt(mm)
                mm.global_ge = float(eta)
            curves[name] = mm.frf(f, responses=resp, references=[ref], beta=beta)
        except Exception as e:  # noqa: BLE001 - an overlay curve must not fail the stage
            log.warning("FRF of the %s model failed: %s", name, e)
    return plot_frf_overlays(curves, d / OVERLAY_NAME, responses=resp, reference=ref, beta=beta)
