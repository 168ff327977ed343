"""The correlate stage: test modes against the FE model."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..outputs import write_json
from ._common import StageResult, load_model, load_modes


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
