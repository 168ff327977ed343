"""Correlation figures saved to files: MAC matrix, frequency 45° plot, FRF overlays, COMAC bars.

Every function builds a :class:`matplotlib.figure.Figure` directly (no pyplot
state, safe on headless machines), saves it to ``path`` (format from the
suffix: .png, .pdf, .svg) and returns the path.  :func:`save_correlation_plots`
writes the standard set for a :class:`~updating.correlation.metrics.CorrelationResult`
into a directory (used by ``modalab correlate --plots DIR``).
"""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from modalab.core.errors import ModalabValueError, ShapeError
from modalab.core.frf import FRF

__all__ = ["plot_mac", "plot_frequencies", "plot_frf_overlay", "plot_comac", "save_correlation_plots"]

log = logging.getLogger(__name__)


def _figure(size):
    from matplotlib.figure import Figure  # lazy: matplotlib, only when drawing (start-up time)

    return Figure(figsize=size, layout="constrained")


def _save(fig, path) -> Path:
    p = Path(path)
    if not p.parent.exists():
        raise ModalabValueError(f"cannot save the figure to {str(p)!r}: folder {str(p.parent)!r} does not exist; "
                                "create it first")
    fig.savefig(p, dpi=150)
    log.debug("saved figure %s", p)
    return p


def plot_mac(mac_matrix, path, *, analysis_freq_hz=None, test_freq_hz=None, pairs=None,
             title: str = "MAC: analysis vs test", annotate: bool | None = None) -> Path:
    """MAC matrix as a colour map (analysis modes on rows, test modes on columns), pairs outlined.

    Values are printed in the cells when ``annotate`` is True (default: when at most 15×15).
    """
    from matplotlib.patches import Rectangle  # lazy: matplotlib, only when drawing (start-up time)

    M = np.asarray(mac_matrix, float)
    if M.ndim != 2 or 0 in M.shape:
        raise ShapeError(f"MAC matrix has shape {M.shape}; expected a non-empty (n_analysis, n_test) matrix")
    na, nx = M.shape
    fig = _figure((min(1.6 + 0.45 * nx + 1.5, 16.0), min(1.2 + 0.45 * na + 0.8, 14.0)))
    ax = fig.add_subplot()
    im = ax.imshow(M, vmin=0, vmax=1, cmap="Blues", origin="upper", aspect="auto")
    fig.colorbar(im, ax=ax, label="MAC")

    def labels(n, f):
        return [f"{k + 1}" + (f"\n{f[k]:.4g}" if f is not None else "") for k in range(n)]

    ax.set_xticks(range(nx), labels(nx, test_freq_hz), fontsize=7)
    ax.set_yticks(range(na), labels(na, analysis_freq_hz), fontsize=7)
    ax.set_xlabel("test mode" + (" / Hz" if test_freq_hz is not None else ""))
    ax.set_ylabel("analysis mode" + (" / Hz" if analysis_freq_hz is not None else ""))
    ax.set_title(title)
    if annotate is None:
        annotate = na <= 15 and nx <= 15
    if annotate:
        for i in range(na):
            for j in range(nx):
                ax.text(j, i, f"{M[i, j]:.2f}", ha="center", va="center", fontsize=6,
                        color="white" if M[i, j] > 0.6 else "black")
    for ia, jx in pairs or []:
        ax.add_patch(Rectangle((jx - 0.5, ia - 0.5), 1, 1, fill=False, edgecolor="red", linewidth=1.5))
    return _save(fig, path)


def plot_frequencies(test_freq_hz, analysis_freq_hz, path, *, labels=None, title: str = "Natural frequencies") -> Path:
    """Paired frequencies, analysis against test, with the 45° line (section 2.2.1).

    Both arrays are in pair order (one entry per pair); ``labels`` annotate the points
    (:func:`save_correlation_plots` writes "test/FE" mode numbers).
    """
    fx, fa = np.asarray(test_freq_hz, float), np.asarray(analysis_freq_hz, float)
    if fx.shape != fa.shape or fx.ndim != 1:
        raise ShapeError(f"frequencies have shapes {fx.shape} and {fa.shape}; expected two 1-D arrays in pair order")
    fig = _figure((5, 5))
    ax = fig.add_subplot()
    hi = 1.05 * max(fx.max(initial=0), fa.max(initial=0), 1e-12)
    ax.plot([0, hi], [0, hi], "k-", lw=0.8, label="45° (perfect)")
    for pct in (5, 10):
        ax.plot([0, hi], [0, hi * (1 + pct / 100)], ":", color="0.6", lw=0.6)
        ax.plot([0, hi], [0, hi * (1 - pct / 100)], ":", color="0.6", lw=0.6)
    ax.plot(fx, fa, "o", color="tab:blue", label="pairs" + (" (test/FE mode)" if labels is not None else ""))
    for k in range(fx.size):
        ax.annotate(str(labels[k]) if labels is not None else str(k + 1), (fx[k], fa[k]), fontsize=7,
                    xytext=(3, 3), textcoords="offset points")
    ax.set_xlim(0, hi)
    ax.set_ylim(0, hi)
    ax.set_aspect("equal")
    ax.set_xlabel("test frequency [Hz]")
    ax.set_ylabel("analysis frequency [Hz]")
    ax.set_title(title + " (dotted: ±5 %, ±10 %)")
    ax.legend(loc="upper left", fontsize=8)
    return _save(fig, path)


def plot_frf_overlay(analysis: FRF, test: FRF, path, *, responses=None, reference=None, max_panels: int = 6,
                     title: str = "FRF overlay") -> Path:
    """Magnitudes (log scale) of analysis and test FRFs on the same labels, one panel per response.

    Both FRFs must share the frequency lines and carry the chosen labels (align with
    :func:`updating.correlation.metrics.frf_correlation` first when the labels differ).
    """
    for nm, f in (("analysis", analysis), ("test", test)):
        if not isinstance(f, FRF):
            raise ModalabValueError(f"{nm}: got {type(f).__name__}; expected a modalab.core.frf.FRF")
    resp = list(test.responses if responses is None else responses)[:max_panels]
    ref = test.references[0] if reference is None else reference
    if analysis.quantity != test.quantity:
        analysis = analysis.to(test.quantity)
    fig = _figure((7, 2.4 * len(resp)))
    axes = fig.subplots(len(resp), 1, squeeze=False)[:, 0]
    for ax, r in zip(axes, resp):
        hx = test.get(r, ref)
        ha = analysis.get(r, ref)
        ax.semilogy(test.freq_hz, np.abs(hx), color="tab:blue", lw=1, label="test")
        ax.semilogy(analysis.freq_hz, np.abs(ha), color="tab:red", lw=1, ls="--", label="analysis")
        ax.set_ylabel(f"|H| {r}/{ref}\n[{test.units}]", fontsize=8)
        ax.grid(True, which="both", lw=0.3)
    axes[0].legend(fontsize=8)
    axes[0].set_title(title)
    axes[-1].set_xlabel("frequency [Hz]")
    return _save(fig, path)


def plot_comac(comac_values, dofs, path, *, title: str = "COMAC per DOF", threshold: float | None = 0.8) -> Path:
    """COMAC per DOF as bars; bars below ``threshold`` are highlighted."""
    v = np.asarray(comac_values, float)
    labels = [str(d) for d in dofs]
    if v.ndim != 1 or v.size != len(labels):
        raise ShapeError(f"{v.size} COMAC values for {len(labels)} DOF labels; give one value per DOF")
    fig = _figure((max(5, 0.25 * v.size + 1.5), 3.5))
    ax = fig.add_subplot()
    colors = ["tab:red" if threshold is not None and x < threshold else "tab:blue" for x in v]
    ax.bar(range(v.size), v, color=colors)
    if threshold is not None:
        ax.axhline(threshold, color="k", lw=0.7, ls="--")
    ax.set_xticks(range(v.size), labels, rotation=90, fontsize=6)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("COMAC")
    ax.set_title(title)
    return _save(fig, path)


def save_correlation_plots(result, directory, *, fmt: str = "png") -> dict:
    """Write MAC, frequency and COMAC figures of a CorrelationResult into ``directory``; returns {name: path}."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    out = {"mac": plot_mac(result.mac, d / f"mac.{fmt}", analysis_freq_hz=result.analysis.freq_hz,
                           test_freq_hz=result.test.freq_hz, pairs=result.pairs)}
    if result.pairs:
        ia, jx = result.pairing.analysis_index, result.pairing.test_index
        out["frequencies"] = plot_frequencies(result.test.freq_hz[jx], result.analysis.freq_hz[ia],
                                              d / f"frequencies.{fmt}",
                                              labels=[f"{j + 1}/{i + 1}" for i, j in result.pairs])
        out["comac"] = plot_comac(result.comac, result.test.dofs, d / f"comac.{fmt}")
    return out
