"""The frf stage: raw hits to H1/H2/Hv FRFs with coherence."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from modalab.core.errors import ModalabValueError, PlanError
from modalab.app.outputs import write_json
from modalab.app.stages._common import StageResult
from modalab.core import uff
from acquisition.reciprocity import reciprocity_check, reorder_by_reciprocity
from acquisition.spectral import estimate_frf_roving
from acquisition.plan import exponential_window
from acquisition.windows import ForceWindow
from modalab.core.plots import plot_frf
from modalab.app.figures import plot_coherence_map


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

    return dict(uff.read_geometry(path, required=False))     # a file without geometry is fine, a damaged one not


def frf(in_uff, out_uff, opts: FRFOptions = FRFOptions(), *, plot_path=None, details_dir=None, exact=None,
        measured: bool = False) -> StageResult:
    """Raw hits in a UFF → H1 (H2, Hv) FRFs + coherence in a UFF; roving-hammer data reordered by reciprocity.

    measured : ``in_uff`` holds FRFs already (a project's measured FRFs): they are copied, with the geometry.
    plot_path : the FRF figure (``exact``: an exact FRF drawn over it).
    details_dir : also write ``frf.json`` (summary), ``reciprocity.json`` and ``coherence.png`` there.

    The FRFs (and ``frf.json``'s ``backend``) say which DAQ took the hits when the records say so: 'sim' (the
    simulated lab, also ``modalab sim``), 'nidaqmx'; None when the file does not say.
    """

    out = Path(out_uff)
    if measured:
        H = uff.read_frf(in_uff)
    else:
        H = _estimate(in_uff, opts)
    out.parent.mkdir(parents=True, exist_ok=True)
    geometry = _geometry(in_uff)
    if geometry:
        uff.write_geometry(out, geometry)
    uff.write_frf(out, H, append=bool(geometry))
    files = [out]
    if plot_path is not None:
        plot_frf(H, path=plot_path, others={"exact": exact} if exact is not None else None,
                 title=f"{H.metadata.get('estimator', opts.estimator)} FRFs")
        files.append(Path(plot_path))
    coh = H.coherence
    summary = {"backend": H.metadata.get("backend"), "responses": len(H.responses), "references": [str(r) for r in H.references], "lines": int(H.n_freq),
               "band_hz": [float(H.freq_hz[0]), float(H.freq_hz[-1])],
               "median_coherence": float(np.nanmedian(coh)) if coh is not None else None}
    if details_dir is not None:
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


    recs = uff.read_records(in_uff)
    if not recs:
        raise ModalabValueError(f"{in_uff}: no time records (dataset 58, function type 1) to turn into FRFs; "
                                "run 'modalab info' to see what the file holds")
    fs = recs[0].sample_rate_hz
    bw = opts.bandwidth_hz
    if bw is not None and not 0 < bw <= fs / 2.56 * (1 + 1e-9):
        # the rule of a test plan (acquisition.plan): lines above fs/2.56 lie in the anti-alias filter's roll-off
        raise PlanError(f"{in_uff}: --bandwidth {bw:g} Hz; expected above 0 and at most fs/2.56 = {fs / 2.56:g} Hz "
                        f"(sample rate {fs:g} Hz: lines above it lie in the anti-alias roll-off); give --bandwidth "
                        f"{fs / 2.56:g} or less, or leave it out")
    fw = ForceWindow(fraction=opts.force_fraction) if opts.force_fraction else None
    ew = exponential_window(opts.exp_beta, opts.exp_end_level)      # the one rule, as for a test plan
    H = estimate_frf_roving(recs, estimator=opts.estimator, force_window=fw, exp_window=ew)
    kinds = {(r.metadata or {}).get("backend") for r in recs}
    if len(kinds) == 1 and None not in kinds:          # every hit says which DAQ took it: the FRFs say so too
        H.metadata["backend"] = kinds.pop()
    elif len(kinds) > 1:
        H.metadata["backend"] = "mixed: " + ", ".join(sorted(str(k) for k in kinds))
    H = H.band(0.0, bw or fs / 2.56)
    if opts.reciprocity and len(H.references) > len(H.responses):
        H = reorder_by_reciprocity(H)
    return H
