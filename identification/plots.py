"""Figures of the identification: stabilisation diagram, synthesis overlays, AutoMAC.

Every function builds a :class:`matplotlib.figure.Figure` without pyplot and,
given ``path``, saves it there (parent folders are created); it returns the figure.
"""
from __future__ import annotations

import numpy as np

from modalab.core.frf import FRF
from modalab.core.modes import ModeSet
from modalab.core.plots import save
from .indicators import auto_mac, frf_correlation
from .stabilisation import StabilisationDiagram

__all__ = ["plot_stabilisation", "plot_synthesis", "plot_automac"]

_STYLE = {"o": ("o", "0.75", "new"), "f": ("o", "tab:orange", "freq."), "d": ("s", "tab:blue", "freq.+damp."),
          "v": ("^", "tab:purple", "freq.+vector"), "s": ("+", "tab:green", "stable")}


def _figure(w, h):
    from matplotlib.figure import Figure  # lazy: matplotlib, only when drawing (start-up time)

    return Figure(figsize=(w, h), layout="constrained")


def plot_stabilisation(diag: StabilisationDiagram, frf: FRF, *, selected_hz=None, path=None, indicator: str = "cmif",
                       title: str = ""):
    """Stabilisation diagram (model order vs frequency) over the CMIF or the sum of |H|.

    ``indicator``: 'cmif' (singular values of H(ω), log scale) or 'sum' (Σ|H|).
    """
    fig = _figure(10.0, 6.5)
    ax = fig.add_subplot(1, 1, 1)
    lo, hi = frf.freq_hz[0], frf.freq_hz[-1]
    status = diag.status
    inside = (diag.freq_hz >= lo) & (diag.freq_hz <= hi)
    for code in ("o", "f", "d", "v", "s"):
        m = inside & (status == code)
        mk, col, lab = _STYLE[code]
        ax.plot(diag.freq_hz[m], diag.order[m], mk, ms=3.5 if code != "s" else 5, color=col, mfc="none" if code in "od" else col,
                lw=0, label=f"{lab} ({m.sum()})")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("model order")
    ax.set_xlim(lo, hi)
    ax.set_ylim(0, diag.orders.max() + 1 if diag.orders.size else 1)
    if selected_hz is not None:
        for k, f0 in enumerate(np.atleast_1d(selected_hz)):
            ax.axvline(f0, color="tab:red", lw=0.8, ls="--", label="selected" if k == 0 else None)
    ax2 = ax.twinx()
    if indicator == "cmif" and frf.n_in > 0:
        cm = frf.cmif()
        for k in range(cm.shape[0]):
            ax2.semilogy(frf.freq_hz, cm[k], color="k", lw=0.8 if k == 0 else 0.5, alpha=1.0 if k == 0 else 0.5)
        ax2.set_ylabel(f"CMIF [{frf.units}]")
    else:
        ax2.semilogy(frf.freq_hz, frf.real_part_sum(), color="k", lw=0.8)
        ax2.set_ylabel(f"sum |H| [{frf.units}]")
    ax.set_zorder(ax2.get_zorder() + 1)
    ax.patch.set_visible(False)
    ax.legend(loc="upper left", fontsize=7, ncol=3, framealpha=0.8)
    c = diag.criteria
    ax.set_title(title or f"Stabilisation (f {100 * c.freq_tol:g} %, ζ {100 * c.damping_tol:g} %, MAC {c.mac_min:g})")
    if path is not None:
        save(fig, path)
    return fig


def plot_synthesis(frf: FRF, synth: FRF, *, pairs=None, path=None, max_curves: int = 6, title: str = ""):
    """Measured (solid) vs synthesised (dashed) magnitude and phase, with FRAC per curve in the legend."""
    if pairs is None:
        pairs = [(o, i) for i in range(frf.n_in) for o in range(frf.n_out)]
        step = max(1, len(pairs) // max_curves)
        pairs = pairs[::step][:max_curves]
    fig = _figure(9.0, 7.0)
    am, ap = fig.subplots(2, 1, sharex=True, height_ratios=[2, 1])
    corr = frf_correlation(synth.H, frf.H)
    for k, (o, i) in enumerate(pairs):
        col = f"C{k % 10}"
        lab = f"{frf.responses[o]}/{frf.references[i]} (FRAC {corr[o, i]:.3f})"
        am.semilogy(frf.freq_hz, np.abs(frf.H[o, i]), color=col, lw=0.8, label=lab)
        am.semilogy(synth.freq_hz, np.abs(synth.H[o, i]), color=col, lw=1.0, ls="--")
        ap.plot(frf.freq_hz, np.degrees(np.angle(frf.H[o, i])), color=col, lw=0.6)
        ap.plot(synth.freq_hz, np.degrees(np.angle(synth.H[o, i])), color=col, lw=0.8, ls="--")
    am.set_ylabel(f"|H| [{frf.units}]")
    ap.set_ylabel("phase [deg]")
    ap.set_xlabel("frequency [Hz]")
    am.legend(fontsize=7)
    am.set_title(title or "Measured (solid) vs synthesised (dashed)")
    if path is not None:
        save(fig, path)
    return fig


def plot_automac(modes: ModeSet, *, path=None, real: bool = False, title: str = ""):
    """AutoMAC matrix of the (complex or real-approximated) shapes, values annotated."""
    phi = modes.real_shapes if real else modes.shapes
    A = auto_mac(phi) if modes.n_modes else np.zeros((0, 0))
    fig = _figure(6.5, 5.5)
    ax = fig.add_subplot(1, 1, 1)
    im = ax.imshow(A, vmin=0, vmax=1, cmap="viridis", origin="lower")
    fig.colorbar(im, ax=ax, label="MAC")
    labels = [f"{f:.4g}" for f in modes.freq_hz]
    ax.set_xticks(range(len(labels)), labels, rotation=90, fontsize=7)
    ax.set_yticks(range(len(labels)), labels, fontsize=7)
    if len(labels) <= 20:
        for a in range(A.shape[0]):
            for b in range(A.shape[1]):
                ax.text(b, a, f"{A[a, b]:.2f}", ha="center", va="center", fontsize=6,
                        color="k" if A[a, b] > 0.5 else "w")
    ax.set_xlabel("mode [Hz]")
    ax.set_ylabel("mode [Hz]")
    ax.set_title(title or "AutoMAC")
    if path is not None:
        save(fig, path)
    return fig
