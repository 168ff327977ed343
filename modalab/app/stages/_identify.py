"""The identify stage: poly-reference PolyMAX identification of FRFs."""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

from modalab.core.errors import ModalabValueError
from modalab.app.outputs import write_json
from modalab.app.stages._common import StageResult, _band, _tuple, check_band_lines
from identification import identify as _identify
from identification import SelectionOptions, edge_resonances
from modalab.core import uff

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class IdentifyOptions:
    """``modalab identify``: band (Hz; default all lines above 0 Hz), highest model order, pole selection
    ('auto', a selection file, or frequencies in Hz), references to use, frequency weighting."""

    band_hz: tuple | None = None
    max_order: int | None = None
    select: object = "auto"
    references: tuple | None = None
    weighting: str | None = None
    reciprocity: bool | None = None       # None: automatic for a roving-hammer export; False: as given
    exp_beta: float | None = None         # the exponential window's decay (1/s) when the file does not say
    force_window: bool = False            # use exp_beta even when the file carries another beta
    band_option: str = "--band"           # how the band was given, for messages: an option or a project key
    band_source: str | None = None        # the file that gave it (a project file), None: the command line
    select_tol: float | None = None       # relative window around each frequency of a manual selection

    def __post_init__(self):
        object.__setattr__(self, "band_hz", _tuple(self.band_hz))
        object.__setattr__(self, "references", _tuple(self.references))
        if isinstance(self.select, list):
            object.__setattr__(self, "select", tuple(self.select))



def _warn_edges(full, H, frf_path, opts: IdentifyOptions = IdentifyOptions()) -> None:
    """Warn for each resonance of the data that an edge of the band cuts (:func:`edge_resonances`); the fix is
    said as the band was given (``--band LO HI``, or ``[identify] band_hz = [LO, HI]`` in the project file)."""
    for r in edge_resonances(full.freq_hz, full.H, (H.freq_hz[0], H.freq_hz[-1])):
        lo, hi = H.freq_hz[0], H.freq_hz[-1]
        fix = ""
        if r["suggest_hz"] is not None:
            new = (r["suggest_hz"], hi) if r["edge"] == "lower" else (lo, r["suggest_hz"])
            fix = (f"; move the edge past it, e.g. --band {new[0]:g} {new[1]:g}" if opts.band_option.startswith("-")
                   else f"; move the edge past it, e.g. {opts.band_option} = [{new[0]:g}, {new[1]:g}]"
                   + (f" in {opts.band_source}" if opts.band_source else ""))
        log.warning("%s: a resonance at %.4g Hz (half-power width %.2g Hz) sits at the band's %s edge %g Hz: the "
                    "band cuts it, so it is not identified and biases its neighbours%s", frf_path, r["freq_hz"],
                    r["width_hz"], r["edge"], r["edge_hz"], fix)


def identify(frf_path, out_uff, opts: IdentifyOptions = IdentifyOptions(), *, json_path=None, plots_dir=None,
             report_path=None) -> StageResult:
    """FRFs in a UFF → modes (UFF 55) by poly-reference PolyMAX (:func:`identification.identify`).

    The FRF file's node coordinates (datasets 2411/15) are written with the modes (dataset 2411), so
    correlate and update can put the test nodes on the model's grids by geometry.

    json_path : ``modes.json`` (schema ``modalab/app/schemas/modes.schema.json``).
    plots_dir : stabilisation diagram, synthesis and AutoMAC figures.
    report_path : ``identification.json`` (settings, stabilisation, timings).
    """


    full = uff.read_frf(frf_path)
    check_band_lines(full, opts.band_hz, frf_path, option=opts.band_option, source=opts.band_source)
    H = _band(full, opts.band_hz)
    if opts.band_hz:
        _warn_edges(full, H, frf_path, opts)
    sel = list(opts.select) if isinstance(opts.select, tuple) else opts.select
    selection = SelectionOptions() if opts.select_tol is None else SelectionOptions(manual_tol=opts.select_tol)
    try:
        modes, rep = _identify(H, max_order=opts.max_order, select=sel,
                               references=list(opts.references) if opts.references else None,
                               weighting=opts.weighting, plots_dir=plots_dir, reciprocity=opts.reciprocity,
                               exp_beta=opts.exp_beta, force_window=opts.force_window, selection=selection)
    except ModalabValueError as e:
        if "SelectionOptions.manual_tol" not in str(e):
            raise
        # the library names its API setting; the command line user reaches it as --select-tol (select_tol)
        raise ModalabValueError(f"{frf_path}: " + str(e).replace(
            "widen SelectionOptions.manual_tol",
            f"widen --select-tol (select_tol in a project; now {selection.manual_tol:g})")) from None
    if modes.n_modes == 0:
        raise ModalabValueError(f"{frf_path}: identification found no modes in "
                                f"{H.freq_hz[0]:g}-{H.freq_hz[-1]:g} Hz; widen the band or raise the model order")
    geometry = uff.read_geometry(frf_path, required=False)
    if geometry:
        # the test geometry travels with the modes, so correlate/update can map test nodes onto model grids
        modes.coordinates = geometry
    out = Path(out_uff)
    out.parent.mkdir(parents=True, exist_ok=True)
    uff.write_modes(out, modes)                # atomic; never over an input (modalab.core._output)
    files = [out]
    if json_path is not None:
        files.append(modes.to_json(json_path, input=frf_path,
                                   extra={"reciprocity": rep.settings["reciprocity"],
                                          "window_correction": rep.settings["window_correction"]}))
    if report_path is not None:
        files.append(write_json(report_path, rep.to_dict()))
    files += [Path(p) for p in rep.figures.values()]
    return StageResult((modes, rep), tuple(files),
                       {"modes": modes.n_modes, "freq_hz": [round(float(f), 3) for f in modes.freq_hz]})
