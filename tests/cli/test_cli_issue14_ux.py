"""Issue 14, a fresh user's second walk (ux14): wrong input to the commands is one line, exit 2, naming the
option, what was expected and what to do; what the commands print says what they did."""
from pathlib import Path

import pytest

from modalab.app.cli import main
from modalab.app.stages import load_model, load_parameters
from modalab.core.errors import PlanError

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "examples" / "demo_project"


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


@pytest.fixture(scope="module")
def small_frf(tmp_path_factory):
    """A small FRF file (0-800 Hz) from a one-point simulated test."""
    d = tmp_path_factory.mktemp("frf")
    assert main(["sim", "-o", str(d / "h.uff"), "--points", "1+Z", "--hits", "1", "--samples", "2048",
                 "--no-plot"]) == 0
    assert main(["frf", str(d / "h.uff"), "-o", str(d / "f.uff"), "--no-plot"]) == 0
    return d / "f.uff"


@pytest.mark.parametrize("argv, expect", [
    (["--select", "10Hz,20Hz"], ["--select '10Hz,20Hz'", "'10Hz' is not a frequency in Hz", "e.g. --select 10,20"]),
    (["--select", "10,-3"], ["'-3' is not a positive frequency"]),
    (["--band", "-5", "70"], ["--band -5 70", "expected 0 <= LO < HI in Hz"]),
    (["--band", "70", "5"], ["--band 70 5", "expected 0 <= LO < HI in Hz"]),
    (["--select", "10", "--select-tol", "5"], ["--select-tol 5", "between 0 and 1"]),
])
def test_identify_refuses_bad_select_and_band_in_one_line(small_frf, tmp_path, capsys, argv, expect):
    capsys.readouterr()
    assert main(["identify", str(small_frf), "-o", str(tmp_path / "x.uff")] + argv) == 2
    err = _one_line(capsys)
    assert all(e in err for e in expect), err
    assert not (tmp_path / "x.uff").exists()


def test_identify_select_far_from_any_pole_names_the_cli_option(small_frf, tmp_path, capsys):
    capsys.readouterr()
    assert main(["identify", str(small_frf), "--band", "5", "700", "--select", "5000", "-o",
                 str(tmp_path / "x.uff")]) == 2
    err = _one_line(capsys)
    assert "--select-tol" in err and "SelectionOptions" not in err and str(small_frf) in err, err


@pytest.mark.parametrize("command, option", [
    (["sim", "--points", "1+Z", "--hits", "1", "--no-plot", "-o"], "--overwrite"),   # sim's --force is the hammer's
    (["frf", "IN", "--no-plot", "-o"], "--force"),
])
def test_an_existing_output_names_the_option_of_that_command(small_frf, tmp_path, capsys, command, option):
    out = tmp_path / "out.uff"
    out.write_text("keep me")
    capsys.readouterr()
    assert main([str(small_frf) if x == "IN" else x for x in command] + [str(out)]) == 2
    err = _one_line(capsys)
    assert f"pass {option} to replace it" in err, err
    assert out.read_text() == "keep me"


@pytest.mark.parametrize("value, expect", [("35", "--freq-window 0.35 for ±35 %"), ("1", "--freq-window 0.01"),
                                           ("0", "between 0 and 1"), ("-0.2", "between 0 and 1")])
def test_correlate_freq_window_is_a_fraction(tmp_path, capsys, value, expect):
    assert main(["correlate", str(DEMO / "nominal.bdf"), str(tmp_path / "m.json"), "--freq-window", value]) == 2
    err = _one_line(capsys)
    assert f"--freq-window {value}" in err and "0.35 = ±35 %" in err and expect in err, err


@pytest.mark.parametrize("bw", ["5000", "0"])
def test_frf_bandwidth_above_fs_over_2_56_is_refused(small_frf, tmp_path, capsys, bw):
    capsys.readouterr()
    hits = small_frf.parent / "h.uff"
    assert main(["frf", str(hits), "--bandwidth", bw, "-o", str(tmp_path / "f.uff"), "--no-plot"]) == 2
    err = _one_line(capsys)
    assert str(hits) in err and f"--bandwidth {bw} Hz" in err and "fs/2.56 = 800 Hz" in err, err
    assert not (tmp_path / "f.uff").exists()


def test_a_misspelt_command_is_one_line_with_the_closest(capsys):
    with pytest.raises(SystemExit) as e:
        main(["idnetify", "frf.uff", "-o", "x.uff"])
    assert e.value.code == 2
    err = _one_line(capsys)
    assert "unknown command 'idnetify' (did you mean identify?)" in err, err


def test_info_on_a_bulk_data_file_says_what_it_is_and_who_reads_it(capsys):
    assert main(["info", str(DEMO / "nominal.bdf")]) == 2
    err = _one_line(capsys)
    assert "nominal.bdf is Nastran bulk data" in err and "modalab correlate" in err, err


CHAIN = """SOL 103
CEND
BEGIN BULK
GRID           1              0.      0.      0.           12456
GRID           2              .5      0.      0.           12456
CONM2        101       1              1.
CONM2        102       2             1.5
$ name: kground
PELAS         11   4.+4
PELAS         12   3.+4
CELAS1        21      11       1       3
CELAS1        22      12       1       3       2       3
ENDDATA
"""


@pytest.mark.parametrize("deck, param, expect", [
    ("chain", 'field = "k"\nproperties = ["kground"]', ["field = 'k' with elements = [21]"]),
    ("demo", 'field = "Emod"\nproperties = ["PNAME"]', ["has no field 'Emod' (did you mean 'E'?)"]),
    ("demo", 'field = "E"\nproperties = ["PTYPO"]', ["(did you mean 'PNAME'?)"]),
])
def test_parameter_file_errors_name_the_file_and_the_closest_choice(tmp_path, capsys, deck, param, expect):

    if deck == "chain":
        model = tmp_path / "chain.bdf"
        model.write_text(CHAIN)
    else:
        model = DEMO / "nominal.bdf"
        name = sorted({p.name for p in load_model(model).properties.values() if getattr(p, "name", "")})[0]
        param = param.replace("PNAME", name).replace("PTYPO", name[:-1])
        expect = [x.replace("PNAME", name) for x in expect]
    params = tmp_path / "p.toml"
    params.write_text(f'[[parameter]]\nname = "x"\n{param}\n')
    with pytest.raises(PlanError) as e:                   # what update and diagnose call on --params
        load_parameters(params, load_model(model))
    err = str(e.value)
    assert err.startswith(f"{params}:") and all(x in err for x in expect), err
