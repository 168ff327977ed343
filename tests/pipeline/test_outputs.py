"""The application's one writer (:mod:`modalab.app.outputs`): umask permissions, atomic replace, shipped schemas."""
from __future__ import annotations

import json
import os
import stat

import numpy as np
import pytest

from modalab.app import outputs


@pytest.mark.parametrize("mask", [0o022, 0o077, 0o002])
def test_new_files_honour_the_umask(tmp_path, mask):
    old = os.umask(mask)
    try:
        p = outputs.write_json(tmp_path / "sub" / "x.json", {"a": np.float64(1.5), "b": np.arange(3)})
    finally:
        os.umask(old)
    assert stat.S_IMODE(p.stat().st_mode) == 0o666 & ~mask
    assert json.loads(p.read_text()) == {"a": 1.5, "b": [0, 1, 2]}
    assert [q.name for q in p.parent.iterdir()] == ["x.json"]          # no temporary file left


def test_a_failed_write_keeps_the_old_file(tmp_path):
    p = outputs.write_text(tmp_path / "x.txt", "old")
    with pytest.raises(TypeError):
        outputs.write_bytes(p, "not bytes")
    assert p.read_text() == "old" and [q.name for q in tmp_path.iterdir()] == ["x.txt"]


def test_schemas_ship_and_reject_a_wrong_layout():
    jsonschema = pytest.importorskip("jsonschema")
    for name in outputs.SCHEMAS:
        jsonschema.Draft202012Validator.check_schema(outputs.schema(name))
    good = {"findings": [], "parameters": {"E": {"initial": 1.0, "updated": 1.1, "std": 0.01}},
            "fit": {"nominal": {"frf_error_held_out": 0.1}}, "statement": "Nothing is missing."}
    outputs.validate(good, "diagnosis")
    with pytest.raises(jsonschema.ValidationError, match="statement"):
        outputs.validate({k: v for k, v in good.items() if k != "statement"}, "diagnosis")
    bad = dict(good, findings=[{"physics": "gremlins", "nodes": [1], "dofs": [], "description": "", "values": [],
                                "evidence": ""}])
    with pytest.raises(jsonschema.ValidationError):
        outputs.validate(bad, "diagnosis")
    # the layout run.py wrote before (a bare mode table) is not a modes.json
    with pytest.raises(jsonschema.ValidationError):
        outputs.validate([{"mode": 1, "freq_hz": 10.0, "damping_pct": 1.0}], "modes")
