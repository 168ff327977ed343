"""Figures of a diagnosis: MCI maps before/after, FRF overlays at the located DOFs, frequency table.

All figures are built with :class:`matplotlib.figure.Figure` (no pyplot state, Agg-safe) and saved as
PNG files; :func:`write_figures` writes all of them for a :class:`~updating.diagnosis.Diagnosis`.
"""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)
__all__ = ["mci_maps_figure", "frf_overlay_figure", "frequency_table_figure", "write_figures"]


def _figure(w=8.0, h=5.0):
    from matplotlib.figure import Figure  # lazy: matplotlib, only when drawing (start-up time)
    return Figure(figsize=(w, h), constrained_layout=True)


def _line_edges(f: np.ndarray) -> tuple[np.ndarray, bool]:
    """Cell edges of the lines ``f`` on a true frequency axis, and whether that axis is logarithmic: the
    diagnosis' lines are often log-spaced, so each cell spans the geometric midpoints of its neighbours (the
    arithmetic ones when a line is at or below 0 Hz).  A single line gets a cell of ±1 %."""
    if f.size == 1:
        return np.array([0.99, 1.01]) * f[0] if f[0] > 0 else np.array([f[0] - 0.5, f[0] + 0.5]), f[0] > 0
    if np.all(f > 0):
        g = np.log(f)
        mid = 0.5 * (g[1:] + g[:-1])
        return np.exp(np.concatenate([[2 * g[0] - mid[0]], mid, [2 * g[-1] - mid[-1]]])), True
    mid = 0.5 * (f[1:] + f[:-1])
    return np.concatenate([[2 * f[0] - mid[0]], mid, [2 * f[-1] - mid[-1]]]), False


def mci_maps_figure(maps: dict, path) -> Path:
    """Condensed force residual (MCI, thesis eq. 3.89) per measured DOF and line, after parameter updating
    (before) and with the added physics (after), on a common log colour scale."""
    from matplotlib.colors import LogNorm  # lazy: matplotlib, only when drawing (start-up time)
    fig = _figure(10, 4.5)
    before, after = np.asarray(maps["before"]), np.asarray(maps["after"])
    vmax = max(float(np.max(before)), float(np.max(after)), 1e-300)
    vmin = max(vmax * 1e-4, min(float(np.min(before[before > 0], initial=vmax)),
                                float(np.min(after[after > 0], initial=vmax))))
    f = np.asarray(maps["freq_hz"], float)
    edges, log_axis = _line_edges(f)
    axes = fig.subplots(1, 2, sharey=True)
    for ax, data, title in ((axes[0], before, "parameters only"), (axes[1], after, "with physics")):
        im = ax.pcolormesh(edges, np.arange(len(maps["responses"]) + 1) - 0.5,
                           np.clip(data, vmin, None), norm=LogNorm(vmin=vmin, vmax=vmax), shading="flat")
        if log_axis:
            ax.set_xscale("log")
        ax.set_xlim(edges[0], edges[-1])
        ax.set_xlabel("frequency (Hz), log scale" if log_axis else "frequency (Hz)")
        ax.set_title(f"MCI, {title}")
    axes[0].set_yticks(np.arange(len(maps["responses"])), maps["responses"])
    axes[0].set_ylabel("measured DOF")
    fig.colorbar(im, ax=axes, label="|MCI| / σ (weighted)")
    path = Path(path)
    fig.savefig(path, dpi=110)
    return path


def frf_overlay_figure(curves: dict, path) -> Path:
    """|H| of the measured data and of the nominal, parameters-only and augmented models at the located DOFs."""
    pairs = curves["pairs"]
    n = max(len(pairs), 1)
    fig = _figure(8, 2.6 * n)
    axes = np.atleast_1d(fig.subplots(n, 1, sharex=True))
    f = np.asarray(curves["freq_hz"])
    style = {"measured": dict(color="k", lw=0, marker=".", ms=3), "nominal": dict(color="0.6", lw=1),
             "parameters_only": dict(color="tab:blue", lw=1), "with_physics": dict(color="tab:red", lw=1.2)}
    for ax, (label, H) in zip(axes, pairs):
        for key, h in H.items():
            ax.semilogy(f, np.abs(h), label=key.replace("_", " "), **style.get(key, {}))
        ax.set_ylabel("|receptance| (m/N)")
        ax.set_title(label, fontsize=9)
    axes[0].legend(fontsize=8, ncol=4)
    axes[-1].set_xlabel("frequency (Hz)")
    path = Path(path)
    fig.savefig(path, dpi=110)
    return path


def frequency_table_figure(freqs: dict, path) -> Path:
    """Natural frequencies (Hz) of the test and the three models (MAC-paired with the test modes), errors in %."""
    test = freqs.get("test") or []
    cols = ["nominal", "parameters_only", "with_physics"]
    n = max([len(test)] + [len(freqs.get(c) or []) for c in cols])
    rows = []
    for i in range(n):
        t = test[i] if i < len(test) else None
        row = [str(i + 1), f"{t:.3f}" if t is not None else "-"]
        for c in cols:
            v = (freqs.get(c) or [])
            if i < len(v) and v[i] is not None:
                row.append(f"{v[i]:.3f}" + (f" ({100 * (v[i] - t) / t:+.1f} %)" if t else ""))
            else:
                row.append("-")
        rows.append(row)
    fig = _figure(8, 0.35 * (n + 2) + 0.5)
    ax = fig.subplots()
    ax.axis("off")
    tab = ax.table(cellText=rows or [["-"] * 5], colLabels=["mode", "test (Hz)", "nominal", "parameters only",
                                                              "with physics"], loc="center")
    tab.auto_set_font_size(False)
    tab.set_fontsize(8)
    path = Path(path)
    fig.savefig(path, dpi=110)
    return path


def write_figures(diag, directory) -> list:
    """All figures of ``diag`` into ``directory``; returns the paths written."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    out = []
    if diag.maps:
        out.append(mci_maps_figure(diag.maps, d / "mci_maps.png"))
    if getattr(diag, "curves", None):
        out.append(frf_overlay_figure(diag.curves, d / "frf_overlay.png"))
    if getattr(diag, "frequencies", None):
        out.append(frequency_table_figure(diag.frequencies, d / "frequencies.png"))
    return out
