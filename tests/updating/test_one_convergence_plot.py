"""Issue 15: one parameter-convergence figure.  ``updating.methods.mci_plots.plot_convergence`` is the only
definition; the update stage (``modalab update``, raw values), ``MCIUpdater.plot_convergence`` (normalised) and
the report (which embeds the update stage's ``update/convergence.png``) all go through it."""
import ast
import pathlib

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
PACKAGES = ("modalab", "acquisition", "identification", "updating", "hardware_sim")


def _module_functions(name):
    out = []
    for pkg in PACKAGES:
        for f in sorted((ROOT / pkg).rglob("*.py")):
            for node in ast.parse(f.read_text(encoding="utf-8")).body:
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name == name:
                    out.append(str(f.relative_to(ROOT)))
    return out


def test_one_definition_of_the_convergence_plot():
    assert _module_functions("plot_convergence") == ["updating/methods/mci_plots.py"]


def test_raw_and_normalised(tmp_path):
    from updating.methods.mci_plots import plot_convergence

    H = np.array([[2.0, 1.0], [2.2, 0.9], [2.3, 0.85]])
    for norm in (True, False):
        p = plot_convergence(H, tmp_path / f"sub{norm}" / "convergence.png", names=["a", "b"], normalise=norm)
        assert p.is_file() and p.stat().st_size > 1000


def test_the_update_stage_and_the_report_write_and_show_convergence_png(tmp_path):
    from modalab.app.cli import main
    from modalab.app.report import build_report
    from updating.fe import ParametricFEModel
    from updating.fe.bulk import to_bulk, write_bdf
    from updating.fe.models.garteur import garteur_model, garteur_parameters

    nominal = garteur_model(mesh=2)
    write_bdf(to_bulk(nominal), tmp_path / "nominal.bdf")
    pm = ParametricFEModel(nominal, garteur_parameters(nominal))
    ms = pm.model_at(np.array([1.05, 1.0, 1.0, 1.0])).modes(14)
    dofs = [x for x in ms.dofs if x.axis == 3]
    test = ms.select_dofs(dofs).select_modes(np.flatnonzero(ms.freq_hz > 1.0)[:6])
    test.coordinates = {x.node: tuple(nominal.nodes[x.node].xyz) for x in dofs}
    test.to_uff(tmp_path / "test_modes.uff")
    (tmp_path / "params.toml").write_text('[[parameter]]\nname = "E_wing"\nfield = "E"\nproperties = ["wing"]\n')
    run = tmp_path / "run"
    assert main(["update", str(tmp_path / "nominal.bdf"), "--modes", str(tmp_path / "test_modes.uff"),
                 "--params", str(tmp_path / "params.toml"), "-o", str(run / "update")]) == 0
    png = run / "update" / "convergence.png"
    assert png.is_file() and png.stat().st_size > 1000
    html, _ = build_report(run, run / "report", title="convergence")
    text = pathlib.Path(html).read_text(encoding="utf-8")
    i = text.index("<figcaption>Parameter convergence</figcaption>")
    assert "data:image/png;base64," in text[text.rindex("<figure>", 0, i):i]


def test_mci_updater_writes_it(tmp_path):
    from updating.methods.mci import MCIUpdater
    from cases import six_dof_pair

    X, A = six_dof_pair()
    frf = X.structure().frf(np.arange(0.2, 30, 0.2), responses=["2+X", "3+X"], references=["2+X"])
    u = MCIUpdater(max_iter=3).fit(A, frf)
    p = u.plot_convergence(tmp_path / "conv.png", model=A, reference=X.p0)
    assert pathlib.Path(p).is_file() and pathlib.Path(p).stat().st_size > 1000
