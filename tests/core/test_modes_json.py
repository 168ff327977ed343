"""``modes.json``: one layout, one writer (:meth:`ModeSet.to_json`), one schema (``modes.schema.json``)."""
import ast
import json
import pathlib

import numpy as np
import pytest

from identification import modal_system, noisy_frf
from modalab.app import outputs, stages
from modalab.core import uff
from modalab.core.modes import ModeSet

ROOT = pathlib.Path(__file__).resolve().parents[2]
jsonschema = pytest.importorskip("jsonschema")


def _modes(freq=(12.5, 40.0), dofs=("12+Z", "12-RX", "1001+Y")):
    rng = np.random.default_rng(3)
    n, m = len(dofs), len(freq)
    return ModeSet(freq_hz=freq, damping=np.linspace(0.01, 0.02, m),
                   shapes=rng.normal(size=(n, m)) + 1j * rng.normal(size=(n, m)), dofs=dofs,
                   participation=rng.normal(size=(1, m)) + 0j, references=[dofs[0]], scaling="unit_modal_mass",
                   indicators={"MPC": np.linspace(0.9, 0.99, m), "damping_std": np.full(m, 1e-4)},
                   metadata={"n_orders": np.int64(40)}, freq_cov=np.diag(np.full(m, 0.01)),
                   coordinates={12: (0.0, 0.1, 0.2), 1001: (1.0, 0.0, 0.0)})


def test_round_trip_keeps_every_field(tmp_path):
    ms = _modes()
    p = ms.to_json(tmp_path / "modes.json", input="frf.uff", extra={"window_correction": {"beta_per_s": 0.0}})
    back = ModeSet.from_json(p)
    np.testing.assert_array_equal(back.freq_hz, ms.freq_hz)
    np.testing.assert_array_equal(back.damping, ms.damping)
    np.testing.assert_array_equal(back.shapes, ms.shapes)
    np.testing.assert_array_equal(back.participation, ms.participation)
    np.testing.assert_array_equal(back.freq_cov, ms.freq_cov)
    assert [str(d) for d in back.dofs] == ["12+Z", "12-RX", "1001+Y"]
    assert back.references == ms.references and back.scaling == "unit_modal_mass"
    assert back.coordinates == ms.coordinates and back.metadata == {"n_orders": 40}
    np.testing.assert_array_equal(back.indicators["MPC"], ms.indicators["MPC"])
    doc = json.loads(p.read_text())
    assert doc["input"] == "frf.uff" and doc["window_correction"] == {"beta_per_s": 0.0}
    assert doc["table"] == ms.table()
    assert doc["table"][1] == {"mode": 2, "freq_hz": 40.0, "damping_pct": pytest.approx(2.0), "MPC": 0.99,
                               "damping_std": 1e-4}
    outputs.validate(p, "modes")


def test_extra_cannot_replace_the_mode_set(tmp_path):
    with pytest.raises(ValueError, match="freq_hz"):
        _modes().to_json(tmp_path / "m.json", extra={"freq_hz": [1.0]})
    assert not (tmp_path / "m.json").exists()


def test_a_rigid_body_mode_and_every_dof_label_validate(tmp_path):
    ms = _modes(freq=(0.0, 7.0), dofs=("12+Z", "12-RX", "1001+Y", "7", "3-RZ"))
    outputs.validate(ms.to_json(tmp_path / "modes.json"), "modes")
    doc = json.loads((tmp_path / "modes.json").read_text())
    assert doc["table"][0]["freq_hz"] == 0.0 and doc["input"] is None
    # the schema still refuses what is not a modes.json: a bad label, a negative frequency
    for bad in (dict(doc, dofs=["12+Q", "1+X", "2+X", "3+X", "4+X"]), dict(doc, dofs=["-12+Z"] + doc["dofs"][1:]),
                dict(doc, table=[dict(doc["table"][0], freq_hz=-1.0)])):
        with pytest.raises(jsonschema.ValidationError):
            outputs.validate(bad, "modes")


def test_the_identify_stage_writes_modes_json_with_the_one_writer(tmp_path, monkeypatch):
    mm, _ = modal_system([30.0, 75.0], [0.01, 0.02], 4, rng=1)
    frf = noisy_frf(mm, np.linspace(1.0, 120.0, 600), [mm.dofs[0]], noise=0.002, rng=2)
    uff.write_frf(tmp_path / "frf.uff", frf)
    calls = []
    real = ModeSet.to_json
    monkeypatch.setattr(ModeSet, "to_json", lambda self, *a, **k: calls.append(a) or real(self, *a, **k))
    r = stages.identify(tmp_path / "frf.uff", tmp_path / "modes.uff", stages.IdentifyOptions(max_order=20),
                        json_path=tmp_path / "modes.json")
    assert calls == [(tmp_path / "modes.json",)]
    outputs.validate(tmp_path / "modes.json", "modes")
    doc = json.loads((tmp_path / "modes.json").read_text())
    assert doc["input"] == str(tmp_path / "frf.uff") and {"reciprocity", "window_correction"} <= set(doc)
    np.testing.assert_allclose(ModeSet.from_json(tmp_path / "modes.json").freq_hz, r.result[0].freq_hz)


def test_no_other_code_writes_the_modes_json_layout():
    """Only ModeSet.to_json builds a document with the modes.json keys ``input`` and ``table`` (``modalab info``'s
    summary of a UFF has a ``table`` but no ``input``)."""
    found = []
    for pkg in ("modalab", "acquisition", "identification", "updating", "hardware_sim"):
        for p in sorted((ROOT / pkg).rglob("*.py")):
            for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
                keys = {k.value for k in getattr(node, "keys", ()) if isinstance(k, ast.Constant)}
                if isinstance(node, ast.Dict) and {"input", "table"} <= keys:
                    found.append(f"{p.relative_to(ROOT)}:{node.lineno}")
    assert found == ["modalab/core/modes.py:" + str(_line_of_to_json_doc())], found


def _line_of_to_json_doc():
    src = (ROOT / "modalab/core/modes.py").read_text(encoding="utf-8").splitlines()
    return next(i for i, s in enumerate(src, 1) if '"table": self.table()' in s)
