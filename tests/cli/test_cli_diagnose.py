"""``modalab diagnose`` from files: FRFs (both criteria), modes alone (UFF 55), and bad input."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from modalab.core import uff
from modalab.app.cli import main
from modalab.core.modes import ModeSet
from modalab.app.outputs import validate

CASES = Path(__file__).resolve().parents[2] / "examples" / "concealed"


@pytest.mark.parametrize("criterion", ["mci", "frf"])
def test_diagnose_names_the_concealed_mass_from_the_files(tmp_path, criterion, capsys):
    d = CASES / "bar_added_mass"
    out = tmp_path / "diagnosis.json"
    assert main(["diagnose", str(d / "nominal.bdf"), str(d / "measured.uff"), "--json", str(out),
                 "--criterion", criterion]) == 0
    res = json.loads(out.read_text())
    validate(res, "diagnosis")
    truth = json.loads((d / "truth.json").read_text())["concealed"][0]
    assert [f["physics"] for f in res["findings"]] == ["added_mass"]
    f = res["findings"][0]
    assert abs(f["nodes"][0] - truth["nodes"][0]) <= 1
    assert f["values"][0]["unit"] == "kg" and f["values"][0]["value"] == pytest.approx(truth["value"], rel=0.3)
    assert "FINDING added_mass" in capsys.readouterr().out


def test_diagnose_from_modes_alone_reads_uff55(tmp_path):
    sys.path.insert(0, str(CASES))
    try:
        import build as B
    finally:
        sys.path.remove(str(CASES))
    kind, cat, effect, rec = B.CASES["bar_ground_spring"]
    rng = np.random.default_rng(3)
    nominal = B._structures(1)[kind]()
    truth = B._structures(B.REFINE, rng=rng)[kind]()
    effect(truth, B.REFINE)
    ms = truth.modes(6).select_dofs([f"{n}+Z" for n in sorted(nominal.nodes)])
    phi = np.real(ms.shapes) * (1 + 0.01 * np.random.default_rng(4).standard_normal(ms.shapes.shape))
    path = tmp_path / "gvt.uff"
    uff.write_modes(path, ModeSet(freq_hz=ms.freq_hz, shapes=phi, dofs=ms.dofs))
    out = tmp_path / "d.json"
    assert main(["diagnose", str(CASES / "bar_ground_spring" / "nominal.bdf"), "--modes", str(path),
                 "--json", str(out)]) == 0
    res = json.loads(out.read_text())
    assert [(f["physics"], f["dofs"]) for f in res["findings"]] == [("ground_spring", rec["dofs"])]
    assert res["findings"][0]["values"][0]["value"] == pytest.approx(rec["value"], rel=0.3)


def test_diagnose_without_measurements_says_what_to_give(capsys):
    assert main(["diagnose", str(CASES / "bar_control" / "nominal.bdf")]) == 2
    err = capsys.readouterr().err
    assert "MEASURED.uff" in err and "--modes" in err


def test_diagnose_rejects_an_unknown_criterion(capsys):
    with pytest.raises(SystemExit) as e:
        main(["diagnose", "m.bdf", "f.uff", "--criterion", "bic"])
    assert e.value.code == 2
    assert "bic" in capsys.readouterr().err
