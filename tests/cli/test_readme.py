"""The README's promises: its two commands, every line of "Commands in practice", the plan example validates,
.ci/run runs the test command."""
import json
import pathlib
import shlex
import shutil
import tomllib

ROOT = pathlib.Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text()


def _blocks(lang):
    return [b.split("```")[0] for b in README.split(f"```{lang}")[1:]]


def test_opens_with_the_two_commands_and_ci_runs_the_test_command():
    first = _blocks("bash")[0].strip().splitlines()
    setup = first[0].split("#")[0].strip()
    tests = first[1].split("#")[0].strip()
    assert setup.startswith("pip install -e .") and "modalab demo" in setup
    assert tests == "pip install -e '.[test]' && python -m pytest -q -n auto --dist loadgroup"
    ci = (ROOT / ".ci" / "run").read_text().strip().splitlines()
    assert ci[-1].strip() == tests


def test_plan_example_is_valid():
    from acquisition.plan import TestPlan

    plan = TestPlan.from_dict(tomllib.loads(_blocks("toml")[0]), source="README")
    assert plan.pattern == "hammer" and plan.averages == 3


def test_parameter_example_loads(tmp_path):
    from modalab.app.stages import load_parameters
    from updating.fe.models.garteur import garteur_model

    (tmp_path / "p.toml").write_text(_blocks("toml")[1])
    params = load_parameters(tmp_path / "p.toml", garteur_model(mesh=2))[0]
    assert params[0].name == "E_wing"


def test_diagnosis_schema_example_is_json():
    d = json.loads(_blocks("json")[0])
    assert set(d) >= {"findings", "parameters", "fit", "statement"}
    for block in d["fit"].values():
        assert {"frf_error_held_out", "freq_error_max_pct", "mac_min"} <= set(block)


def _commands_in_practice() -> list:
    block = README.split("## Commands in practice")[1].split("```bash")[1].split("```")[0]
    return [ln.split("#")[0].strip() for ln in block.splitlines() if ln.split("#")[0].strip()]


def test_commands_in_practice_run_as_written(tmp_path, monkeypatch, capsys, caplog):
    """Every line, in order, in a folder holding only a clone's examples/ (in-process: main() per line); the
    identify line's band cuts no resonance (--band 5 700 cut the 695.5 Hz mode)."""
    from modalab.app.cli import main
    from modalab.app.outputs import validate

    shutil.copytree(ROOT / "examples", tmp_path / "examples")
    monkeypatch.chdir(tmp_path)
    lines = _commands_in_practice()
    assert len(lines) >= 9 and lines[0].startswith("modalab sim")
    for line in lines:
        argv = shlex.split(line)
        assert argv[0] == "modalab", line
        with caplog.at_level("WARNING"):
            assert main(argv[1:]) == 0, (line, capsys.readouterr().err[-2000:])
    cut = [r.getMessage() for r in caplog.records if "sits at the band's" in r.getMessage()]
    assert cut == [], cut
    validate(tmp_path / "modes.json", "modes")
    validate(tmp_path / "diagnosis.json", "diagnosis")
    validate(tmp_path / "diag" / "diagnosis.json", "diagnosis")
    validate(tmp_path / "out" / "report" / "summary.json", "summary")
    validate(tmp_path / "report" / "summary.json", "summary")          # modalab report . (the step-by-step chain)
    _exact_model_stays_exact(json.loads((tmp_path / "diagnosis.json").read_text()))
    html = (tmp_path / "report" / "report.html").read_text()
    assert "The diagnosis stage has not run" not in html and "stabilisation" in html
    # the commands run one by one keep no manifest: no empty Stages table; modalab run's report has one
    assert "<h2>Stages</h2>" not in html and "<h2>Stages</h2>" in (tmp_path / "out" / "report" / "report.html").read_text()
    # the coherence of frf.uff, drawn by the report (modalab frf draws no map; it said "not available")
    assert "<figcaption>Coherence map</figcaption>" in html and "Coherence map: not available" not in html
    for p in ("model.bdf", "params.toml", "corr.json", "updated/updated.bdf", "session/session.uff",
              "out/report/report.html"):
        assert (tmp_path / p).is_file(), p


def _exact_model_stays_exact(d):
    """The chain's data are simulated from the exported model.bdf itself: the diagnosis reads χ²/N about 1 in
    units of the data's noise, finds nothing, leaves the parameters at nominal, and its test frequencies (FRF
    peaks, no --modes) are refined between the 0.25 Hz lines.  With the viscous demo (ζ rising with frequency,
    which PARAM G cannot express) χ²/N read 12-14."""
    fit = d["fit"]["nominal"]
    assert fit["chi2_per_value_train"] < 1.5 and fit["chi2_per_value_held_out"] < 1.5, fit
    assert d["findings"] == []
    for name, v in d["parameters"].items():
        if v["mode"] == "factor":
            assert abs(v["updated"] - 1.0) < 0.003, (name, v)
    f = [p["test_hz"] for p in d["pairing"]["nominal"]["pairs"]]
    assert len(f) >= 10 and all(abs(x / 0.25 - round(x / 0.25)) > 1e-3 for x in f), f


def test_the_slow_tier_command_selects_the_tests_left_out_of_the_default_run():
    """Development's ``python -m pytest -q -n auto -m slow`` (collected only, not run: it takes about half an hour)
    selects every test marked ``slow`` and nothing else: the benchmark's tuning seeds but for its two controls,
    which the default run keeps."""
    import ast
    import subprocess
    import sys

    cmd = "python -m pytest -q -n auto -m slow"
    assert any(ln.split("#")[0].strip() == cmd for b in _blocks("bash") for ln in b.splitlines()), cmd
    marked = set()
    for path in (ROOT / "tests").rglob("test_*.py"):
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, ast.FunctionDef) and any(ast.unparse(d) == "pytest.mark.slow"
                                                          for d in node.decorator_list):
                marked.add(node.name)
    seeds = ast.parse((ROOT / "tests" / "benchmarks_discovery" / "test_discovery_seeds.py").read_text())
    tests = {n.name for n in seeds.body if isinstance(n, ast.FunctionDef) and n.name.startswith("test_")}
    controls = {n for n in tests if "_control_" in n}
    assert len(controls) == 2 and not controls & marked and tests - controls <= marked
    out = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-m", "slow", "-p", "no:cacheprovider",
                          "-p", "no:xdist"], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    collected = {ln.split("::")[-1].split("[")[0] for ln in out.splitlines() if "::" in ln}
    assert collected == marked, (collected ^ marked)
