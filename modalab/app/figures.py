"""The figures the stages draw for the report of ``modalab run``: :func:`plot_coherence_map` (the frf stage),
:func:`plot_frf_overlays` (the diagnose stage).

The convergence figure is :func:`updating.methods.mci_plots.plot_convergence`, the MCI maps are the diagnosis
engine's (:mod:`updating.diagnosis.report`); the report itself is the report stage,
:mod:`modalab.app.stages._report`.  They write PNG files with matplotlib's object API (no pyplot state, safe
headless).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["plot_coherence_map", "plot_frf_overlays"]


# ----------------------------------------------------------------------------- figures
def _figure(w, h):
    from matplotlib.figure import Figure  # lazy: matplotlib, only when drawing (start-up time)

    return Figure(figsize=(w, h), layout="constrained")


def _save(fig, path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100, metadata={"Software": None})
    return path


def plot_coherence_map(frf, path) -> Path:
    """Coherence per response DOF (rows) and frequency line, one panel per reference."""
    if frf.coherence is None:
        fig = _figure(6, 1.5)
        fig.text(0.5, 0.5, "no coherence in these FRFs", ha="center")
        return _save(fig, path)
    n_in = len(frf.references)
    fig = _figure(7, 1.2 + 0.16 * len(frf.responses) * n_in + 0.5 * n_in)
    axes = fig.subplots(n_in, 1, squeeze=False)[:, 0]
    f = frf.freq_hz
    im = None
    for j, ax in enumerate(axes):
        c = np.asarray(frf.coherence[:, j, :], float)
        im = ax.imshow(c, aspect="auto", origin="lower", vmin=0.0, vmax=1.0, cmap="viridis",
                       extent=(f[0], f[-1], -0.5, len(frf.responses) - 0.5), interpolation="nearest")
        ax.set_yticks(range(len(frf.responses)), [str(r) for r in frf.responses], fontsize=6)
        ax.set_ylabel(f"ref {frf.references[j]}", fontsize=8)
    axes[-1].set_xlabel("frequency [Hz]")
    axes[0].set_title("Coherence per response DOF")
    fig.colorbar(im, ax=list(axes), label="coherence", shrink=0.8)
    return _save(fig, path)


def plot_frf_overlays(curves: dict, path, *, responses, reference, beta: float = 0.0) -> Path:
    """|H| of several FRF sets (name -> FRF) at the given responses and one reference, one panel each;
    ``beta``: the exponential window's decay rate (1/s) the data and the model curves share (in the title)."""
    fig = _figure(7, 2.2 * len(responses) + 0.6)
    axes = fig.subplots(len(responses), 1, squeeze=False)[:, 0]
    styles = {"measured": dict(color="k", lw=1.2), "nominal": dict(color="tab:gray", ls=":", lw=1.2)}
    for ax, r in zip(axes, responses):
        for k, (name, frf) in enumerate(curves.items()):
            try:
                h = frf.get(r, reference)
            except Exception:  # noqa: BLE001 - a curve without this DOF is left out of its panel
                continue
            st = styles.get(name, dict(lw=1.0, ls="--", color=f"C{k + 1}"))
            ax.semilogy(frf.freq_hz, np.abs(h), label=name, **st)
        ax.set_ylabel(f"|H| {r}/{reference}", fontsize=8)
        ax.grid(True, which="both", lw=0.3)
    axes[0].legend(fontsize=7)
    # the window on its own line: on one line the title ran past the figure's edge ("(s = iω +", issue 14)
    axes[0].set_title("FRF overlays (accelerance, m/s²/N)" + (
        f"\nexponential window β = {beta:.3g} 1/s on data and models (s = iω + β)" if beta else ""), fontsize=9)
    axes[-1].set_xlabel("frequency [Hz]")
    return _save(fig, path)
