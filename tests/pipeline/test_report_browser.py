"""The ``modalab run`` report: one self-contained HTML file, checked in a real headless Chromium.

The run folder is made from synthetic artifacts with the report's own plotting helpers (the end-to-end test
builds a real one); Chromium loads the file from disk with the network off, an injected script checks that
every <img> decoded (naturalWidth > 0) and lists every resource the page fetched, and writes the result into
the DOM, which ``--dump-dom`` prints.  Skipped when Chromium is absent (CI installs it).
"""
from __future__ import annotations

import html as htmlmod
import json
import re
import shutil
import subprocess

import numpy as np
import pytest

from modalab.core import uff
from modalab.core.frf import FRF
from modalab.app.report import build_report, plot_coherence_map, plot_frf_overlays
from updating.methods.mci_plots import plot_convergence
from updating.diagnosis.report import mci_maps_figure

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")

_CHECK = """<script>
window.addEventListener('load', function () {
  var imgs = Array.prototype.slice.call(document.images);
  var res = performance.getEntriesByType('resource').map(function (e) { return e.name; });
  var out = {n: imgs.length,
             bad: imgs.filter(function (i) { return !(i.complete && i.naturalWidth > 0); }).map(function (i) { return i.alt; }),
             widths: imgs.map(function (i) { return i.naturalWidth; }),
             resources: res.filter(function (r) { return r.indexOf('data:') !== 0; })};
  var pre = document.createElement('pre');
  pre.id = 'imgcheck';
  pre.textContent = 'IMGCHECK' + JSON.stringify(out) + 'ENDCHECK';
  document.body.appendChild(pre);
});
</script>"""


def _frf(n_f=200):
    f = np.linspace(0.5, 100, n_f)
    resp = ["1+Z", "2+Z", "3+Z", "4+Z"]
    refs = ["1+Z", "4+Z"]
    wn = np.array([12.0, 37.0, 71.0])
    H = np.zeros((4, 2, n_f), complex)
    rng = np.random.default_rng(3)
    phi = rng.normal(size=(4, 3))
    for r in range(3):
        den = wn[r] ** 2 - f ** 2 + 2j * 0.02 * wn[r] * f
        H += (phi[:, r, None, None] * phi[[0, 3], r][None, :, None]) * (-(2 * np.pi * f) ** 2 / (2 * np.pi) ** 2 / den)
    coh = np.clip(1 - 0.2 * rng.random(H.shape), 0, 1)
    return FRF(freq_hz=f, H=H, responses=resp, references=refs, coherence=coh)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("run")
    frf = _frf()
    (d / "frf").mkdir()
    geo = {1: (0.0, 0.0, 0.0), 2: (0.3, 0.0, 0.0), 3: (0.6, 0.1, 0.0), 4: (0.9, 0.0, 0.05)}
    uff.write_geometry(d / "frf" / "frf.uff", geo)
    uff.write_frf(d / "frf" / "frf.uff", frf, append=True)
    plot_coherence_map(frf, d / "frf" / "coherence.png")
    (d / "frf" / "frf.json").write_text(json.dumps({"responses": 4, "references": ["1+Z", "4+Z"], "lines": 200,
                                                    "band_hz": [0.5, 100.0], "median_coherence": 0.9}))
    (d / "update").mkdir()
    plot_convergence(np.array([[1.0, 1.0], [1.02, 0.98], [1.04, 0.97]]), d / "update" / "convergence.png",
                     names=["E_wing", "t_fin"], normalise=False)
    (d / "update" / "update.json").write_text(json.dumps({"parameters": {
        "E_wing": {"initial": 1.0, "updated": 1.04, "std": 0.01}, "t_fin": {"initial": 1.0, "updated": 0.97, "std": 0.02}},
        "converged": True, "iterations": 2}))
    (d / "diagnose" / "figures").mkdir(parents=True)
    mci_maps_figure({"freq_hz": frf.freq_hz[:50], "responses": frf.responses,
                     "before": np.random.default_rng(1).random((4, 50)),
                     "after": 0.1 * np.random.default_rng(2).random((4, 50))}, d / "diagnose" / "figures" / "mci_maps.png")
    plot_frf_overlays({"measured": frf, "nominal": frf}, d / "diagnose" / "frf_overlay_models.png",
                      responses=frf.responses[:2], reference=frf.references[0])
    (d / "diagnose" / "diagnosis.json").write_text(json.dumps({
        "statement": "The test article carries mass the model leaves out <at> node 4 & more.",
        "findings": [{"physics": "added_mass", "description": "point mass at node 4", "evidence": "real, −ω²",
                      "values": [{"name": "m", "value": 0.08, "std": 0.004, "unit": "kg"}]}],
        "fit": {"nominal": {"frf_error_train": 0.5, "frf_error_held_out": 0.6}}, "ranking": [], "parameters": {}}))
    html, summary = build_report(d, d / "report", title="report test")
    return d, html, summary


def test_report_is_self_contained(run_dir):
    d, html, summary = run_dir
    text = html.read_text(encoding="utf-8")
    # every src/href is a data: URI; no link, script or stylesheet import from elsewhere
    for m in re.finditer(r'(?:src|href)\s*=\s*"([^"]*)"', text):
        assert m.group(1).startswith("data:image/png;base64,"), m.group(1)[:60]
    assert "<script" not in text and "@import" not in text and "url(" not in text
    n_img = text.count("<img ")
    assert n_img == 5           # geometry, coherence, convergence, MCI maps, FRF overlay (others not run)
    # the statement is escaped, not interpreted
    assert "&lt;at&gt; node 4 &amp; more" in text
    s = json.loads(summary.read_text())
    assert s["diagnosis"]["findings"][0]["physics"] == "added_mass"
    assert s["update"]["parameters"]["E_wing"]["updated"] == 1.04
    # sections whose stage did not run say so
    assert "Stabilisation diagram: not available" in text


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (apt-get install chromium)")
def test_report_renders_in_headless_chromium(run_dir, tmp_path):
    d, html, _ = run_dir
    page = tmp_path / "report_checked.html"
    page.write_text(html.read_text(encoding="utf-8").replace("</body>", _CHECK + "</body>"), encoding="utf-8")
    profile = tmp_path / "profile"
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           f"--user-data-dir={profile}", "--virtual-time-budget=5000", "--dump-dom", page.as_uri()]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    m = re.search(r'<pre id="imgcheck">IMGCHECK(.*?)ENDCHECK</pre>', p.stdout, re.S)
    assert m, f"no check marker in the DOM (chromium rc={p.returncode}): {p.stderr[-2000:]}"
    res = json.loads(htmlmod.unescape(m.group(1)))
    assert res["n"] == 5
    assert res["bad"] == [], f"images that did not decode: {res['bad']}"
    assert all(w > 100 for w in res["widths"])
    assert res["resources"] == [], f"the page fetched external resources: {res['resources']}"
    # and a screenshot is not blank
    shot = tmp_path / "shot.png"
    cmd2 = cmd[:-2] + [f"--screenshot={shot}", "--window-size=1200,3000", page.as_uri()]
    subprocess.run(cmd2, capture_output=True, text=True, timeout=120)
    assert shot.is_file() and shot.stat().st_size > 10_000


def test_report_with_null_fit_values_and_std(tmp_path):
    """A diagnosis without held-out DOFs (null FRF error) or a modes-only one (frequency error and MAC, no FRF
    error), and a finding whose uncertainty could not be computed (std null): the report shows "—", never
    a crash and never a number it was not given."""
    d = tmp_path / "run"
    (d / "diagnose").mkdir(parents=True)
    (d / "diagnose" / "diagnosis.json").write_text(json.dumps({
        "statement": "The model misses a mass at node 3.",
        "findings": [{"physics": "added_mass", "description": "point mass at node 3", "evidence": "modes",
                      "values": [{"name": "m", "value": 0.05, "std": None, "unit": "kg"}]}],
        "fit": {"nominal": {"frf_error_train": 0.4, "frf_error_held_out": None},
                "with_physics": {"frf_error_train": None, "frf_error_held_out": None, "freq_error_max_pct": 0.31,
                                 "mac_min": 0.97}},
        "ranking": [], "parameters": {"E": {"initial": 1.0, "updated": 1.01, "std": None}}}))
    html, _ = build_report(d, d / "report", title="nulls")
    text = html.read_text(encoding="utf-8")
    assert "m = 0.05 kg (± not determined by these data)" in text
    assert "largest frequency error [%]" in text and "lowest MAC" in text and ">0.97<" in text
    assert ">None<" not in text and ">—<" in text


def test_a_damaged_stage_output_is_an_error_not_a_missing_stage(tmp_path):
    from modalab.core.errors import ModalabValueError

    d = tmp_path / "run"
    (d / "diagnose").mkdir(parents=True)
    (d / "diagnose" / "diagnosis.json").write_text('{"statement": "cut in the mid')
    with pytest.raises(ModalabValueError, match=r"diagnosis.json' line 1: not valid JSON.*--from diagnose"):
        build_report(d, d / "report", title="damaged")
    assert not (d / "report" / "report.html").exists()
