"""Issue 14 (ux14 item 3): a roving-hammer file with 3 hit points x 1 accelerometer.

``info`` and ``identify`` apply one rule (:func:`identification.api.roving_hammer_layout`): identify transposes
such a file, so the shapes come out on the 3 hit points; identified without the transpose, the shapes rest on one
DOF and ``correlate`` must say that its MAC cannot tell them apart.  The FRFs come from plain numpy (a 3-DOF
spring-mass chain with stiffness-proportional damping, modal superposition written here), written with pyuff.
"""
import json
from pathlib import Path

import numpy as np
import pytest
import pyuff

from modalab.app.cli import main

M = np.array([1.0, 1.5, 0.8])
K = np.array([4e4, 3e4, 2e4])
BDF = (Path(__file__).resolve().parents[1] / "data" / "chain3.bdf").read_text()


def _accelerance(f):
    Km = np.array([[K[0] + K[1], -K[1], 0], [-K[1], K[1] + K[2], -K[2]], [0, -K[2], K[2]]])
    C = 1e-4 * Km
    w = 2 * np.pi * f
    H = np.array([-(wi ** 2) * np.linalg.inv(Km - wi ** 2 * np.diag(M) + 1j * wi * C) for wi in w])
    return H.transpose(1, 2, 0)


@pytest.fixture(scope="module")
def roving(tmp_path_factory):
    d = tmp_path_factory.mktemp("rov")
    f = np.arange(1, 2001) * 0.05
    H = _accelerance(f)
    u = pyuff.UFF(str(d / "roving.uff"))
    u.write_sets({'type': 15, 'node_nums': [1, 2, 3], 'def_cs': [0] * 3, 'disp_cs': [0] * 3, 'color': [1] * 3,
                  'x': [0., .5, 1.], 'y': [0.] * 3, 'z': [0.] * 3}, mode='add')
    for i in (1, 2, 3):                      # one accelerometer at 3, the hammer roves over 1..3
        u.write_sets({'type': 58, 'func_type': 4, 'rsp_node': 3, 'rsp_dir': 3, 'ref_node': i, 'ref_dir': 3,
                      'data': H[2, i - 1], 'x': f, 'id1': f'H 3+Z/{i}+Z', 'rsp_ent_name': 'pt', 'ref_ent_name': 'pt',
                      'abscissa_spacing': 1, 'abscissa_spec_data_type': 18, 'ordinate_spec_data_type': 12,
                      'orddenom_spec_data_type': 13, 'abscissa_axis_units_lab': 'Hz',
                      'ordinate_axis_units_lab': 'm/s^2', 'orddenom_axis_units_lab': 'N', 'load_case_id': 0},
                     mode='add')
    (d / "model.bdf").write_text(BDF)
    return d


def test_info_and_identify_agree_and_the_shapes_cover_the_hit_points(roving, capsys):
    capsys.readouterr()
    assert main(["info", str(roving / "roving.uff")]) == 0
    assert "a roving-hammer export" in capsys.readouterr().out
    assert main(["identify", str(roving / "roving.uff"), "--band", "5", "70", "-o", str(roving / "m.uff"),
                 "--json", str(roving / "m.json")]) == 0
    m = json.loads((roving / "m.json").read_text())
    assert m["reciprocity"]["applied"] is True, m["reciprocity"]
    assert len(m["table"]) == 3 and len(m["dofs"]) == 3


def test_correlate_warns_when_the_mac_rests_on_fewer_dofs_than_pairs(roving, capsys):
    assert main(["identify", str(roving / "roving.uff"), "--band", "5", "70", "--no-reciprocity", "-o",
                 str(roving / "one.uff")]) == 0
    capsys.readouterr()
    assert main(["correlate", str(roving / "model.bdf"), str(roving / "one.uff"), "--json",
                 str(roving / "c.json")]) == 0
    out = capsys.readouterr().out
    assert "WARNING: the MAC rests on 1 measured DOF for 3 paired modes" in out, out
    s = json.loads((roving / "c.json").read_text())["summary"]
    assert s["n_test_dofs"] == 1 and "1 measured DOF for 3 paired modes" in s["mac_warning"]
    # modes.uff keeps no references: the advice names both causes (it said only "measure more DOFs" first)
    assert "measure more response DOFs; if the modes come from a roving-hammer file" in out
    assert "identify it without --no-reciprocity" in out, out


def test_correlate_names_the_fix_for_modes_of_an_untransposed_roving_hammer_file(roving, capsys):
    """modes.json keeps the references: shapes on the 1 accelerometer, participation at the 3 hit points is a
    roving-hammer file identified with --no-reciprocity; the advice is to identify it again with the transpose,
    not to measure more DOFs (the hit points are the DOFs already measured)."""
    assert main(["identify", str(roving / "roving.uff"), "--band", "5", "70", "--no-reciprocity", "-o",
                 str(roving / "nr.uff"), "--json", str(roving / "nr.json")]) == 0
    capsys.readouterr()
    assert main(["correlate", str(roving / "model.bdf"), str(roving / "nr.json"), "--json",
                 str(roving / "nr_c.json")]) == 0
    out = capsys.readouterr().out
    assert ("these modes have their shapes at the 1 response DOF (3+Z) and their participation at 3 references, "
            "the hit points of a roving-hammer test: identify the FRF file again without --no-reciprocity") in out, out
    assert "measure more" not in out
    warn = json.loads((roving / "nr_c.json").read_text())["summary"]["mac_warning"]
    assert "identify the FRF file again without --no-reciprocity" in warn


def test_correlate_given_the_roving_hammer_frf_file_says_to_identify_it_first(roving, capsys):
    capsys.readouterr()
    assert main(["correlate", str(roving / "model.bdf"), str(roving / "roving.uff")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert "holds FRFs (1 response x 3 references), not modes: identify them first" in err, err
    assert "roving-hammer file (its 3 hit points are its references)" in err and "--no-reciprocity" in err, err


def test_correlate_names_where_the_coordinates_of_a_json_come_from(roving, capsys):
    assert main(["identify", str(roving / "roving.uff"), "--band", "5", "70", "--no-reciprocity", "-o",
                 str(roving / "one2.uff"), "--json", str(roving / "one2.json")]) == 0
    capsys.readouterr()
    assert main(["correlate", str(roving / "model.bdf"), str(roving / "one2.json")]) == 0
    out = capsys.readouterr().out
    assert "one2.json (its coordinates): 1 test node on" in out and "dataset 2411" not in out, out


def test_an_unsupported_structural_card_is_an_error_unless_ignored(roving, capsys):
    deck = roving / "t6.bdf"
    deck.write_text(BDF.replace("ENDDATA", "CTRIA6       901      99       1       2       3       4       4       4\n"
                                           "ENDDATA"))
    line = 1 + deck.read_text().splitlines().index(next(x for x in deck.read_text().splitlines()
                                                        if x.startswith("CTRIA6")))
    assert main(["identify", str(roving / "roving.uff"), "--band", "5", "70", "-o", str(roving / "m3.uff")]) == 0
    capsys.readouterr()
    assert main(["correlate", str(deck), str(roving / "m3.uff")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert f"'{deck}'" in err and f"line {line}" in err and "CTRIA6" in err and "--ignore-unsupported" in err, err
    assert main(["correlate", str(deck), str(roving / "m3.uff"), "--ignore-unsupported"]) == 0


def test_report_builds_one_html_from_the_outputs_of_the_commands(roving, tmp_path, monkeypatch, capsys):
    import shutil

    for f in ("roving.uff", "model.bdf"):
        shutil.copy(roving / f, tmp_path / f)
    (tmp_path / "params.toml").write_text('[[parameter]]\nname = "k_12"\nfield = "k"\nelements = [22]\n'
                                          'lower = 0.5\nupper = 2.0\n')
    monkeypatch.chdir(tmp_path)
    for argv in (["identify", "roving.uff", "--band", "5", "70", "-o", "m.uff", "--json", "modes.json",
                  "--plots", "id_plots"],
                 ["correlate", "model.bdf", "m.uff", "--plots", "corr", "--json", "corr.json"],
                 ["update", "model.bdf", "--modes", "modes.json", "--params", "params.toml", "-o", "updated/"]):
        assert main(argv) == 0, argv
    capsys.readouterr()
    assert main(["report", "."]) == 0
    out = capsys.readouterr().out
    assert "identify: modes.json" in out and "update: updated/update.json" in out and "wrote report/report.html" in out
    html = (tmp_path / "report" / "report.html").read_text()
    summary = json.loads((tmp_path / "report" / "summary.json").read_text())
    assert len(summary["modes"]) == 3 and summary["update"]["parameters"]["k_12"]["updated"] > 0
    assert "Stabilisation diagram: not available" not in html and "MAC, updated model: not available" not in html
    # roving.uff (pyuff, FRFs only): why there is no coherence map, in words
    assert "No coherence map: the FRF file roving.uff holds no coherence functions" in html, html
    # the model to use is named where update wrote it (updated/), not in a run folder's layout (update/)
    assert summary["model_to_use"]["file"] == "updated/updated.bdf", summary["model_to_use"]
    assert (tmp_path / summary["model_to_use"]["file"]).is_file()
    assert "modalab report," in html and "modalab run report" not in html      # no 'modalab run' was involved
    # two different outputs of one stage: the report cannot choose, and says which
    other = json.loads((tmp_path / "modes.json").read_text())
    other["freq_hz"][0] *= 1.01
    (tmp_path / "other.json").write_text(json.dumps(other))
    assert main(["report", ".", "-o", "r2"]) == 2
    err = capsys.readouterr().err
    assert "two identify outputs" in err and "other.json" in err and len(err.strip().splitlines()) == 1


def test_update_says_the_mac_dof_warning_once(roving, capsys):
    """update printed 'WARNING: the MAC rests on ...' twice, below the table before and the table after updating
    (the test DOFs are the same in both)."""
    assert main(["identify", str(roving / "roving.uff"), "--band", "5", "70", "--no-reciprocity", "-o",
                 str(roving / "one3.uff"), "--json", str(roving / "one3.json")]) == 0
    (roving / "k.toml").write_text('[[parameter]]\nname = "k1"\nfield = "k"\nelements = [21]\n')
    capsys.readouterr()
    assert main(["update", str(roving / "model.bdf"), "--modes", str(roving / "one3.json"), "--params",
                 str(roving / "k.toml"), "-o", str(roving / "u")]) == 0
    out = capsys.readouterr().out
    assert out.count("WARNING: the MAC rests on 1 measured DOF") == 1, out
    s = json.loads((roving / "u" / "update.json").read_text())
    assert "1 measured DOF" in s["correlation_after"]["summary"]["mac_warning"]
