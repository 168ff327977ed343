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


@pytest.mark.parametrize("old, new, match", [
    ('estimator = "H1"', 'estimator = "H3"', r"\[frf\] estimator = 'H3'; expected one of H1, H2, Hv"),
    ("mac_min = 0.5", "mac_min = 1.5", r"\[correlate\] mac_min = 1.5; expected a value in \[0, 1\]"),
    ("max_findings = 2", 'max_findings = 2\nkinds = ["added_mas"]',
     r"\[diagnose\] kinds: unknown kind of missing physics 'added_mas'; did you mean 'added_mass'\?"),
    ('"218+Z", "200+Z"', '"219+Q", "200+Z"', r"\[report\] frf_dofs: cannot parse DOF label '219\+Q'"),
    ("max_iter = 10", 'max_iter = 10\nregularisation = "lcurv"', r"\[update\] regularisation = 'lcurv'"),
    ("max_order = 24", "max_order = 24\nselect = [12.0, -3.0]", r"\[identify\] select = \[12.0, -3.0\]"),
])
def test_a_bad_value_is_refused_when_the_project_is_read(tmp_path, old, new, match):
    """Every value a stage would refuse is refused before any work, naming the project file, section and key
    (it used to fail only when its stage started, after the acquisition)."""
    from modalab.app.project import load_project

    proj = _project(tmp_path / "p")
    text = proj.read_text()
    assert old in text
    bad = proj.parent / "bad.toml"
    bad.write_text(text.replace(old, new, 1))
    with pytest.raises(PlanError, match=match) as e:
        load_project(bad)
    assert str(bad) in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(PlanError):
        R.run_project(bad, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_a_failed_rerun_keeps_the_earlier_output_and_its_manifest_entry(tmp_path, monkeypatch):
    """A stage that fails on a rerun leaves its earlier complete output (and the stages built on it) as they
    were: the folder and its manifest entry come back, and the next run skips every stage."""
    proj = _project(tmp_path / "p")
    out = tmp_path / "out"

    def fake(stage, fail=False):
        def run(ctx, *a):
            if fail:
                (ctx.dir(stage) / "partial.txt").write_text("half")
                raise PlanError(f"{stage} failed")
            p = ctx.dir(stage) / f"{stage}.txt"
            p.write_text(stage)
            return [p], {"stage": stage}
        return run

    monkeypatch.setattr(R, "stage_acquire", fake("acquire"))
    for s in ("frf", "identify"):
        monkeypatch.setitem(R._RUN, s, fake(s))
    R.run_project(proj, out, until_stage="identify")
    before = (out / "manifest.json").read_text()
    monkeypatch.setitem(R._RUN, "frf", fake("frf", fail=True))
    with pytest.raises(PlanError, match="frf failed"):
        R.run_project(proj, out, until_stage="identify", from_stage="frf")
    assert (out / "frf" / "frf.txt").read_text() == "frf" and not (out / "frf" / "partial.txt").exists()
    assert not (out / ".frf.previous").exists()
    assert R.Manifest(out).entry("frf") == __import__("json").loads(before)["stages"]["frf"]
    monkeypatch.setitem(R._RUN, "frf", fake("frf"))
    res = R.run_project(proj, out, until_stage="identify")
    assert res.status == {"acquire": "skipped", "frf": "skipped", "identify": "skipped", "correlate": "not requested",
                          "update": "not requested", "diagnose": "not requested", "report": "not requested"}
    R.run_project(proj, out, until_stage="identify", from_stage="frf")     # a successful rerun: no folder left aside
    assert sorted(p.name for p in out.iterdir()) == ["acquire", "frf", "identify", "manifest.json"]
