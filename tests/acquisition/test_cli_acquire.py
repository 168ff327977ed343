"""``modalab acquire`` from the command line: sim backend (auto and terminal-interactive), resume,
previews instead of a live window without a display, and a clear message without the NI driver."""
import os
import subprocess
import sys

import pytest

from _acq_session_util import ROOT, accepted_hits, journal, small_plan
from modalab.core import uff
from modalab.app.cli import _ConsoleObserver, main


def _run(args, stdin=None):
    env = {**os.environ, "MPLBACKEND": "Agg"}
    env.pop("DISPLAY", None)
    return subprocess.run([sys.executable, "-m", "modalab.app.cli", *map(str, args)], cwd=ROOT, env=env, input=stdin,
                          capture_output=True, text=True, timeout=300)


def _ni_driver_present() -> bool:
    try:
        import nidaqmx.system

        nidaqmx.system.System.local().driver_version
        return True
    except Exception:  # noqa: BLE001
        return False


@pytest.mark.skipif(_ni_driver_present(), reason="this machine has the NI-DAQmx driver")
def test_nidaqmx_backend_without_driver_is_a_clear_message(tmp_path):
    plan = small_plan(tmp_path, points=("14+Z",))
    r = _run(["acquire", plan, "--backend", "nidaqmx", "--auto", "-o", tmp_path / "s"])
    assert r.returncode != 0
    assert "Traceback" not in r.stderr and "Traceback" not in r.stdout
    assert "NI-DAQmx" in r.stderr and "--backend sim" in r.stderr and "install" in r.stderr.lower()
    assert len(r.stderr.strip().splitlines()) == 1
    assert r.stdout == ""                         # the backend line only once every check has passed
    assert not (tmp_path / "s").exists()          # no half session left behind


def test_cli_auto_sim_writes_previews_without_a_display(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.setenv("MODALAB_LIVE_PLOT", "1")     # asked for, but there is no display
    plan = small_plan(tmp_path, points=("1+Z", "19+Z"), hammer_range=2000.0)
    out = tmp_path / "s"
    assert main(["acquire", str(plan), "--backend", "sim", "--auto", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert text.startswith("backend: sim - the simulated lab")
    assert "session complete" in text and "range suggestion: hammer" in text
    assert text.count("lower coherence than the kept hits x1") == 2
    for k in range(2):
        for kind in ("hit", "frf"):
            png = out / "preview" / f"point_{k:03d}_{kind}.png"
            assert png.exists() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    import matplotlib.pyplot as plt

    assert plt.get_fignums() == []                   # no window was opened
    assert len(uff.read_records(out / "session.uff")) == 4


def test_live_plot_only_with_a_display_and_the_flag(tmp_path, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    assert not _ConsoleObserver(tmp_path, live_plot=True).live
    monkeypatch.setenv("DISPLAY", ":0")
    assert _ConsoleObserver(tmp_path, live_plot=True).live
    assert not _ConsoleObserver(tmp_path, live_plot=False).live


def test_cli_interactive_at_the_terminal_then_resume(tmp_path):
    plan = small_plan(tmp_path, points=("19+Z",))
    out = tmp_path / "s"
    # accept, an invalid key, reject; then end of input = quit
    r = _run(["acquire", plan, "--backend", "sim", "-o", out], stdin="a\nx\nr\n")
    assert r.returncode == 3, r.stderr
    assert "please answer one of: a, r, s, b, q" in r.stdout
    assert "session incomplete; continue with" in r.stdout and "--resume" in r.stdout
    before = accepted_hits(journal(out))
    assert len(before) == 1
    r = _run(["acquire", plan, "--backend", "sim", "--auto", "--resume", "-o", out])
    assert r.returncode == 0, r.stderr
    after = accepted_hits(journal(out))
    assert all(after[h] == v for h, v in before.items()) and len(after) == 2
    assert "session complete" in r.stdout


def test_cli_errors_are_one_clear_line(tmp_path, capsys):
    plan = small_plan(tmp_path, points=("14+Z",))
    out = tmp_path / "s"
    out.mkdir()
    (out / "session.json").write_text("{}")
    assert main(["acquire", str(plan), "--backend", "sim", "--auto", "-o", str(out)]) == 2
    cap = capsys.readouterr()
    assert "already holds a session" in cap.err and "--resume" in cap.err
    assert cap.out == ""                   # no backend line before a refusal (issue 14 audit)
    bad = small_plan(tmp_path, points=("14+Z", "99+Z"), name="bad.toml")
    assert main(["acquire", str(bad), "--backend", "sim", "--auto", "-o", str(tmp_path / "t")]) == 2
    assert "99" in capsys.readouterr().err
    assert main(["acquire", str(tmp_path / "missing.toml"), "--auto", "-o", str(tmp_path / "u")]) == 2
    assert "cannot read test plan" in capsys.readouterr().err


@pytest.mark.parametrize("case", ["typo", "binary", "directory", "output_is_a_file", "output_below_a_file",
                                  "hammer_in_mv_per_g"])
def test_cli_acquire_bad_input_is_one_line_exit_2(tmp_path, capsys, case):
    plan = small_plan(tmp_path, points=("14+Z",))
    out = tmp_path / "s"
    expect = str(plan)
    if case == "typo":
        plan = small_plan(tmp_path, points=("14+Z",), name="typo.toml",
                          edit=lambda d: d["acquisition"].update(averges=4))
        expect = "unknown key acquisition.averges; did you mean acquisition.averages?"
    elif case == "hammer_in_mv_per_g":
        # a fresh user's plan: accepted, a whole session run and "peak force 78.9 N" printed as with mV/N
        plan = small_plan(tmp_path, points=("14+Z",), name="unit.toml",
                          edit=lambda d: d["channels"][0].update(sensitivity_unit="mV/g"))
        expect = ("unit.toml: channel 1 (hammer): sensitivity_unit = 'mV/g' is a sensitivity to acceleration, "
                  "but role = 'force' measures force; expected one of mV/N, V/N")
    elif case == "binary":
        plan = tmp_path / "random.toml"
        plan.write_bytes(bytes(range(256)) * 4)
        expect = "random.toml' is not a text file"
    elif case == "directory":
        plan, expect = tmp_path, "is a directory"
    elif case == "output_is_a_file":
        out.write_text("precious")
        expect = "is a file"
    else:
        (tmp_path / "f").write_text("precious")
        out = tmp_path / "f" / "s"
        expect = "is a file, not a folder"      # refused before the session starts, as for every verb
    code = main(["acquire", str(plan), "--backend", "sim", "--auto", "--quiet", "-o", str(out)])
    cap = capsys.readouterr()
    assert code == 2
    assert len(cap.err.strip().splitlines()) == 1 and expect in cap.err and "Traceback" not in cap.err
    assert cap.out == ""                   # the error alone: the backend line only once every check passed
    if case.startswith("output"):
        assert (tmp_path / ("s" if case == "output_is_a_file" else "f")).read_text() == "precious"
    else:
        assert not out.exists()                      # nothing written for a bad plan


def test_cli_acquire_the_demo_project_plan_as_documented(tmp_path, capsys):
    # issue 14 #6: `modalab acquire examples/demo_project/plan.toml --backend sim --auto -o s` was rejected for
    # its own [sim] keys; its structure (nominal.bdf beside it) is found from any working directory
    import tomllib

    import tomli_w

    src = ROOT / "examples" / "demo_project" / "plan_quick.toml"
    d = tomllib.loads(src.read_text())
    d["roving"]["points"] = d["roving"]["points"][:1]
    (tmp_path / "proj").mkdir()
    (tmp_path / "proj" / "plan.toml").write_text(tomli_w.dumps(d))
    (tmp_path / "proj" / "nominal.bdf").write_bytes((src.parent / "nominal.bdf").read_bytes())
    code = main(["acquire", str(tmp_path / "proj" / "plan.toml"), "--backend", "sim", "--auto", "--quiet",
                 "-o", str(tmp_path / "s")])
    assert code == 0, capsys.readouterr().err
    assert "session complete" in capsys.readouterr().out


def _corpus(tmp_path):
    """Damaged copies of a valid plan: truncated at 10/50/99 % and mid-line, random bytes, empty, wrong types,
    a DOF the simulated structure does not have."""
    import random

    def plan(name, edit=None):
        return small_plan(tmp_path, points=("1+Z",), averages=1, max_hits=1, record_s=0.25, name=name,
                          edit=edit).read_bytes()

    src = plan("valid.toml")
    text = src.decode()
    mid = text.index("\n", len(text) // 3) + 5
    rnd = random.Random(14)
    yield "cut10", src[: len(src) // 10]
    yield "cut50", src[: len(src) // 2]
    yield "cut99", src[: len(src) * 99 // 100]
    yield "midline", src[:mid]
    yield "random", bytes(rnd.randrange(256) for _ in range(600))
    yield "empty", b""
    yield "nul", b"\x00" * 64
    yield "rate_string", plan("x.toml", lambda d: d["acquisition"].update(sample_rate_hz="fast"))
    yield "points_string", plan("x.toml", lambda d: d["roving"].update(points="1+Z"))
    yield "noisy_string", plan("x.toml", lambda d: d["sim"].update(noisy={"acc_1Z": "loud"}))
    yield "dead_string", plan("x.toml", lambda d: d["sim"].update(dead="acc_1Z"))
    yield "faults_number", plan("x.toml", lambda d: d["sim"].update(faults=3))
    yield "unknown_dof", plan("x.toml", lambda d: (d.pop("geometry"), d["roving"].update(points=["999+Z"])))


def test_cli_acquire_bad_input_corpus(tmp_path, capsys):
    # every damaged plan: exit 2, one line naming the file, no traceback, no session folder left behind
    # (or, when a cut happens to leave a valid plan, a normal run)
    for name, data in _corpus(tmp_path):
        plan = tmp_path / f"{name}.toml"
        plan.write_bytes(data)
        out = tmp_path / f"out_{name}"
        code = main(["acquire", str(plan), "--backend", "sim", "--auto", "--quiet", "-o", str(out)])
        cap = capsys.readouterr()
        assert "Traceback" not in cap.err + cap.out, name
        assert code == 2, (name, code, cap.err)
        assert len(cap.err.strip().splitlines()) == 1 and f"{name}.toml" in cap.err, (name, cap.err)
        assert not out.exists(), name
