"""``modalab run`` on the smaller demo: interrupted and resumed, end to end, manifest skip/rerun logic.

One quick demo run is shared by the tests of this module (it is the expensive part): it is started in a
subprocess, killed (SIGKILL, like a crash or a power cut) in the middle of the acquisition, and continued in
this process.  The other tests check the artifacts, the diagnosis and how reruns use the manifest.
"""
from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from modalab.app.demo_project import DEMO_FILES, _ERRORS, DEMO_PARAMETERS, demo_project_dir, run_demo
from modalab.core.errors import PlanError
from modalab.app.project import STAGES, load_project
from modalab.app.run import Manifest, content_hash, run_project, sha256_file

REPO = Path(__file__).resolve().parents[2]
#: one worker runs this module with -n and --dist loadgroup (the README's test command): its module fixture is a whole demo run
pytestmark = pytest.mark.xdist_group("demo_run")


def _hit_times(out: Path) -> list:
    j = out / "acquire" / "session" / "journal.jsonl"
    if not j.is_file():
        return []
    times = []
    for line in j.read_text().splitlines():
        try:
            e = json.loads(line)
        except json.JSONDecodeError:            # a line cut by the kill
            continue
        if e.get("event") == "hit":
            times.append(float(e["time"]))
    return times


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo_run")
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", MPLBACKEND="Agg")
    code = f"from modalab.app.demo_project import run_demo; run_demo({str(out)!r}, quick=True)"
    proc = subprocess.Popen([sys.executable, "-c", code], cwd=REPO, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)
    t_end = time.time() + 240
    while time.time() < t_end and len(_hit_times(out)) < 8 and proc.poll() is None:
        time.sleep(0.2)
    killed_at = time.time()
    alive = proc.poll() is None
    if alive:
        os.kill(proc.pid, signal.SIGKILL)
    err = proc.communicate()[1].decode(errors="replace")
    assert alive, f"the demo run ended before it could be interrupted: {err[-2000:]}"
    before = _hit_times(out)
    man_before = json.loads((out / "manifest.json").read_text()) if (out / "manifest.json").is_file() else {}
    t0 = time.perf_counter()
    res = run_demo(out, quick=True)
    return {"out": out, "result": res, "killed_at": killed_at, "hits_before": before, "manifest_before": man_before,
            "elapsed": time.perf_counter() - t0}


def test_interrupted_acquisition_resumes(demo):
    out = demo["out"]
    # nothing was complete at the kill, so the manifest had no stage
    assert "acquire" not in demo["manifest_before"].get("stages", {})
    assert len(demo["hits_before"]) >= 8
    after = _hit_times(out)
    # the hits taken before the kill were kept: the session continued instead of starting again
    assert after[: len(demo["hits_before"])] == demo["hits_before"]
    assert all(t < demo["killed_at"] for t in demo["hits_before"])
    assert len(after) > len(demo["hits_before"])
    assert demo["result"].status["acquire"] == "ran"


def test_end_to_end_artifacts_and_manifest(demo):
    out, res = demo["out"], demo["result"]
    assert all(res.status[s] == "ran" for s in STAGES), res.status
    for rel in ("acquire/session.uff", "frf/frf.uff", "frf/coherence.png", "identify/modes.uff",
                "identify/stabilisation.png", "correlate/mac_before.png", "update/updated.bdf", "update/mac_after.png",
                "update/convergence.png", "diagnose/diagnosis.json", "diagnose/diagnosed.bdf", "diagnose/figures/mci_maps.png",
                "diagnose/frf_overlay_models.png", "report/report.html", "report/summary.json"):
        assert (out / rel).is_file(), rel
    man = json.loads((out / "manifest.json").read_text())
    assert list(man["stages"]) == list(STAGES)
    for s, e in man["stages"].items():
        assert len(e["key"]) == 64 and e["outputs"]
        for rel, h in e["outputs"].items():
            assert content_hash(out / rel) == h, rel
    # the report embeds every figure it names
    html = (out / "report" / "report.html").read_text()
    assert html.count("<img ") >= 10 and 'src="http' not in html


def test_outputs_follow_the_schemas(demo):
    """modes.json, diagnosis.json, summary.json and the session's summary.json of a run follow the schemas shipped
    with the package."""
    from modalab.app.outputs import validate

    out = demo["out"]
    validate(out / "acquire" / "session" / "summary.json", "session_summary")
    validate(out / "identify" / "modes.json", "modes")
    validate(out / "diagnose" / "diagnosis.json", "diagnosis")
    validate(out / "report" / "summary.json", "summary")
    summary = json.loads((out / "report" / "summary.json").read_text())
    assert summary["diagnosis"] == json.loads((out / "diagnose" / "diagnosis.json").read_text())


def test_updating_moves_parameters_towards_the_truth(demo):
    upd = json.loads((demo["out"] / "update" / "update.json").read_text())
    assert upd["converged"], upd["history"][-1]          # stationary at the end, not stalled
    truth = dict(zip(DEMO_PARAMETERS, _ERRORS))
    # the thicknesses are found; E_wing and rho_fuselage absorb part of what the model leaves out
    for name in ("t_fin", "t_wing"):
        p = upd["parameters"][name]["updated"]
        assert abs(p - truth[name]) < 0.5 * abs(1.0 - truth[name]), (name, p, truth[name])
    before = json.loads((demo["out"] / "correlate" / "correlation.json").read_text())
    err0 = np.mean(np.abs([r["freq_error_pct"] for r in before["pairs"]]))
    err1 = np.mean(np.abs([r["freq_error_pct"] for r in upd["correlation_after"]["pairs"]]))
    assert err1 < 0.6 * err0


def test_diagnosis_finds_the_concealed_effect(demo):
    d = json.loads((demo["out"] / "diagnose" / "diagnosis.json").read_text())
    assert d["statement"] and d["findings"], d.get("statement")
    # what the truth builder hides: 200 g at the right wing tip (node 218 of the nominal numbering)
    masses = [f for f in d["findings"] if f["physics"] == "added_mass" and 218 in f["nodes"]]
    assert masses, [f["description"] for f in d["findings"]]
    m = masses[0]["values"][0]
    assert m["unit"] == "kg" and abs(m["value"] - 0.2) < 0.25 * 0.2, m
    assert "218" in d["statement"]
    fit = d["fit"]
    assert fit["with_physics"]["frf_error_held_out"] < fit["parameters_only"]["frf_error_held_out"] \
        < fit["nominal"]["frf_error_held_out"]
    # with the missing mass in the model, the wing parameters it had biased come back towards the truth: compared
    # within the same fit (the diagnosis' own parameters-only fit), not across methods.  (This test used to compare
    # rho_fuselage with the update stage's value; that held only while the update weighted every frequency with an
    # assumed 1 %.  With the identification's sigma the update puts rho_fuselage within 0.6 % of the truth, 0.9448
    # vs 0.95, and both diagnosis fits at 0.962-0.966: a difference between methods, and rho_fuselage is not what
    # a wing-tip mass biases.)
    truth = dict(zip(DEMO_PARAMETERS, _ERRORS))
    for name in ("E_wing", "t_wing"):
        v = d["parameters"][name]
        assert abs(v["updated"] - truth[name]) < abs(v["parameters_only"] - truth[name]), (name, v)
    err = {k: np.sqrt(np.mean([(d["parameters"][n][k] - truth[n]) ** 2 for n in DEMO_PARAMETERS]))
           for k in ("parameters_only", "updated")}
    assert err["updated"] < 0.6 * err["parameters_only"], err
    # the update stage (parameters only, from the modes) absorbs the mass the same way: E_wing stays biased, and it
    # says that its frequency residuals are far beyond the identification's sigma (the model leaves something out)
    upd = json.loads((demo["out"] / "update" / "update.json").read_text())
    assert abs(d["parameters"]["E_wing"]["updated"] - truth["E_wing"]) < \
        0.2 * abs(upd["parameters"]["E_wing"]["updated"] - truth["E_wing"])
    assert upd["identifiability"]["residual_check"]["frequency"]["std_factor"] > 10


def test_the_update_uses_the_identifications_uncertainties_and_the_report_says_so(demo):
    """run/demo update from modes.json (the UFF carries no frequency uncertainty): the frequencies are weighted by
    the identification's freq_std_hz, and the report says so, and that the residuals exceed them (the demo's
    model leaves out a mass)."""
    upd = json.loads((demo["out"] / "update" / "update.json").read_text())
    assert upd["frequency_weights"].startswith("relative sigma per test mode") and "modes.json" in upd["frequency_weights"]
    html = (demo["out"] / "report" / "report.html").read_text()
    assert "Frequency weights: relative sigma per test mode" in html
    assert "The frequency residuals are" in html


def test_report_says_simulated_which_model_and_the_selection(demo):
    """Issue 14: simulated data are said so (session.json, UFF ID lines, summary.json, the report); the report
    names the model to use; the selected term is shown with its rank; damping columns in %; each file has one
    writer (the engine's figures in figures/, the stage's overlay under its own name)."""
    out = demo["out"]
    assert json.loads((out / "acquire" / "session" / "session.json").read_text())["backend"] == "sim"
    assert b'"backend":"sim"' in (out / "acquire" / "session.uff").read_bytes()
    assert b'"backend":"sim"' in (out / "frf" / "frf.uff").read_bytes()
    s = json.loads((out / "report" / "summary.json").read_text())
    assert s["backend"] == "sim" and s["simulated"] is True
    assert s["model_to_use"]["file"] == "diagnose/diagnosed.bdf" and "parameters-only" in s["model_to_use"]["why"]
    text = (out / "report" / "report.html").read_text(encoding="utf-8")
    assert "<b>Simulated data.</b>" in text and "Model to use: diagnose/diagnosed.bdf" in text
    dec = json.loads((out / "diagnose" / "diagnosis.json").read_text())["decisions"]
    assert any("218" in t["candidate"] for t in dec if t["decision"] == "found")
    assert "Selected terms" in text and "point mass at node 218" in text.split("Selected terms")[1][:2000]
    assert "σ ζ [%]" in text and "damping_std" not in text and "MPD [°]" in text and "χ² ratio" in text
    assert not (out / "diagnose" / "mci_maps.png").exists() and not (out / "diagnose" / "frf_overlay.png").exists()


def _conclusions(out: Path, diagnosis: bool = True) -> dict:
    """What a run concludes: identified modes, pairs, updated parameters and findings (node, value)."""
    modes = json.loads((out / "identify" / "modes.json").read_text())
    corr = json.loads((out / "correlate" / "correlation.json").read_text())
    upd = json.loads((out / "update" / "update.json").read_text())
    got = {"modes": modes["table"],
           "pairs": [(r["test_mode"], r["analysis_mode"], r["mac"]) for r in corr["pairs"]],
           "updated": {k: v["updated"] for k, v in upd["parameters"].items()}}
    if diagnosis:
        d = json.loads((out / "diagnose" / "diagnosis.json").read_text())
        got["findings"] = [(f["physics"], f["nodes"], f["dofs"], [v["value"] for v in f["values"]])
                           for f in d["findings"]]
        got["statement"] = d["statement"]
    return got


def test_the_same_demo_twice_up_to_the_update_gives_the_same_modes_pairs_and_parameters(demo, tmp_path):
    """Deterministic: the quick demo run again from scratch up to the update (here against the shared run, which
    was interrupted and resumed) gives the same modes, pairs and updated parameters to the last bit (fixed seeds
    in the simulated lab, fixed ARPACK start vectors, deterministic pairing).  The whole demo twice, with its
    diagnosis, is in the slow tier (below); the diagnosis' own determinism is tested in the default run on other
    inputs: on one process and two (tests/updating/test_diagnosis_parallel.py), serially and on a Dask cluster
    (tests/cli/test_cli_campaign.py)."""
    res = run_demo(tmp_path / "again", quick=True, until_stage="update")
    assert res.status["diagnose"] == "not requested" and res.status["update"] == "ran"
    a, b = _conclusions(demo["out"], diagnosis=False), _conclusions(tmp_path / "again", diagnosis=False)
    assert a["modes"] and a["pairs"]
    assert a == b


@pytest.mark.slow
def test_the_same_demo_twice_gives_the_same_conclusions(demo, tmp_path):
    """Deterministic: ``modalab demo --quick`` run again from scratch (here against the shared run, which was
    interrupted and resumed) gives the same modes, pairs, parameters and findings — nodes and values to the
    last bit (fixed seeds in the simulated lab, fixed ARPACK start vectors, deterministic pairing).  Slow tier:
    the default run's demo, its rerun up to the update and the README's `modalab run` of the quick project took
    three quarters of CI's 25 minutes with this third demo."""
    from modalab.app.cli import main

    assert main(["demo", "--quick", "-o", str(tmp_path / "again")]) == 0
    a, b = _conclusions(demo["out"]), _conclusions(tmp_path / "again")
    assert a["findings"] and a["findings"] == b["findings"]
    assert a == b


def test_run_command_prints_a_line_per_stage_and_the_report_last(demo, capsys):
    """Not on a terminal: one line per stage with its time (or 'up to date'), the report's path last."""
    from modalab.app.cli import main

    proj = demo["out"] / "project" / "project_quick.toml"
    assert main(["run", str(proj), "-o", str(demo["out"]), "--from", "report"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert [ln.split()[1] for ln in lines[:len(STAGES)]] == list(STAGES)
    assert all("up to date" in ln for ln in lines[:len(STAGES) - 1])
    assert re.fullmatch(r"\[7/7\] report +done in \d+\.\d s", lines[len(STAGES) - 1])
    assert lines[-1] == f"report: {demo['out'] / 'report' / 'report.html'}"
    assert "data: simulated (backend sim: the simulated lab, not hardware)" in lines
    assert f"model to use: {demo['out'] / 'diagnose' / 'diagnosed.bdf'}" in lines


def test_ctrl_c_during_run_says_how_to_continue(tmp_path):
    d = tmp_path / "p"
    d.mkdir()
    for name in DEMO_FILES:
        (d / name).write_bytes((demo_project_dir() / name).read_bytes())
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", MPLBACKEND="Agg", PYTHONPATH=str(REPO))
    proc = subprocess.Popen([sys.executable, "-m", "modalab.app.cli", "run", "project_quick.toml", "-o", "out"], cwd=d,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    t_end = time.time() + 240
    while time.time() < t_end and not _hit_times(d / "out") and proc.poll() is None:
        time.sleep(0.2)
    assert proc.poll() is None, proc.communicate()[1].decode()[-2000:]
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err.decode()[-2000:]
    assert "Traceback" not in err.decode()
    assert out.decode().strip().splitlines()[-1] == (
        "interrupted during the acquire stage. Completed stages are kept (manifest.json) and an interrupted "
        "acquisition keeps every accepted hit. Continue with: modalab run project_quick.toml -o out")


def test_rerun_skips_and_changed_options_rerun_only_dependents(demo, tmp_path):
    out = demo["out"]
    proj_path = out / "project" / "project_quick.toml"
    t0 = time.perf_counter()
    r = run_project(proj_path, out)
    assert all(v == "skipped" for v in r.status.values()), r.status
    assert time.perf_counter() - t0 < 20
    # the command line: the same, with per-stage progress
    from modalab.app.cli import main

    assert main(["run", str(proj_path), "-o", str(out), "--quiet"]) == 0
    # a report option: only the report
    proj = load_project(proj_path)
    proj.options["report"]["title"] = "another title"
    r = run_project(proj, out)
    assert [s for s, v in r.status.items() if v == "ran"] == ["report"]
    assert "another title" in (out / "report" / "report.html").read_text()
    # a correlation option: correlate and what reads it (update, report); FRFs, identification and the
    # diagnosis stay (the identified modes and the FRFs did not change)
    proj.options["correlate"]["mac_min"] = 0.6
    r = run_project(proj, out)
    ran = [s for s, v in r.status.items() if v == "ran"]
    assert ran == ["correlate", "update", "report"], r.status
    assert r.status["diagnose"] == "skipped" and r.status["identify"] == "skipped"
    # --from / --until: just identify again; identical modes -> nothing downstream reruns afterwards
    r = run_project(proj, out, from_stage="identify", until_stage="identify")
    assert [s for s, v in r.status.items() if v == "ran"] == ["identify"]
    assert r.status["report"] == "not requested"
    r = run_project(proj, out)
    assert [s for s, v in r.status.items() if v == "ran"] in ([], ["report"]), r.status
    # a tampered output is noticed and only its stage (and what depends on a changed product) reruns
    p = out / "update" / "convergence.png"
    p.write_bytes(p.read_bytes() + b"x")
    m = Manifest(out)
    assert not m.valid("update", m.entry("update")["key"])
    r = run_project(proj, out)
    assert r.status["update"] == "ran" and r.status["diagnose"] == "skipped"


def test_project_validation_names_the_problem(tmp_path):
    d = tmp_path / "p"
    d.mkdir()
    for name in DEMO_FILES:
        (d / name).write_bytes((demo_project_dir() / name).read_bytes())
    text = (d / "project_quick.toml").read_text()
    (d / "bad1.toml").write_text(text.replace('bulk = "nominal.bdf"', 'bulk = "missing.bdf"'))
    with pytest.raises(PlanError, match="missing.bdf"):
        load_project(d / "bad1.toml")
    (d / "bad2.toml").write_text(text.replace("[identify]", "[identify]\nbandwidth = 3"))
    with pytest.raises(PlanError, match=r"\[identify\] unknown key bandwidth \(did you mean band_hz\?\); expected one of band_hz, "):
        load_project(d / "bad2.toml")
    (d / "bad3.toml").write_text(text.replace("band_hz = [2.0, 80.0]", "band_hz = [80.0, 2.0]", 1))
    with pytest.raises(PlanError, match="0 <= low < high"):
        load_project(d / "bad3.toml")
    (d / "bad4.toml").write_text(text.replace('plan = "plan_quick.toml"', 'plan = "plan_quick.toml"\nfrf = "x.uff"'))
    with pytest.raises(PlanError, match="exactly one of plan"):
        load_project(d / "bad4.toml")
    (d / "params_bad.toml").write_text('[[parameter]]\nname = "E_wing"\nfield = "E"\n')
    (d / "bad5.toml").write_text(text.replace('parameters = "params.toml"', 'parameters = "params_bad.toml"'))
    with pytest.raises(PlanError, match="exactly one selector"):
        load_project(d / "bad5.toml")
    with pytest.raises(PlanError, match="stage 'fit'"):
        run_project(d / "project_quick.toml", tmp_path / "o", from_stage="fit")


def test_examples_folder_matches_the_packaged_demo():
    ex = REPO / "examples" / "demo_project"
    for name in DEMO_FILES:
        assert (ex / name).read_bytes() == (demo_project_dir() / name).read_bytes(), name


# ----------------------------------------------------------------------------- manifest unit tests
from hypothesis import given, settings, strategies as st  # noqa: E402

from modalab.app.run import stage_key  # noqa: E402

_opt_values = st.one_of(st.integers(-5, 5), st.floats(-10, 10, allow_nan=False), st.text(max_size=5), st.booleans(),
                        st.none(), st.lists(st.floats(0, 100, allow_nan=False), max_size=3))


@settings(max_examples=60, deadline=None)
@given(opts=st.dictionaries(st.text(min_size=1, max_size=6), _opt_values, min_size=1, max_size=6), data=st.data())
def test_stage_key_changes_with_any_option_and_ignores_order(opts, data):
    inputs = {"model": "ab" * 32}
    k = stage_key({"sec": opts}, inputs, {})
    assert k == stage_key({"sec": dict(reversed(list(opts.items())))}, inputs, {})
    name = data.draw(st.sampled_from(sorted(opts)))
    new = data.draw(_opt_values.filter(lambda v: repr(v) != repr(opts[name])))
    changed = dict(opts, **{name: new})
    assert stage_key({"sec": changed}, inputs, {}) != k
    assert stage_key({"sec": opts}, {"model": "cd" * 32}, {}) != k
    assert stage_key({"sec": opts}, inputs, {"frf": {"frf/frf.uff": "0" * 64}}) != k


def test_manifest_atomic_entries_and_output_hashes(tmp_path):
    out = tmp_path / "run"
    (out / "frf").mkdir(parents=True)
    f = out / "frf" / "frf.uff"
    f.write_bytes(b"data")
    m = Manifest(out)
    m.record("frf", {"key": "k1", "outputs": {"frf/frf.uff": content_hash(f)}})
    # a crash while the next manifest was being written leaves a temporary file, never a torn manifest
    (out / ".manifest.json.999.tmp").write_text('{"version": 1, "sta')
    m2 = Manifest(out)
    assert m2.valid("frf", "k1") and not m2.valid("frf", "k2") and not m2.valid("identify", "k1")
    f.write_bytes(b"dat4")
    assert not Manifest(out).valid("frf", "k1")
    # in a UFF the writer's time stamp does not count, the data does
    from modalab.core import uff
    from modalab.core.frf import FRF

    frf = FRF(freq_hz=np.linspace(1, 10, 10), H=np.ones((1, 1, 10), complex), responses=["1+Z"], references=["1+Z"])
    uff.write_frf(f, frf)
    h = content_hash(f)
    time.sleep(1.1)
    uff.write_frf(f, frf)
    assert content_hash(f) == h and sha256_file(f) != h
    uff.write_frf(f, FRF(freq_hz=frf.freq_hz, H=2 * frf.H, responses=["1+Z"], references=["1+Z"]))
    assert content_hash(f) != h
    f.unlink()
    assert not Manifest(out).valid("frf", "k1")
    # a corrupt manifest means: everything runs again (with a warning), not a crash
    (out / "manifest.json").write_text("{not json")
    assert Manifest(out).stages == {}
