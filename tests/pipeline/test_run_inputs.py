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
