"""``modalab run`` never overwrites a project input: inputs are protected for the whole run, and an input lying
in a folder the run replaces is refused before any work."""
from __future__ import annotations

import pytest

import modalab.app.run as R
from modalab.app.demo_project import DEMO_FILES, demo_project_dir
from modalab.core.errors import OutputError, PlanError
from modalab.app.outputs import write_text


def _project(d):
    d.mkdir(parents=True)
    for name in DEMO_FILES:
        (d / name).write_bytes((demo_project_dir() / name).read_bytes())
    return d / "project_quick.toml"


def test_an_input_inside_a_stage_folder_is_refused_before_any_work(tmp_path):
    out = tmp_path / "out"
    proj = _project(out / "frf")                     # the project (and its inputs) inside OUT/frf
    before = {p: p.read_bytes() for p in proj.parent.iterdir()}
    with pytest.raises(PlanError, match="an output never overwrites an input"):
        R.run_project(proj, out)
    assert {p: p.read_bytes() for p in proj.parent.iterdir()} == before
    assert not (out / "manifest.json").exists() and not (out / "acquire").exists()


def test_a_stage_writing_over_an_input_is_stopped(tmp_path, monkeypatch):
    proj = _project(tmp_path / "p")
    bulk = proj.parent / "nominal.bdf"
    text = bulk.read_text()

    def rogue_acquire(ctx, resume):                  # a stage that would write its output over the model
        write_text(ctx.project.bulk_path, "overwritten")
        return [], {}

    monkeypatch.setattr(R, "stage_acquire", rogue_acquire)
    with pytest.raises(OutputError, match="is an input of this command"):
        R.run_project(proj, tmp_path / "out", until_stage="acquire")
    assert bulk.read_text() == text


@pytest.mark.parametrize("own_band", [True, False])
def test_the_diagnose_stage_gets_the_band(tmp_path, monkeypatch, own_band):
    """[diagnose] band_hz reaches the diagnose stage; without it, the identification band does."""
    from modalab.app.project import load_project

    proj = load_project(_project(tmp_path / "p"))
    proj.options["identify"]["band_hz"] = [3.0, 70.0]
    proj.options["diagnose"]["band_hz"] = [2.0, 80.0] if own_band else None
    seen = {}

    def fake_diagnose(model_path, *, opts, **kw):
        seen["band"] = opts.band_hz
        return type("R", (), {"files": (), "summary": {}})()

    monkeypatch.setattr(R.stages, "diagnose", fake_diagnose)
    R.stage_diagnose(R._Context(proj, tmp_path / "out", "sim", None))
    assert seen["band"] == ((2.0, 80.0) if own_band else (3.0, 70.0))
