"""The report's coherence map for outputs of commands run one by one (``modalab frf`` ... ``modalab report .``).

``modalab frf`` writes no coherence map (only ``modalab run``'s frf stage does), so the report of the README's
"Commands in practice" said "(Coherence map: not available)" although frf.uff held the coherence.  Now the
report draws the map from the FRF file, and says in words why there is none when the file holds no coherence
or the report found no FRF file.
"""
from __future__ import annotations

import numpy as np

from modalab.app.report import build_report
from modalab.core import uff
from modalab.core.frf import FRF


def _frf(coherence: bool) -> FRF:
    f = np.linspace(1.0, 100.0, 120)
    H = (-(f ** 2) / (40.0 ** 2 - f ** 2 + 2j * 0.02 * 40.0 * f))[None, None, :] * np.array([[1.0], [0.6]])[:, :, None]
    coh = np.clip(1 - 0.3 * np.random.default_rng(0).random(H.shape), 0, 1) if coherence else None
    return FRF(freq_hz=f, H=H, responses=["1+Z", "2+Z"], references=["1+Z"], coherence=coh)


def _report(tmp_path, frf):
    d = tmp_path / "run"
    (d / "frf").mkdir(parents=True)
    if frf is not None:
        uff.write_frf(d / "frf" / "frf.uff", frf)
    html, _ = build_report(d, tmp_path / "report", title="coherence")
    return html.read_text(encoding="utf-8")


def test_the_map_is_drawn_from_the_frf_file_when_no_stage_drew_it(tmp_path):
    text = _report(tmp_path, _frf(coherence=True))
    assert "not available" not in text.split("<h2>Test overview</h2>")[1].split("<h2>")[0]
    assert "<figcaption>Coherence map</figcaption>" in text
    assert (tmp_path / "report" / "coherence.png").is_file()
    assert text.count('alt="coherence"') == 1


def test_frfs_without_coherence_say_why(tmp_path):
    text = _report(tmp_path, _frf(coherence=False))
    assert "No coherence map: the FRF file frf.uff holds no coherence functions" in text
    assert "estimated from repeated hits" in text and "Coherence map: not available" not in text
    assert not (tmp_path / "report" / "coherence.png").exists()


def test_no_frf_file_says_so(tmp_path):
    text = _report(tmp_path, None)
    assert "No coherence map: no FRF file with this report" in text


def test_a_run_on_a_measured_file_without_coherence_says_why_not_a_blank_figure(tmp_path):
    """``modalab run`` with ``frf_path`` (a measured FRF file) draws a placeholder map for FRFs without
    coherence; the report says why in words instead of embedding it."""
    from modalab.app.figures import plot_coherence_map

    d = tmp_path / "run"
    (d / "frf").mkdir(parents=True)
    frf = _frf(coherence=False)
    uff.write_frf(d / "frf" / "frf.uff", frf)
    plot_coherence_map(frf, d / "frf" / "coherence.png")
    text = build_report(d, tmp_path / "report")[0].read_text(encoding="utf-8")
    assert "No coherence map: the FRF file frf.uff holds no coherence functions" in text
    assert 'alt="coherence"' not in text
