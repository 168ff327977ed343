"""Mistakes a new user makes on purpose (issue 14's README walk): each is one clear line, exit code 2, with the
closest valid choice when there is one; and what the help says is what the code does."""
import sys
import tomllib
from pathlib import Path

import pytest

from modalab.app.cli import QUICK_HELP, build_parser, first_hit_path, main

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "examples" / "demo_project"


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("argv, flag", [
    (["update", "MODEL", "--modes", "m.json", "-o", "updated.bdf"], "-o 'updated.bdf'"),
    (["diagnose", "MODEL", "--modes", "m.uff", "--report", "diag.json"], "--report 'diag.json'"),
    (["run", "PROJECT", "-o", "out.html"], "-o 'out.html'"),
    (["acquire", "PLAN", "--auto", "-o", "session.uff"], "-o 'session.uff'"),
    (["identify", "f.uff", "--band", "5", "50", "-o", "m.uff", "--plots", "plots.png"], "--plots 'plots.png'"),
    (["sim", "-o", "h.uff", "--export-model", "model.bdf"], "--export-model 'model.bdf'"),
])
def test_a_folder_output_named_like_a_file_is_refused(tmp_path, monkeypatch, capsys, argv, flag):
    monkeypatch.chdir(tmp_path)
    argv = [str(DEMO / "nominal.bdf") if x == "MODEL" else str(DEMO / "project_quick.toml") if x == "PROJECT"
            else str(DEMO / "plan_quick.toml") if x == "PLAN" else x for x in argv]
    assert main(argv) == 2
    err = _one_line(capsys)
    assert flag in err and "looks like a" in err and "give a folder name" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == []          # nothing created


@pytest.mark.parametrize("argv, wrong, meant", [
    (["frf", "--exp_end", "0.01", "h.uff", "-o", "x.uff"], "--exp_end", "--exp-end"),
    (["identify", "f.uff", "-o", "m.uff", "--max_order", "30"], "--max_order", "--max-order"),
    (["update", "m.bdf", "--modes", "m.uff", "-o", "u", "--max-itre", "3"], "--max-itre", "--max-iter"),
    (["diagnose", "m.bdf", "f.uff", "--critrion", "mci"], "--critrion", "--criterion"),
])
def test_an_unknown_option_names_the_command_and_the_closest_option(capsys, argv, wrong, meant):
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert f"modalab {argv[0]}: error: unrecognized argument(s): {wrong} (did you mean {meant}?)" in err
    assert len(err.strip().splitlines()) == 1 and "usage:" not in err   # one line, not the usage (issue 14)


def test_kinds_take_comma_and_space_lists_and_name_each_misspelt_item():
    from modalab.app._cli_diagnose import parse_kinds
    from modalab.core.errors import PlanError

    assert parse_kinds(["added_mass,ground_spring"]) == ("added_mass", "ground_spring")
    assert parse_kinds(["added_mass", "ground_spring,", "local_damping"]) == ("added_mass", "ground_spring",
                                                                             "local_damping")
    with pytest.raises(PlanError) as e:
        parse_kinds(["added_mass,ground_sprng", "joint"])
    msg = str(e.value)
    assert "ground_sprng (did you mean ground_spring?)" in msg and "joint (did you mean joint_flexibility?)" in msg
    assert "added_mass (" not in msg


@pytest.mark.parametrize("edit, expect", [
    (lambda t: t.replace("[identify]", "[identfy]"), "unknown section [identfy] (did you mean [identify]?)"),
    (lambda t: t.replace("max_order =", "max_ordr ="), "[identify] unknown key max_ordr (did you mean max_order?)"),
])
def test_project_typos_suggest_the_closest_name_without_python_reprs(tmp_path, edit, expect):
    from modalab.app.project import load_project
    from modalab.core.errors import PlanError

    p = tmp_path / "project.toml"
    p.write_text(edit((DEMO / "project_quick.toml").read_text()))
    with pytest.raises(PlanError) as e:
        load_project(p)
    assert expect in str(e.value)
    assert "['" not in str(e.value) and "{'" not in str(e.value)


def test_a_refused_resume_names_the_changed_keys_only(tmp_path, capsys):
    sys.path.insert(0, str(ROOT / "tests" / "acquisition"))
    from _acq_session_util import small_plan

    out = tmp_path / "s"
    plan = small_plan(tmp_path, points=("14+Z",), averages=2)
    assert main(["acquire", str(plan), "--auto", "--quiet", "-o", str(out)]) == 0
    # no --backend: the simulated lab, said on screen and recorded with the data
    assert "backend: sim - the simulated lab (hardware_sim): the data are SIMULATED" in capsys.readouterr().out
    import json

    assert json.loads((out / "session.json").read_text())["backend"] == "sim"
    from modalab.core import uff

    assert uff.read_frf(out / "session.uff").metadata["backend"] == "sim"
    assert all(r.metadata.get("backend") == "sim" for r in uff.read_records(out / "session.uff"))
    plan = small_plan(tmp_path, points=("14+Z",), averages=3, name="plan2.toml")
    assert main(["acquire", str(plan), "--auto", "--quiet", "--resume", "-o", str(out)]) == 2
    err = _one_line(capsys)
    assert "acquisition.averages 2 -> 3" in err
    assert "{'" not in err and "record_s" not in err                 # only what changed, no dict dumps


def test_update_prints_parameters_with_the_digits_of_the_change():
    from modalab.app._cli_update import parameter_change

    assert parameter_change(1.0, 1.0000291, 2.91e-05) == "1 -> 1.000029 (+0.00291 %) ± 2.91e-05"
    assert parameter_change(1.0, 1.09, 0.01) == "1 -> 1.09 (+9 %) ± 0.01"
    assert parameter_change(2.1e11, 2.1e11, None) == "2.1e+11 -> 2.1e+11 (+0 %)"


def test_quick_means_the_same_in_help_readme_and_the_demo_files():
    help_text = build_parser()._subparsers._group_actions[0].choices["demo"].format_help()
    assert " ".join(QUICK_HELP.split()[:6]) in " ".join(help_text.split())
    readme = " ".join((ROOT / "README.md").read_text().split())
    assert "2 accepted averages per point instead of 3" in readme and "fewer points" not in readme
    full, quick = (tomllib.loads((DEMO / n).read_text()) for n in ("plan.toml", "plan_quick.toml"))
    assert full["roving"]["points"] == quick["roving"]["points"]                    # same points
    assert (full["acquisition"]["averages"], quick["acquisition"]["averages"]) == (3, 2)
    assert (full["acquisition"]["max_hits"], quick["acquisition"]["max_hits"]) == (4, 3)
    pf, pq = (tomllib.loads((DEMO / n).read_text()) for n in ("project.toml", "project_quick.toml"))
    assert (pf["identify"]["max_order"], pq["identify"]["max_order"]) == (40, 24)
    assert (pf["update"]["max_iter"], pq["update"]["max_iter"]) == (20, 10)
    for n in ("40", "24", "20", "10", "3", "4"):
        assert n in QUICK_HELP


def test_sim_writes_its_figure_next_to_the_output_and_says_so(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "run" / "h.uff"
    assert main(["sim", "-o", str(out), "--points", "1+Z", "--hits", "1", "--samples", "1024"]) == 0
    assert first_hit_path(out) == tmp_path / "run" / "h_first_hit.png"
    assert first_hit_path(out).is_file() and not (tmp_path / "first_hit.png").exists()
    assert f"first hit (force and responses against time): {first_hit_path(out)}" in capsys.readouterr().out
    assert main(["sim", "-o", str(tmp_path / "q.uff"), "--points", "1+Z", "--hits", "1", "--samples", "1024",
                 "--no-plot"]) == 0
    assert not first_hit_path(tmp_path / "q.uff").exists()
    assert "hits_first_hit.png" in (ROOT / "README.md").read_text()


def test_wrong_kinds_of_file_are_named(tmp_path, capsys):
    (tmp_path / "params.toml").write_text((DEMO / "params.toml").read_text())
    (tmp_path / "modes.json").write_text('{"modes": []}')
    assert main(["correlate", str(tmp_path / "params.toml"), str(tmp_path / "modes.json")]) == 2
    err = _one_line(capsys)
    assert "is a TOML file" in err and "Nastran bulk data" in err
    assert main(["correlate", str(DEMO / "nominal.bdf"), str(DEMO / "nominal.bdf")]) == 2
    err = _one_line(capsys)
    assert "is Nastran bulk data" in err and "test modes" in err
    from modalab.app.stages._common import sniff_kind

    assert [sniff_kind(DEMO / n) for n in ("plan.toml", "project.toml", "params.toml", "nominal.bdf")] == \
        ["toml", "toml", "toml", "bulk"]


@pytest.fixture(scope="module")
def small_frf(tmp_path_factory):
    """A small FRF file (0-800 Hz) from a one-point simulated test."""
    d = tmp_path_factory.mktemp("frf")
    assert main(["sim", "-o", str(d / "h.uff"), "--points", "1+Z", "--hits", "1", "--samples", "2048",
                 "--no-plot"]) == 0
    assert main(["frf", str(d / "h.uff"), "-o", str(d / "f.uff"), "--no-plot"]) == 0
    return d / "f.uff"


def test_identify_band_beyond_the_data_is_clipped_with_a_warning_or_refused(small_frf, tmp_path, capsys):
    from modalab.core import uff

    f = uff.read_frf(small_frf).freq_hz
    capsys.readouterr()
    assert main(["identify", str(small_frf), "--band", str(f[-1] + 500), str(f[-1] + 4000), "-o",
                 str(tmp_path / "x.uff")]) == 2
    err = _one_line(capsys)
    assert f"the data spans {f[0]:.4g}..{f[-1]:.4g} Hz" in err and not (tmp_path / "x.uff").exists()
    # clipped: a warning naming the data's range, as a user reads it (no module path)
    from modalab.app.stages._common import _band
    import logging

    records = []

    class _H(logging.Handler):
        def emit(self, r):
            records.append(r)

    h = _H()
    logging.getLogger("modalab").addHandler(h)
    try:
        H = _band(uff.read_frf(small_frf), (5.0, 5000.0))
    finally:
        logging.getLogger("modalab").removeHandler(h)
    assert H.freq_hz[0] >= 5.0 and H.freq_hz[-1] == f[-1]
    assert [r.getMessage() for r in records] == [
        f"band 5-5000 Hz reaches beyond the data ({f[0]:g}-{f[-1]:g} Hz); using 5-{f[-1]:g} Hz"]


def test_warnings_read_as_warnings_and_module_paths_only_with_verbose():
    import logging

    from modalab.app.cli import _LogFormatter

    rec = logging.LogRecord("updating.diagnosis.workflow", logging.WARNING, __file__, 1,
                            "E_seg2 runs into its prior (%s std)", ("-0.9",), None)
    assert _LogFormatter(0).format(rec) == "warning: E_seg2 runs into its prior (-0.9 std)"
    assert _LogFormatter(1).format(rec) == "warning [updating.diagnosis.workflow]: E_seg2 runs into its prior (-0.9 std)"


def test_diagnose_given_a_modes_file_as_measured_points_to_modes(small_frf, tmp_path, capsys):
    import numpy as np

    from modalab.core import uff
    from modalab.core.modes import ModeSet

    H = uff.read_frf(small_frf)
    ms = ModeSet(freq_hz=[10.0, 20.0], damping=[0.01, 0.01], shapes=np.ones((len(H.responses), 2)),
                 dofs=list(H.responses))
    uff.write_modes(tmp_path / "modes.uff", ms)
    capsys.readouterr()
    assert main(["diagnose", str(DEMO / "nominal.bdf"), str(tmp_path / "modes.uff")]) == 2
    err = _one_line(capsys)
    assert "holds identified modes (dataset 55), not measured FRFs" in err
    assert f"--modes {tmp_path / 'modes.uff'}" in err


@pytest.mark.parametrize("jobs", ["0", "-2"])
def test_diagnose_jobs_below_one_is_one_line_before_any_file_is_read(tmp_path, monkeypatch, capsys, jobs):
    monkeypatch.chdir(tmp_path)
    assert main(["diagnose", str(DEMO / "nominal.bdf"), "missing.uff", "--jobs", jobs, "--json", "d.json"]) == 2
    err = _one_line(capsys)
    assert f"--jobs {jobs}: expected a positive number of processes" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_a_sim_point_outside_the_model_and_a_missing_modes_file_say_where_and_what_to_do(tmp_path, monkeypatch,
                                                                                          capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["sim", "-o", "s.uff", "--points", "1+Z", "99+Z", "--hits", "1", "--samples", "1024"]) == 2
    assert "99+Z is not in the model" in _one_line(capsys)
    assert main(["update", str(DEMO / "nominal.bdf"), "--modes", "nothere.json", "-o", "upd"]) == 2
    err = _one_line(capsys)
    assert "'nothere.json'" in err and "check the path" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == []          # nothing created
