"""Issue 14 audit (ux14, third walk): the refusals a fresh user still met.  Each wrong input is one line on
stderr, exit code 2, naming the option or file, what was expected and what to do; nothing is written."""
import json
from pathlib import Path

import pytest

from modalab.app.cli import main

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "examples" / "demo_project"


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


@pytest.fixture()
def freqs(tmp_path):
    """A frequency-only test set of the demo deck (what a GVT's frequency list gives)."""
    p = tmp_path / "f.json"
    p.write_text(json.dumps({"freq_hz": [19.0, 67.5, 71.0]}))
    return p


@pytest.mark.parametrize("sigma", ["0.8", "5"])
def test_update_refuses_a_freq_sigma_above_one_half(tmp_path, capsys, freqs, sigma):
    out = tmp_path / "u"
    assert main(["update", str(DEMO / "nominal.bdf"), "--modes", str(freqs), "--freq-sigma", sigma,
                 "-o", str(out)]) == 2
    err = _one_line(capsys)
    assert f"--freq-sigma {sigma}" in err and "expected a fraction up to 0.5" in err, err
    assert f"--freq-sigma {float(sigma) / 100:g}" in err, err
    assert not out.exists()


@pytest.mark.parametrize("sigma", ["nan", "0", "-0.01", "inf"])
def test_update_refuses_a_freq_sigma_that_is_not_a_positive_number(tmp_path, capsys, freqs, sigma):
    out = tmp_path / "u"
    assert main(["update", str(DEMO / "nominal.bdf"), "--modes", str(freqs), "--freq-sigma", sigma,
                 "-o", str(out)]) == 2
    err = _one_line(capsys)
    assert f"--freq-sigma {sigma}: expected a relative standard deviation above 0" in err, err
    assert not out.exists()


@pytest.mark.parametrize("bounds", ["lower = 1.2\nupper = 2.0", "lower = 0.2\nupper = 0.9", "upper = 0.95"])
def test_update_refuses_bounds_that_exclude_the_nominal(tmp_path, capsys, freqs, bounds):
    params = tmp_path / "p.toml"
    params.write_text(f'[[parameter]]\nname = "E_wing"\nfield = "E"\nproperties = ["wing"]\n{bounds}\n')
    out = tmp_path / "u"
    assert main(["update", str(DEMO / "nominal.bdf"), "--modes", str(freqs), "--params", str(params),
                 "-o", str(out)]) == 2
    err = _one_line(capsys)
    assert str(params) in err and "'E_wing'" in err and "exclude its nominal value 1" in err, err
    assert not out.exists()


def test_update_accepts_bounds_around_the_nominal(tmp_path, capsys, freqs):
    params = tmp_path / "p.toml"
    params.write_text('[[parameter]]\nname = "E_wing"\nfield = "E"\nproperties = ["wing"]\nlower = 1.0\nupper = 2.0\n')
    assert main(["update", str(DEMO / "nominal.bdf"), "--modes", str(freqs), "--params", str(params),
                 "--freq-sigma", "0.5", "-o", str(tmp_path / "u")]) == 0
    assert (tmp_path / "u" / "update.json").is_file()


@pytest.mark.parametrize("argv, folder, product, flag", [
    (["update", "MODEL", "--modes", "FREQS", "-o", "OUT"], "OUT", "update.json", "-o"),
    (["update", "MODEL", "--modes", "FREQS", "-o", "OUT"], "OUT", "updated.bdf", "-o"),
    (["diagnose", "MODEL", "--modes", "FREQS", "--report", "OUT"], "OUT", "diagnosis.json", "--report"),
    (["report", "TMP", "-o", "OUT"], "OUT", "report.html", "-o"),
    (["report", "TMP"], "TMP/report", "summary.json", "the report folder"),
    (["identify", "FRF", "-o", "TMP/m.uff", "--plots", "OUT"], "OUT", "stabilisation.png", "--plots"),
    (["correlate", "MODEL", "FREQS", "--plots", "OUT"], "OUT", "mac_before.png", "--plots"),
])
def test_an_earlier_output_folder_is_not_overwritten_without_force(tmp_path, capsys, freqs, argv, folder, product,
                                                                    flag, one_point_frf):
    """``update -o``, ``diagnose --report`` and ``report`` replaced the files of an earlier run in their folder
    silently; now that is one line naming the folder and the files, and --force replaces them."""
    out = tmp_path / "out"
    subst = {"MODEL": str(DEMO / "nominal.bdf"), "FREQS": str(freqs), "OUT": str(out), "TMP": str(tmp_path),
             "FRF": str(one_point_frf)}
    argv = [subst.get(x, x.replace("TMP", str(tmp_path))) for x in argv]
    target = Path(folder.replace("TMP", str(tmp_path)).replace("OUT", str(out)))
    target.mkdir(parents=True)
    (target / product).write_text("earlier run")
    capsys.readouterr()
    assert main(argv) == 2
    err = _one_line(capsys)
    assert f"{flag} '{target}' holds the output of an earlier run ({product})" in err and "--force" in err, err
    assert (target / product).read_text() == "earlier run" and sorted(p.name for p in target.iterdir()) == [product]


def test_update_with_force_replaces_its_earlier_output(tmp_path, capsys, freqs):
    out = tmp_path / "u"
    argv = ["update", str(DEMO / "nominal.bdf"), "--modes", str(freqs), "-o", str(out)]
    assert main(argv) == 0
    first = (out / "update.json").read_text()
    assert main(argv) == 2
    assert main(argv + ["--force"]) == 0
    assert json.loads((out / "update.json").read_text())["method"] == json.loads(first)["method"]
    # a folder holding other files only (not this command's products) is fine
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    assert main(["update", str(DEMO / "nominal.bdf"), "--modes", str(freqs), "-o", str(other)]) == 0
    assert (other / "notes.txt").read_text() == "mine" and (other / "update.json").is_file()


@pytest.mark.parametrize("option, value, expect", [
    ("--sample-rate", "50", "expected at least 100 Hz"),
    ("--samples", "0", "expected at least 256 samples"),
    ("--samples", "200", "expected at least 256 samples"),
    ("--hits", "0", "expected at least 1 hit per point"),
    ("--force", "-3", "expected a peak force above 0 N"),
    ("--double-hits", "3", "expected a probability from 0 to 1"),
    ("--seed", "-1", "expected a whole number >= 0"),              # was a ValueError traceback from numpy
])
def test_sim_refuses_bad_acquisition_options_before_simulating(tmp_path, capsys, option, value, expect):
    """--sample-rate 50 printed the first point's progress and then failed on the trigger; --samples 0 ran with
    the default record; --hits 0 answered 'hits_per_point=0 must be >= 1' (no option named)."""
    out = tmp_path / "h.uff"
    assert main(["sim", "-o", str(out), "--points", "1+Z", "--no-plot", option, value]) == 2
    cap = capsys.readouterr()
    err = cap.err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert f"{option} {value}: {expect}" in err and "give e.g." in err, err
    assert cap.out == "" and not out.exists() and list(tmp_path.iterdir()) == []


@pytest.fixture(scope="module")
def one_point_frf(tmp_path_factory):
    """FRFs 0-800 Hz, 1 Hz apart, of a one-point simulated test (no window): the demo's 4 Hz bungee mode and
    its elastic modes."""
    d = tmp_path_factory.mktemp("frf")
    assert main(["sim", "-o", str(d / "h.uff"), "--points", "1+Z", "--hits", "1", "--samples", "2048",
                 "--no-plot"]) == 0
    assert main(["frf", str(d / "h.uff"), "-o", str(d / "f.uff"), "--no-plot"]) == 0
    return d / "f.uff"


def test_sim_refuses_a_point_given_twice(tmp_path, capsys):
    """--points 1+Z 1+Z ran silently (two roving points on one DOF)."""
    out = tmp_path / "h.uff"
    assert main(["sim", "-o", str(out), "--points", "1+Z", "3+Z", "1+Z", "--no-plot"]) == 2
    err = _one_line(capsys)
    assert "--points: 1+Z given twice; expected each DOF once" in err, err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("band, expect", [
    (("0.005", "0.7"), "the band is in Hz, not kHz: give --band 5 700"),
    (("0.02", "0.5"), "the band is in Hz, not kHz: give --band 20 500"),
    (("900", "2000"), "give a band below 800 Hz"),
    (("300", "310"), "give a wider band"),
])
def test_identify_a_band_of_a_few_lines_is_one_clear_line(one_point_frf, tmp_path, capsys, band, expect):
    """--band 0.005 0.7 (kHz for Hz) printed a warning 'only 2 lines for order 40' and then an error about
    max_order; now one line says what the band holds and what to give."""
    capsys.readouterr()
    assert main(["identify", str(one_point_frf), "--band", *band, "-o", str(tmp_path / "m.uff")]) == 2
    err = _one_line(capsys)
    assert f"--band {band[0]} {band[1]} Hz holds" in err and "a band needs at least 16" in err and expect in err, err
    assert str(one_point_frf) in err and "the data spans 0..800 Hz" in err, err
    assert not (tmp_path / "m.uff").exists()


def test_identify_warns_when_a_band_edge_cuts_a_resonance(one_point_frf, tmp_path, caplog):
    with caplog.at_level("WARNING"):
        assert main(["identify", str(one_point_frf), "--band", "5", "700", "-o", str(tmp_path / "a.uff")]) == 0
    cut = [r.getMessage() for r in caplog.records if "sits at the band's" in r.getMessage()]
    assert len(cut) == 1 and "a resonance at 4 Hz" in cut[0] and "lower edge 5 Hz" in cut[0], cut
    assert "e.g. --band 8 700" in cut[0] and str(one_point_frf) in cut[0], cut
    caplog.clear()
    with caplog.at_level("WARNING"):
        assert main(["identify", str(one_point_frf), "--band", "8", "700", "-o", str(tmp_path / "b.uff")]) == 0
    assert not [r for r in caplog.records if "sits at the band's" in r.getMessage()]


@pytest.mark.parametrize("argv, expect", [
    (["frf", "HITS", "-o", "OUT/f.uff", "--no-plot", "--exp-end", "5"], "--exp-end 5: expected the level"),
    (["frf", "HITS", "-o", "OUT/f.uff", "--no-plot", "--exp-beta", "-2"], "--exp-beta -2: expected the window's decay"),
    (["frf", "HITS", "-o", "OUT/f.uff", "--no-plot", "--force-window", "2"], "--force-window 2: expected a fraction"),
    (["identify", "FRF", "-o", "OUT/m.uff", "--max-order", "0"], "--max-order 0: expected a positive model order"),
    (["identify", "FRF", "-o", "OUT/m.uff", "--exp-beta", "-2"], "--exp-beta -2: expected the window's decay"),
    (["correlate", "MODEL", "FREQS", "--mac-min", "5"], "--mac-min 5: expected the lowest MAC"),
    (["correlate", "MODEL", "FREQS", "--freq-window", "inf"], "--freq-window inf: expected a fraction between 0 and 1"),
    (["identify", "FRF", "-o", "OUT/m.uff", "--exp-beta", "inf"], "--exp-beta inf: expected the window's decay"),
    (["correlate", "MODEL", "FREQS", "--n-modes", "0"], "--n-modes 0: expected a positive number"),
    (["update", "MODEL", "--modes", "FREQS", "-o", "OUT/u", "--max-iter", "0"], "--max-iter 0: expected at least 1"),
    (["update", "MODEL", "--frf", "FRF", "--method", "mci", "--band", "0.005", "0.7", "-o", "OUT/u"],
     "--band 0.005 0.7 Hz holds"),
])
def test_option_values_are_refused_naming_the_option(one_point_frf, tmp_path, capsys, freqs, argv, expect):
    """update --max-iter 0 ran ('did not converge in 0 iterations') and mci on a band given in kHz ran on 2 lines;
    frf --exp-end 5, identify --max-order 0 and correlate --mac-min 5 were refused under the stage's key names
    (exp_end_level, max_order, mac_min), not the option typed."""
    out = tmp_path / "out"
    out.mkdir()
    subst = {"HITS": str(one_point_frf.parent / "h.uff"), "FRF": str(one_point_frf), "MODEL": str(DEMO / "nominal.bdf"),
             "FREQS": str(freqs)}
    argv = [subst.get(x, x.replace("OUT", str(out))) for x in argv]
    capsys.readouterr()
    assert main(argv) == 2
    err = _one_line(capsys)
    assert expect in err and "give " in err, err
    assert list(out.iterdir()) == []


@pytest.mark.parametrize("argv, expect", [
    (["update", "M", "--modes", "m.json", "-o", "u", "--method", "eigensens"],
     "modalab update: error: argument --method: invalid choice: 'eigensens' (did you mean 'eigensensitivity'?)"),
    (["run", "p.toml", "--from", "idnetify"], "invalid choice: 'idnetify' (did you mean 'identify'?)"),
    (["frf", "h.uff", "-o", "f.uff", "--estimator", "H3"], "invalid choice: 'H3'"),
    (["sim", "-o", "h.uff", "--hits", "abc"], "modalab sim: error: argument --hits: invalid int value: 'abc'"),
    (["update", "M", "-o", "u"], "one of the arguments --modes --frf is required"),
    (["identify"], "the following arguments are required: inputs, -o/--output"),
])
def test_argparse_errors_are_one_line_with_the_closest_choice(tmp_path, capsys, argv, expect, monkeypatch):
    """An invalid choice, a missing argument or a bad number printed argparse's usage block above the error."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    err = _one_line(capsys)
    assert expect in err and "usage:" not in err and f"see 'modalab {argv[0]} --help'" in err, err
    assert list(tmp_path.iterdir()) == []


def test_a_project_band_in_khz_is_refused_naming_band_hz(one_point_frf, tmp_path):
    """diagnose's band_hz (a project's [diagnose] key) in kHz ran on a handful of lines."""
    from modalab.app.stages import DiagnoseOptions, diagnose
    from modalab.core.errors import ModalabValueError

    with pytest.raises(ModalabValueError) as e:
        diagnose(DEMO / "nominal.bdf", frf_path=one_point_frf, opts=DiagnoseOptions(band_hz=(0.002, 0.08)),
                 json_path=tmp_path / "d.json")
    msg = str(e.value)
    assert msg.startswith("band_hz = [0.002, 0.08] Hz holds") and "give band_hz = [2, 80]" in msg, msg
    assert list(tmp_path.iterdir()) == []


def _band_project(tmp_path, one_point_frf, section_text):
    d = tmp_path / "proj"
    d.mkdir()
    (d / "measured.uff").write_bytes(one_point_frf.read_bytes())
    (d / "nominal.bdf").write_bytes((DEMO / "nominal.bdf").read_bytes())
    p = d / "p.toml"
    p.write_text('[project]\nname = "band"\n[test]\nfrf = "measured.uff"\n[model]\nbulk = "nominal.bdf"\n'
                 + section_text)
    return p


@pytest.mark.parametrize("band, expect", [
    ("[0.005, 0.7]", "the band is in Hz, not kHz: give [identify] band_hz = [5, 700]"),
    ("[900, 2000]", "give a band below 800 Hz (the top line: fs/2.56), e.g. [identify] band_hz = [5, 720]"),
])
def test_a_project_identify_band_out_of_range_names_the_file_and_key(one_point_frf, tmp_path, capsys, band, expect):
    """A project's [identify] band_hz in kHz (or beyond the data) was refused as '--band 0.005 0.7 Hz holds 2
    lines ... give --band 5 700': an option the user never typed; now the project file and its key."""
    p = _band_project(tmp_path, one_point_frf, f"[identify]\nband_hz = {band}\n")
    capsys.readouterr()
    assert main(["run", str(p), "-o", str(tmp_path / "out")]) == 2
    err = _one_line(capsys)
    lo, hi = (float(x) for x in band.strip("[]").split(","))
    assert f"{p}: [identify] band_hz = [{lo:g}, {hi:g}] Hz holds" in err and expect in err, err
    assert "--band" not in err, err
    assert not (tmp_path / "out" / "identify" / "modes.uff").exists()


@pytest.mark.parametrize("band", ['["a", 700]', "[-5, 700]", "[5, inf]", "[5, nan]", "[true, 700]", "[5]"])
def test_a_project_band_that_is_not_two_numbers_from_0_is_one_line(one_point_frf, tmp_path, capsys, band):
    """band_hz = ["a", 700] ended in a traceback (ValueError: could not convert string to float), and
    [-5, 700] was refused as 'expected ... low < high', which it was."""
    p = _band_project(tmp_path, one_point_frf, f"[identify]\nband_hz = {band}\n")
    capsys.readouterr()
    assert main(["run", str(p), "-o", str(tmp_path / "out")]) == 2
    err = _one_line(capsys)
    assert f"{p}: [identify] band_hz = " in err and "two numbers in Hz with 0 <= low < high" in err, err
    assert not (tmp_path / "out").exists()


def test_a_project_band_edge_warning_names_the_project_key(one_point_frf, tmp_path, caplog):
    p = _band_project(tmp_path, one_point_frf, "[identify]\nband_hz = [5, 700]\n")
    from modalab.app.project import load_project
    import modalab.app.run as R
    proj = load_project(p)
    out = tmp_path / "out"
    (out / "frf").mkdir(parents=True)
    (out / "frf" / "frf.uff").write_bytes(one_point_frf.read_bytes())
    with caplog.at_level("WARNING"):
        R.stage_identify(R._Context(proj, out, "sim", None))
    cut = [r.getMessage() for r in caplog.records if "sits at the band's" in r.getMessage()]
    assert len(cut) == 1 and f"e.g. [identify] band_hz = [8, 700] in {p}" in cut[0] and "--band" not in cut[0], cut


@pytest.mark.parametrize("own", [True, False])
def test_a_project_diagnose_band_in_khz_names_the_file_and_the_key_it_came_from(one_point_frf, tmp_path, own):
    """The diagnose stage of a run takes [diagnose] band_hz, else [identify] band_hz: the refusal names that."""
    from modalab.app.project import load_project
    from modalab.core.errors import ModalabValueError
    import modalab.app.run as R
    sec = "[diagnose]\nband_hz = [0.002, 0.08]\n" if own else "[identify]\nband_hz = [0.002, 0.08]\n"
    p = _band_project(tmp_path, one_point_frf, sec)
    out = tmp_path / "out"
    (out / "frf").mkdir(parents=True)
    (out / "frf" / "frf.uff").write_bytes(one_point_frf.read_bytes())
    with pytest.raises(ModalabValueError) as e:
        R.stage_diagnose(R._Context(load_project(p), out, "sim", None))
    key = "[diagnose] band_hz" if own else "[identify] band_hz"
    msg = str(e.value)
    assert msg.startswith(f"{p}: {key} = [0.002, 0.08] Hz holds") and f"give {key} = [2, 80]" in msg, msg


def test_a_project_diagnose_jobs_reaches_the_diagnosis(one_point_frf, tmp_path, monkeypatch):
    """[diagnose] jobs: the processes of the diagnosis' independent fits, as diagnose --jobs; a typo is refused."""
    from modalab.app.project import load_project
    from modalab.core.errors import ModalabValueError
    import modalab.app.run as R
    seen = []
    monkeypatch.setattr(R.stages, "diagnose", lambda *a, opts, **k: seen.append(opts.jobs) or R.stages.StageResult(None))
    out = tmp_path / "out"
    (out / "frf").mkdir(parents=True)
    (out / "frf" / "frf.uff").write_bytes(one_point_frf.read_bytes())
    R.stage_diagnose(R._Context(load_project(_band_project(tmp_path, one_point_frf, "[diagnose]\njobs = 1\n")),
                                out, "sim", None))
    assert seen == [1]
    (tmp_path / "proj" / "p.toml").write_text((tmp_path / "proj" / "p.toml").read_text().replace("jobs", "job"))
    with pytest.raises(ModalabValueError, match=r"\[diagnose\] unknown key job \(did you mean jobs\?\)"):
        load_project(tmp_path / "proj" / "p.toml")


@pytest.mark.parametrize("kinds", [["local_damping"], ["joint_flexibility", "added_mass"]])
def test_a_modes_only_diagnosis_refuses_kinds_it_cannot_judge(tmp_path, capsys, freqs, kinds):
    """diagnose --modes --kinds local_damping said 'Nothing is missing beyond parameter error' without looking
    at a single damping candidate (undamped modes cannot show one)."""
    out = tmp_path / "d.json"
    assert main(["diagnose", str(DEMO / "nominal.bdf"), "--modes", str(freqs), "--kinds", *kinds,
                 "--json", str(out)]) == 2
    err = _one_line(capsys)
    assert f"kinds {kinds[0]}: identified modes alone judge ground_spring and added_mass only" in err, err
    assert "MEASURED.uff" in err and not out.exists()


@pytest.mark.parametrize("section, old, new, expect", [
    ("update", "max_iter = 10", "max_iter = 0", "[update] max_iter = 0; expected a whole number >= 1"),
    ("update", "max_iter = 10", "max_iter = 10\nfreq_sigma = 0.8", "[update] freq_sigma = 0.8; expected relative"),
    ("identify", "max_order = 24", "max_order = -4", "[identify] max_order = -4; expected a whole number >= 1"),
    ("diagnose", "max_nfev = 10", "max_nfev = 0", "[diagnose] max_nfev = 0; expected a whole number >= 1"),
    ("diagnose", "max_nfev = 10", "max_nfev = 10\njobs = 0", "[diagnose] jobs = 0; expected a whole number >= 1"),
])
def test_a_project_value_the_stage_would_refuse_is_refused_before_any_work(tmp_path, capsys, section, old, new,
                                                                          expect):
    """[update] max_iter = 0 ran the acquisition, FRFs, identification and correlation before the update stage
    refused it (or ran it with no iteration)."""
    for f in DEMO.iterdir():
        (tmp_path / f.name).write_bytes(f.read_bytes())
    proj = tmp_path / "project_quick.toml"
    text = proj.read_text()
    assert old in text
    proj.write_text(text.replace(old, new))
    out = tmp_path / "out"
    assert main(["run", str(proj), "-o", str(out)]) == 2
    err = _one_line(capsys)
    assert expect in err and str(proj) in err, err
    assert not out.exists()


@pytest.mark.parametrize("content, expect", [('{"freq_hz": [19.0, -5]}', "mode 2 has frequency -5 Hz"),
                                             ('{"freq_hz": [19.0, NaN]}', "mode 2 has frequency nan Hz"),
                                             ('{"freq_hz": []}', "holds no modes")])
def test_test_modes_with_impossible_frequencies_are_refused(tmp_path, capsys, content, expect):
    """A modes.json with a negative frequency ran the update silently; an empty one failed on the pairing."""
    modes = tmp_path / "m.json"
    modes.write_text(content)
    out = tmp_path / "u"
    assert main(["update", str(DEMO / "nominal.bdf"), "--modes", str(modes), "-o", str(out)]) == 2
    err = _one_line(capsys)
    assert expect in err and str(modes) in err, err
    assert not out.exists()


def test_the_report_wire_frame_of_a_model_with_a_card_the_builder_does_not_model(one_point_frf, tmp_path,
                                                                                   monkeypatch, caplog):
    """The geometry figure drew no wire frame (and said so at info level only) when the deck held a structural
    card the builder does not model, although the diagnosis ran on it with --ignore-unsupported: the wire frame
    needs the grids and elements only."""
    import modalab.app.stages._report as R
    deck = (DEMO / "nominal.bdf").read_text().splitlines()
    at = next(i for i, line in enumerate(deck) if line.startswith("GRID"))
    deck[at:at] = ["CHEXA   900     1       1       2       3       4       5       6", "+       7       8"]
    bdf = tmp_path / "with_hexa.bdf"
    bdf.write_text("\n".join(deck) + "\n")
    (tmp_path / "run" / "frf").mkdir(parents=True)
    (tmp_path / "run" / "frf" / "frf.uff").write_bytes(one_point_frf.read_bytes())
    drawn = []
    real = R.plot_geometry
    monkeypatch.setattr(R, "plot_geometry", lambda *a, **k: drawn.append(k["lines"]) or real(*a, **k))
    with caplog.at_level("WARNING"):
        path = R._geometry_figure(tmp_path / "run", tmp_path, model=bdf)
    assert path is not None and path.is_file()
    assert len(drawn) == 1 and len(drawn[0]) >= 70, "the demo's 71 beam elements drawn"
    assert not [r for r in caplog.records if "wire frame" in r.getMessage()]
