"""The report of ``modalab run`` at the application level: :func:`build_report` and :func:`embed_png` of the report
stage (:mod:`modalab.app.stages._report`, the one implementation; :func:`modalab.app.stages.report` is the
stage function), and the figures the stages draw for it (:mod:`modalab.app.figures`: :func:`plot_coherence_map`,
:func:`plot_frf_overlays`; the convergence figure is :func:`updating.methods.mci_plots.plot_convergence`, the
MCI maps are the diagnosis engine's, :mod:`updating.diagnosis.report`).
"""
from __future__ import annotations

from modalab.app.figures import plot_coherence_map, plot_frf_overlays
from modalab.app.stages._report import build_report, embed_png

__all__ = ["build_report", "plot_coherence_map", "plot_frf_overlays", "embed_png"]
