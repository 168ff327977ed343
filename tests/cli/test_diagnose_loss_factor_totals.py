"""Group loss factors ``eta_<group>`` are offsets from the model-wide ``eta_global`` (PARAM G, to which a MAT1
GE adds): diagnosis.json gives each group's loss factor in all, diagnosed.bdf says it in a comment card on the
group's MAT1, and no group's total is ever negative (issue 14 audit: the offset alone was reported, e.g.
eta_fuselage -1.2e-4, and written as a negative GE without saying what it adds to; then a fitted total below 0
was reported; every fit is now bounded at 0 in all, tests/updating/test_diagnosis_section_damping.py)."""
import json
from pathlib import Path

import pytest

from modalab.app.cli import main
from modalab.app.outputs import validate
from updating.diagnosis.priors import SectionLossFactor, loss_factor_totals
from updating.fe import Parameter
from updating.fe.bulk import read_bdf

CASE = Path(__file__).resolve().parents[2] / "examples" / "concealed" / "stepped_ground_spring"


def _params():
    return [Parameter("E", "E", properties=(1,)), Parameter("eta_global", "global_ge", mode="value"),
            SectionLossFactor("eta_b", "ge", properties=(2,), mode="value")]


def test_totals_add_the_offset_to_the_model_wide_factor():
    assert loss_factor_totals(_params(), [1.0, 0.01, 0.004], None) == {"eta_b": ((2,), pytest.approx(0.014))}
    # without an eta_global parameter, the model's PARAM G
    assert loss_factor_totals(_params()[2:], [-0.003], 0.02)["eta_b"][1] == pytest.approx(0.017)


def test_diagnosis_json_and_the_deck_give_each_groups_total(tmp_path):
    out = tmp_path / "diag"
    assert main(["diagnose", str(CASE / "nominal.bdf"), str(CASE / "measured.uff"), "--report", str(out)]) == 0
    d = json.loads((out / "diagnosis.json").read_text())
    validate(d, "diagnosis")
    pars = d["parameters"]
    groups = [n for n, v in pars.items() if "total" in v]
    assert groups == ["eta_seg2"] and "total" not in pars["eta_global"]
    t = pars["eta_seg2"]["total"]
    assert t["offset_of"] == "eta_global" and t["properties"] == ["2"]
    for key in ("initial", "updated", "parameters_only"):
        assert t[key] == pytest.approx(pars["eta_global"][key] + pars["eta_seg2"][key], rel=1e-12), key
        assert t[key] >= 0, key
    text = (out / "diagnosed.bdf").read_text()
    notes = [ln for ln in text.splitlines() if ln.startswith("$ eta_seg2: loss factor in all")]
    assert len(notes) == 1 and f"{t['updated']:.4g}" in notes[0], notes
    assert any(ln.startswith("$ PARAM G") and "eta_global" in ln for ln in text.splitlines())
    # the deck as written says the same: PARAM G plus the group's MAT1 GE is the reported total
    bulk = read_bdf(out / "diagnosed.bdf")
    g = float(bulk.params["G"].vals[0])
    ge = float(bulk.materials[bulk.properties[2].mid].ge)
    assert g + ge == pytest.approx(t["updated"], rel=1e-9) and g + ge >= 0
    assert g == pytest.approx(pars["eta_global"]["updated"], rel=1e-9)
    # the report's parameter table gives the total beside the offset
    assert main(["report", str(tmp_path)]) == 0
    html = (tmp_path / "report" / "report.html").read_text()
    assert "loss factor in all" in html and "offset added to eta_global" in html
