"""``modalab correlate``/``update`` never pair test node ids with model grid ids silently (issue 16 #5),
and a misspelt key of a parameter file is an error naming file, key and closest valid key (issue 14 #7)."""
import json

import numpy as np
import pytest

from modalab.app.cli import main


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    from updating.fe.bulk import to_bulk, write_bdf
    from updating.fe.models.garteur import garteur_model

    d = tmp_path_factory.mktemp("cmap")
    nominal = garteur_model(mesh=4)
    write_bdf(to_bulk(nominal), d / "nominal.bdf")
    ms = nominal.modes(16)
    dofs = [x for x in ms.dofs if x.axis == 3 and x.node % 2 == 0 and x.node in nominal.nodes][:20]
    test = ms.select_dofs(dofs).select_modes(np.flatnonzero(ms.freq_hz > 1.0)[:6])
    # renumber the test nodes 1..n, as a lab would; coordinates of the grids they sit on
    nodes = sorted({x.node for x in dofs})
    ren = {g: k + 1 for k, g in enumerate(nodes)}
    from modalab.core.modes import ModeSet
    t2 = ModeSet(freq_hz=test.freq_hz, shapes=test.shapes, dofs=[f"{ren[x.node]}+Z" for x in dofs])
    t2.to_uff(d / "nogeo.uff")
    t2.coordinates = {ren[g]: tuple(nominal.nodes[g].xyz) for g in nodes}
    t2.to_uff(d / "geo.uff")
    return d, ren


def test_refuses_without_map_or_geometry(case, capsys):
    d, _ = case
    assert main(["correlate", str(d / "nominal.bdf"), str(d / "nogeo.uff"), "--json", str(d / "x.json")]) == 2
    err = capsys.readouterr().err
    assert "carries no node coordinates" in err and "--geometry" in err and "--same-ids" in err
    assert "Traceback" not in err and not (d / "x.json").exists()


def test_maps_by_geometry_and_reports_it(case, capsys):
    d, ren = case
    assert main(["correlate", str(d / "nominal.bdf"), str(d / "geo.uff"), "--json", str(d / "g.json")]) == 0
    out = capsys.readouterr().out
    assert "DOFs: by geometry" in out and "renumbered: 1->" in out
    js = json.loads((d / "g.json").read_text())
    assert js["geometry_map"]["max_distance_m"] < 1e-9
    assert {int(k): v["model_node"] for k, v in js["geometry_map"]["nodes"].items()} == {v: k for k, v in ren.items()}
    pairs = js["pairs"]
    assert len(pairs) == 6 and min(p["mac"] for p in pairs) > 0.999
    assert all(abs(p["freq_error_pct"]) < 1e-6 for p in pairs)
    # --geometry with a separate file gives the same pairs
    assert main(["correlate", str(d / "nominal.bdf"), str(d / "nogeo.uff"), "--geometry", str(d / "geo.uff"),
                 "--json", str(d / "g2.json")]) == 0
    assert json.loads((d / "g2.json").read_text())["pairs"] == pairs


def test_same_ids_is_explicit_and_said(case, capsys):
    d, _ = case
    rc = main(["correlate", str(d / "nominal.bdf"), str(d / "geo.uff"), "--same-ids"])
    out = capsys.readouterr()
    # test nodes 1..n taken as grids 1..n: either a DOF without a model counterpart (exit 2, named) or a
    # correlation that says how the DOFs were mapped
    if rc == 2:
        assert "no model counterpart" in out.err
    else:
        assert rc == 0 and "same node ids (--same-ids)" in out.out


def test_update_refuses_a_misspelt_parameter_key(case, capsys):
    d, _ = case
    (d / "bad.toml").write_text('[[parameter]]\nname = "E_wing"\nfield = "E"\nproperties = ["wing"]\nlowr = 0.5\n')
    out = d / "never"
    assert main(["update", str(d / "nominal.bdf"), "--modes", str(d / "geo.uff"), "--params", str(d / "bad.toml"),
                 "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "bad.toml" in err and "'lowr'" in err and "did you mean 'lower'" in err
    assert not out.exists()


def test_frequency_only_set_end_to_end(case, capsys, tmp_path):
    """A JSON of repeated frequencies (no shapes): correlate pairs by order and says so; update uses the
    covariance of the mean, keeps the exact model at nominal and reports the condition number."""
    d, _ = case
    from updating.fe.models.garteur import garteur_model

    f = garteur_model(mesh=4).modes(16).freq_hz
    f = f[f > 1.0][:6]
    rng = np.random.default_rng(2)
    reps = f * (1 + 1e-3 * (0.8 * rng.normal(size=(40, 1)) + 0.6 * rng.normal(size=(40, f.size))))
    (tmp_path / "f.json").write_text(json.dumps({"freq_repeats_hz": reps.tolist()}))
    assert main(["correlate", str(d / "nominal.bdf"), str(tmp_path / "f.json")]) == 0
    out = capsys.readouterr().out
    assert "no mode shapes" in out and "pairing by frequency order" in out and "6 pairs" in out
    (tmp_path / "p.toml").write_text('[[parameter]]\nname = "E_wing"\nfield = "E"\nproperties = ["wing"]\n'
                                     '[[parameter]]\nname = "t_fin"\nfield = "h"\nproperties = ["fin"]\n')
    assert main(["update", str(d / "nominal.bdf"), "--modes", str(tmp_path / "f.json"), "--params",
                 str(tmp_path / "p.toml"), "-o", str(tmp_path / "u")]) == 0
    out = capsys.readouterr().out
    assert "frequency-only test set" in out and "condition number" in out
    js = json.loads((tmp_path / "u" / "update.json").read_text())
    assert js["frequency_weights"].startswith("covariance of the test frequencies")
    for name, v in js["parameters"].items():
        sd = js["identifiability"]["std_unregularised"][name]
        assert abs(v["updated"] - 1.0) < 4 * sd, (name, v, sd)
        assert sd < 5e-3


def test_freq_sigma_of_the_wrong_length_is_refused(case, capsys, tmp_path):
    d, _ = case
    (tmp_path / "f.json").write_text(json.dumps({"freq_hz": [10.0, 20.0, 30.0]}))
    out = tmp_path / "u"
    assert main(["update", str(d / "nominal.bdf"), "--modes", str(tmp_path / "f.json"), "--freq-sigma", "0.01",
                 "0.02", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--freq-sigma: got 2 value(s)" in err and "Traceback" not in err and not out.exists()
