"""What the report says, from small run folders: which model to use, simulated data, the mode table's units,
the selected terms and the turned-down candidates (issue 14)."""
import json

from modalab.app.stages._report import _mode_table, _selection_html, _which_model, build_report


def _diag(findings):
    return {"statement": "s", "findings": findings, "fit": {}, "parameters": {},
            "ranking": [{"candidate": "spring to ground at 110+Z", "physics": "ground_spring", "explained": 0.09}]}


MASS = {"physics": "added_mass", "description": "point mass at node 218", "evidence": "e", "nodes": [218],
        "values": [{"name": "m", "value": 0.2, "std": 0.01, "unit": "kg"}]}


def test_which_model_follows_the_diagnosis():
    assert _which_model(_diag([MASS]), {"parameters": {}})[0] == "diagnose/diagnosed.bdf"
    assert "parameters-only" in _which_model(_diag([MASS]), {})[1]
    assert _which_model(_diag([]), None)[0] == "diagnose/diagnosed.bdf"
    use, why = _which_model(_diag([]), {"parameters": {}})
    assert use == "update/updated.bdf" and "no missing physics" in why
    assert _which_model(None, {"parameters": {}})[0] == "update/updated.bdf"
    assert _which_model(None, None) is None


def test_mode_table_prints_damping_columns_in_percent_with_a_legend():
    t = _mode_table([{"mode": 1, "freq_hz": 5.2778, "damping_pct": 1.0009, "damping_std": 3.7e-05, "MPD": 0.13,
                      "chi2_ratio": 23.6, "contribution": 0.048}])
    assert "σ ζ [%]" in t and "<td class=\"\">0.0037</td>" in t           # 3.7e-05 as a fraction -> 0.0037 %
    assert "damping_std" not in t
    for head in ("MPD [°]", "χ² ratio [-]", "contribution [0-1]"):
        assert head in t
    assert "mean phase deviation" in t and "noise model explains the scatter" in t and "energy" in t


def test_selection_shows_the_winner_and_why_others_were_turned_down():
    d = _diag([MASS])
    d["decisions"] = [{"decision": "rejected", "candidate": "spring to ground at 110+Z", "physics": "ground_spring",
                       "reason": "held-out error up"},
                      {"decision": "found", "candidate": "point mass at node 218", "physics": "added_mass",
                       "reason": ""}]
    html = "".join(_selection_html(d))
    assert "Selected terms" in html and "point mass at node 218" in html and "not in its top 1" in html
    assert "turned down" in html and "held-out error up" in html
    assert "not recorded" in "".join(_selection_html(_diag([MASS])))


def test_report_of_simulated_data_says_so(tmp_path):
    d = tmp_path / "run"
    (d / "frf").mkdir(parents=True)
    (d / "frf" / "frf.json").write_text(json.dumps({"backend": "sim", "responses": 2, "references": ["1+Z"],
                                                    "lines": 10, "band_hz": [0.0, 10.0], "median_coherence": 1.0}))
    (d / "diagnose").mkdir()
    (d / "diagnose" / "diagnosis.json").write_text(json.dumps(_diag([])))
    html, summary = build_report(d, title="t")
    text = html.read_text(encoding="utf-8")
    assert "<b>Simulated data.</b>" in text and "Model to use: update/updated.bdf" not in text  # no update ran
    s = json.loads(summary.read_text())
    assert s["simulated"] is True and s["backend"] == "sim"
    (d / "frf" / "frf.json").write_text(json.dumps({"backend": "nidaqmx", "responses": 2, "references": ["1+Z"],
                                                    "lines": 10, "band_hz": [0.0, 10.0], "median_coherence": 1.0}))
    html, summary = build_report(d, title="t")
    assert "Simulated data" not in html.read_text(encoding="utf-8")
    assert json.loads(summary.read_text())["simulated"] is False
