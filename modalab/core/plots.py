"""Figures of core data: FRF magnitude/phase with coherence, hit previews, geometry.

Every function builds a :class:`matplotlib.figure.Figure` without pyplot (no
display needed, thread-safe) and, given ``path``, saves it there.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .frf import FRF
from .records import TimeRecord

__all__ = ["plot_frf", "plot_hit", "plot_geometry", "save"]


def _figure(w=8.0, h=6.0):
    from matplotlib.figure import Figure  # lazy: matplotlib, only when drawing (start-up time)

    return Figure(figsize=(w, h), layout="constrained")


def save(fig, path) -> Path:
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(p, dpi=110)
    return p


def plot_frf(frf: FRF, pairs=None, *, path=None, max_curves: int = 8, others: dict | None = None, title: str = ""):
    """Magnitude (log), phase and coherence of selected (response, reference) pairs.

    ``others`` maps a label to another FRF drawn dashed on the same pairs (e.g. the exact FRF or a synthesis).
    """
    n_all = frf.n_out * frf.n_in
    if pairs is None:
        pairs = [(r, q) for q in frf.references for r in frf.responses][:max_curves]
    if len(pairs) < n_all:                     # say that the figure shows a part of the set
        title = (title + " — " if title else "") + f"{len(pairs)} of {n_all} FRFs shown"
    has_coh = frf.coherence is not None
    fig = _figure(8.0, 7.5 if has_coh else 6.0)
    axes = fig.subplots(3 if has_coh else 2, 1, sharex=True,
                        gridspec_kw={"height_ratios": [3, 1.5, 1] if has_coh else [3, 1.5]})
    am, ap = axes[0], axes[1]
    for r, q in pairs:
        h = frf.get(r, q)
        line, = am.semilogy(frf.freq_hz, np.abs(h), lw=1.0, label=f"{r} / {q}")
        ap.plot(frf.freq_hz, np.degrees(np.angle(h)), lw=0.8, color=line.get_color())
        for name, other in (others or {}).items():
            try:
                g = other.to(frf.quantity).get(r, q)
            except Exception:  # noqa: BLE001 - a pair missing in the overlay is simply not drawn
                continue
            am.semilogy(other.freq_hz, np.abs(g), ls="--", lw=0.9, color=line.get_color(), alpha=0.8)
        if has_coh:
            i = [d.same_axis(r) for d in frf.responses].index(True)
            j = [d.same_axis(q) for d in frf.references].index(True)
            axes[2].plot(frf.freq_hz, frf.coherence[i, j], lw=0.8, color=line.get_color())
    am.set_ylabel(f"|H| [{frf.units}]")
    ap.set_ylabel("phase [deg]")
    ap.set_yticks([-180, -90, 0, 90, 180])
    if has_coh:
        axes[2].set_ylabel("coherence")
        axes[2].set_ylim(0, 1.05)
    axes[-1].set_xlabel("frequency [Hz]")
    am.legend(fontsize=7, ncol=2, loc="best")
    if others:
        am.set_title((title + "  " if title else "") + "dashed: " + ", ".join(others), fontsize=9)
    elif title:
        am.set_title(title, fontsize=10)
    for a in axes:
        a.grid(True, which="both", alpha=0.3)
    if path is not None:
        save(fig, path)
    return fig


def plot_hit(rec: TimeRecord, *, path=None, title: str = ""):
    """Force trace, force spectrum (bandwidth of the hit) and response traces of one hit."""
    fig = _figure(8.0, 6.5)
    a1, a2, a3 = fig.subplots(3, 1)
    t = rec.t
    for i in rec.force_channels:
        a1.plot(t * 1e3, rec.data[i], lw=0.8, label=f"force {rec.dofs[i]}")
        n = rec.n_samples
        F = np.abs(np.fft.rfft(rec.data[i])) / rec.sample_rate_hz
        f = np.fft.rfftfreq(n, rec.dt)
        ref = F[1:max(2, n // 100)].max() if n > 4 else F.max()
        a2.plot(f, 20 * np.log10(np.maximum(F, 1e-300) / max(ref, 1e-300)), lw=0.8)
    a1.set_xlabel("time [ms]")
    a1.set_ylabel("force [N]")
    a1.legend(fontsize=7)
    a2.axhline(-10, color="k", lw=0.5, ls=":")
    a2.axhline(-20, color="k", lw=0.5, ls=":")
    a2.set_ylim(-60, 6)
    a2.set_xlabel("frequency [Hz]")
    a2.set_ylabel("force spectrum [dB]")
    for i in rec.response_channels:
        a3.plot(t * 1e3, rec.data[i], lw=0.6, label=f"{rec.dofs[i]}{' OVERLOAD' if rec.overload[i] else ''}")
    a3.set_xlabel("time [ms]")                 # one time unit for the force and the responses
    a3.set_ylabel(f"response [{rec.units[rec.response_channels[0]] if rec.response_channels else ''}]")
    a3.legend(fontsize=7, ncol=3)
    if title:
        a1.set_title(title, fontsize=10)
    if path is not None:
        save(fig, path)
    return fig


def plot_geometry(coords: dict, *, dofs=None, path=None, title: str = "", lines=None):
    """3-D view of node coordinates with measured DOFs marked (arrows along their directions)."""
    fig = _figure(7.0, 6.0)
    ax = fig.add_subplot(projection="3d")
    if coords:
        xyz = np.array(list(coords.values()))
        ax.scatter(xyz[:, 0], xyz[:, 1], xyz[:, 2], s=6, c="0.5")
        for a, b in (lines or []):
            if a in coords and b in coords:
                p, q = np.array(coords[a]), np.array(coords[b])
                ax.plot([p[0], q[0]], [p[1], q[1]], [p[2], q[2]], c="0.6", lw=0.8)
        span = max(float(np.ptp(xyz, axis=0).max()), 1e-9)
        for d in dofs or []:
            if d.node in coords and 1 <= d.axis <= 3:
                v = np.zeros(3)
                v[d.axis - 1] = d.sign * 0.06 * span
                p = np.array(coords[d.node])
                ax.quiver(p[0], p[1], p[2], v[0], v[1], v[2], color="C3")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    if title:
        ax.set_title(title, fontsize=10)
    if path is not None:
        save(fig, path)
    return fig
