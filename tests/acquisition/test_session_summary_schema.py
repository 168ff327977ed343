"""A session folder's ``summary.json`` follows ``modalab/app/schemas/session_summary.schema.json`` (issue 15: every
output file one writer and one schema), on real sessions of the simulated lab: complete, with faults (a skipped
point, rejected hits, a dead channel, a range suggestion), interrupted by the operator and resumed, and resumed
after a damaged hit file.  The file is what the acquire stage returns as its summary, and strict JSON."""
import json
import math

import pytest

from _acq_session_util import accepted_hits, journal, small_plan
from acquisition.plan import load_plan
from acquisition.session import AcquisitionSession, ScriptedPrompter
from modalab.app.outputs import validate
from modalab.app.stages import AcquireOptions, acquire, make_sim_backend

jsonschema = pytest.importorskip("jsonschema")


def _strict(path) -> dict:
    """The file as strict JSON (no NaN or Infinity, which Python's reader would take)."""
    def refuse(name):
        raise AssertionError(f"{path}: {name} is not JSON")
    return json.loads(path.read_text(), parse_constant=refuse)


def _checked(session_dir) -> dict:
    path = session_dir / "summary.json"
    doc = _strict(path)
    validate(path, "session_summary")
    return doc


def test_a_session_with_faults_writes_a_summary_that_follows_the_schema(tmp_path):
    plan = small_plan(tmp_path, points=("14+Z", "19+Z"),
                      sim={"dead": ["acc_1Z"], "faults": {"no_trigger_on": [1, 2, 3], "double_hit_on": [5]}})
    out = tmp_path / "s"
    r = acquire(plan, out, AcquireOptions(auto=True))
    doc = _checked(out)
    assert doc == r.summary == r.result.summary.to_dict()           # the stage's summary is the file
    assert out / "summary.json" in r.files
    p0, p1 = doc["points"]
    assert doc["complete"] and p0["skipped"] and p0["mean_coherence"] is None and p0["channel_coherence"] == {}
    assert p1["accepted"] == 2 and p1["rejected"] >= 1 and "double_hit" in p1["rejected_reasons"]
    assert "dead_channel:acc_1Z" in p1["warnings"] and "acc_1Z" in doc["range_suggestions"]


def test_an_interrupted_and_resumed_session_summary_follows_the_schema(tmp_path):
    plan = small_plan(tmp_path, points=("1+Z", "19+Z"))
    out = tmp_path / "s"
    acquire(plan, out, prompter=ScriptedPrompter("aq"))                   # the operator quits after one hit
    doc = _checked(out)
    assert not doc["complete"] and "resume" in doc["stopped"] and doc["resume"] == []
    assert [(p["accepted"], p["done"], p["mean_coherence"]) for p in doc["points"]] == [(1, False, None),
                                                                                      (0, False, None)]
    acquire(plan, out, AcquireOptions(resume=True), prompter=ScriptedPrompter("a" * 3))
    doc = _checked(out)
    assert doc["complete"] and doc["stopped"] == "" and doc["resume"][0].startswith("recovered 0 of 2 points")
    assert all(p["done"] and 0 <= p["mean_coherence"] <= 1 for p in doc["points"])


def test_a_resume_after_a_damaged_hit_writes_a_summary_that_follows_the_schema(tmp_path):
    plan_path = small_plan(tmp_path, points=("1+Z", "19+Z"))
    out = tmp_path / "s"
    acquire(plan_path, out, AcquireOptions(auto=True))
    _checked(out)
    victim = next(h for h, (p, _) in accepted_hits(journal(out)).items() if p == 1)
    f = out / "hits" / f"hit_{victim:06d}.npz"
    b = bytearray(f.read_bytes())
    b[200] ^= 0xFF
    f.write_bytes(bytes(b))
    plan = load_plan(plan_path)
    AcquisitionSession(plan, make_sim_backend(plan), out, mode="auto", resume=True).run()
    doc = _checked(out)
    assert doc["complete"] and doc["points"][1]["lost"] == 1
    assert any(f"LOST hit {victim}" in d for d in doc["discarded_on_resume"])


def test_the_schema_refuses_a_wrong_layout(tmp_path):
    plan = small_plan(tmp_path, points=("14+Z",))
    out = tmp_path / "s"
    acquire(plan, out, AcquireOptions(auto=True))
    good = _checked(out)
    point = good["points"][0]
    for bad in ({k: v for k, v in good.items() if k != "complete"},          # a key missing
                dict(good, points=[dict(point, taken=-1)]),                   # a negative count
                dict(good, points=[dict(point, mean_coherence=1.5)]),         # a coherence above 1
                dict(good, points=[dict(point, point="14 Z")]),               # not a DOF label
                dict(good, extra=1)):                                         # a key nobody writes
        with pytest.raises(jsonschema.ValidationError):
            validate(bad, "session_summary")
    assert not math.isnan(point["mean_coherence"])
