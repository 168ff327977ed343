"""The MCI map figure puts its cells on a true frequency axis (fresh user: log-spaced lines drawn against the
line index with frequency tick labels 0.25, 15, 115, 314, 537, 800 Hz read as a linear axis)."""
from __future__ import annotations

import numpy as np

from updating.diagnosis.report import _line_edges, mci_maps_figure


def test_cells_of_log_spaced_lines_are_centred_on_them_on_a_log_axis():
    f = np.geomspace(0.25, 800.0, 40)
    edges, log_axis = _line_edges(f)
    assert log_axis and edges.size == f.size + 1 and np.all(np.diff(edges) > 0)
    assert np.allclose(np.sqrt(edges[:-1] * edges[1:]), f)          # each line at its cell's geometric centre


def test_a_line_at_zero_gets_a_linear_axis():
    f = np.linspace(0.0, 100.0, 11)
    edges, log_axis = _line_edges(f)
    assert not log_axis and np.allclose(0.5 * (edges[:-1] + edges[1:]), f)


def test_the_figure_axis_spans_the_lines_in_hz(tmp_path):
    import matplotlib
    matplotlib.use("Agg")
    f = np.geomspace(1.0, 500.0, 30)
    rng = np.random.default_rng(0)
    maps = {"freq_hz": f, "responses": ["1+Z", "2+Z"], "before": rng.random((2, 30)) + 0.1,
            "after": rng.random((2, 30)) * 0.1 + 0.01}
    path = mci_maps_figure(maps, tmp_path / "mci.png")
    assert path.stat().st_size > 0
