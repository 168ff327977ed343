"""``modalab correlate`` and ``modalab update`` on the GARTEUR-like bulk data: correlation before/after,
updated deck written and re-importable with the updated frequencies."""
import json

import numpy as np
import pytest

from modalab.app.cli import main


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    from updating.fe.bulk import to_bulk, write_bdf
    from updating.fe import ParametricFEModel
    from updating.fe.models.garteur import garteur_model, garteur_parameters

    d = tmp_path_factory.mktemp("upd")
    nominal = garteur_model(mesh=4)
    write_bdf(to_bulk(nominal), d / "nominal.bdf")
    pm = ParametricFEModel(nominal, garteur_parameters(nominal))
    p_true = np.array([1.08, 0.95, 1.06, 1.0])           # E_wing, t_wing, t_fin, rho_fuselage
    truth = pm.model_at(p_true)
    ms = truth.modes(20)
    dofs = [x for x in ms.dofs if x.axis in (2, 3) and x.node % 2 == 0]
    elastic = np.flatnonzero(ms.freq_hz > 1.0)[:8]
    test = ms.select_dofs(dofs).select_modes(elastic)
    # the test geometry travels with the modes (dataset 2411): correlate/update map test nodes by geometry
    test.coordinates = {x.node: tuple(nominal.nodes[x.node].xyz) for x in dofs}
    test.to_uff(d / "test_modes.uff")
    (d / "params.toml").write_text(
        '[[parameter]]\nname = "E_wing"\nfield = "E"\nproperties = ["wing"]\n'
        '[[parameter]]\nname = "t_wing"\nfield = "h"\nproperties = ["wing"]\n'
        '[[parameter]]\nname = "t_fin"\nfield = "h"\nproperties = ["fin"]\n')
    return d, p_true, test


def test_correlate_cli(case, capsys):
    d, _, test = case
    assert main(["correlate", str(d / "nominal.bdf"), str(d / "test_modes.uff"), "--plots", str(d / "corr"),
                 "--json", str(d / "corr.json")]) == 0
    res = json.loads((d / "corr.json").read_text())
    assert len(res["pairs"]) >= test.n_modes - 1          # the close wing torsion pair may swap partners
    assert all(p["mac"] > 0.5 for p in res["pairs"])
    assert (d / "corr").exists() and any((d / "corr").iterdir())


def test_update_cli_recovers_parameters_and_writes_deck(case, capsys):
    d, p_true, test = case
    out = d / "updated"
    assert main(["update", str(d / "nominal.bdf"), "--modes", str(d / "test_modes.uff"), "--params",
                 str(d / "params.toml"), "-o", str(out)]) == 0
    s = json.loads((out / "update.json").read_text())
    got = [s["parameters"][k]["updated"] for k in ("E_wing", "t_wing", "t_fin")]
    np.testing.assert_allclose(got, p_true[:3], rtol=2e-3)
    before = max(abs(p["freq_error_pct"]) for p in s["correlation_before"]["pairs"])
    after = max(abs(p["freq_error_pct"]) for p in s["correlation_after"]["pairs"])
    assert after < 0.1 < before
    # the exported deck re-imports with the updated frequencies
    from modalab.app.pipeline import load_model

    upd = load_model(out / "updated.bdf").modes(20)
    f = upd.freq_hz[upd.freq_hz > 1.0][:test.n_modes]
    np.testing.assert_allclose(np.sort(f), np.sort(test.freq_hz), rtol=2e-3)
    assert (out / "mac_before.png").exists() and (out / "mac_after.png").exists()
    assert (out / "convergence.png").exists()


def test_update_needs_the_right_data(case, capsys):
    d, _, _ = case
    assert main(["update", str(d / "nominal.bdf"), "--modes", str(d / "test_modes.uff"), "--method", "mci",
                 "-o", str(d / "x")]) == 2
    assert "needs measured FRFs" in capsys.readouterr().err


def test_update_cli_direct_method_writes_updated_matrices(case, capsys):
    # the direct methods run through the same stage (they update matrices, not parameters)
    d, _, _ = case
    out = d / "direct"
    assert main(["update", str(d / "nominal.bdf"), "--modes", str(d / "test_modes.uff"), "--method",
                 "direct-lagrange", "-o", str(out)]) == 0
    s = json.loads((out / "update.json").read_text())
    assert s["method"] == "direct-lagrange" and (out / "updated_matrices.npz").exists()
    m = np.load(out / "updated_matrices.npz")
    assert m["K"].shape == m["M"].shape and np.abs(m["dK"]).max() > 0
