"""Figures say what they show (issue 14, ux14 item 11): a partial FRF set says so, one time unit per hit figure,
the overlay title stays inside the figure."""
import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402

from modalab.app.report import plot_frf_overlays  # noqa: E402
from modalab.core.frf import FRF  # noqa: E402
from modalab.core.plots import plot_frf, plot_hit  # noqa: E402
from modalab.core.records import TimeRecord  # noqa: E402


def _frf(n_out, n_in):
    f = np.arange(1, 51) * 2.0
    H = 1.0 / (1 + 1j * f[None, None, :] / 30.0) * np.ones((n_out, n_in, 1))
    return FRF(freq_hz=f, H=H, responses=[f"{j + 1}+Z" for j in range(n_out)],
               references=[f"{100 + j}+Z" for j in range(n_in)])


def test_a_partial_frf_figure_says_how_many_it_shows():
    fig = plot_frf(_frf(11, 3))
    assert fig.axes[0].get_title().endswith("8 of 33 FRFs shown")
    assert "shown" not in plot_frf(_frf(2, 2)).axes[0].get_title()


def test_a_hit_figure_uses_one_time_unit():
    rng = np.random.default_rng(0)
    rec = TimeRecord(sample_rate_hz=1024.0, data=rng.normal(size=(2, 256)), dofs=["1+Z", "2+Z"],
                     roles=["force", "response"], units=["N", "m/s^2"], sensitivity=[0.00225, 0.0101])
    fig = plot_hit(rec)
    assert fig.axes[0].get_xlabel() == fig.axes[2].get_xlabel() == "time [ms]"


def test_the_overlay_title_fits_in_the_figure(monkeypatch):
    from modalab.app import figures

    monkeypatch.setattr(figures, "_save", lambda fig, path: fig)        # keep the figure to measure its title
    f = np.arange(1, 401) * 2.0
    H = (1e-3 + 10.0 / np.abs(1 - (f / 120.0) ** 2 + 0.02j))[None, None, :] * np.ones((4, 1, 1))
    curves = {"measured": FRF(freq_hz=f, H=H, responses=["1+Z", "3+Z", "4+Z", "5+Z"], references=["19+Z"])}
    fig = plot_frf_overlays(curves, None, responses=["1+Z", "3+Z", "4+Z", "5+Z"], reference="19+Z", beta=1.17)
    t = fig.axes[0].title
    assert "(s = iω + β)" in t.get_text()
    fig.canvas.draw()
    box = t.get_window_extent()
    assert box.x0 >= 0 and box.x1 <= fig.bbox.x1, (box, fig.bbox)
