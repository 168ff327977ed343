"""The CLI in-process: ``main([...])`` with small simulated data; bad input gives a message, not a traceback."""
import json

import numpy as np
import pytest

from modalab.app.cli import build_parser, main
from modalab.core.frf import FRF
from modalab.app.outputs import validate


@pytest.fixture(scope="module")
def hits(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    out = d / "hits.uff"
    assert main(["sim", "-o", str(out), "--points", "1+Z", "4+Z", "19+Z", "--references", "19+Z", "1+Z",
                 "--hits", "2", "--samples", "4096", "--seed", "3"]) == 0
    return out


def test_help_lists_every_command(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    text = capsys.readouterr().out
    for cmd in ("demo", "sim", "frf", "info", "acquire", "identify", "correlate", "update", "diagnose"):
        assert cmd in text
    sub = build_parser()._subparsers._group_actions[0].choices
    for name, p in sub.items():
        assert "Units: SI" in p.format_help(), name
    # a description for users, not the module's developer docstring
    assert "modalab demo -o modalab-demo" in text and "main(args=None)" not in text and "``" not in text


def test_sim_shows_progress_and_exports_the_model_it_simulated(tmp_path, capsys):
    from hardware_sim.demo import demo_structure

    from modalab.app.stages import load_parameters
    from modalab.app.stages import _sim_structure, load_model

    assert main(["sim", "-o", str(tmp_path / "h.uff"), "--points", "1+Z", "19+Z", "--hits", "1", "--samples", "2048",
                 "--no-plot", "--export-model", str(tmp_path / "m")]) == 0
    out = capsys.readouterr().out
    assert "points 1/2: 1+Z" in out and "points 2/2: 19+Z" in out
    # the exported bulk data has the simulated structure's modes (same grillage as CBAR/PBAR, springs, SPC)
    model = load_model(tmp_path / "m" / "model.bdf")
    fe = model.modes(12)
    w, _ = demo_structure().normal_modes()
    np.testing.assert_allclose(fe.freq_hz, w[:12] / (2 * np.pi), rtol=1e-6)
    # and its damping: the bulk data's FRFs are the simulated structure's (PARAM G on the beams, GE on the
    # bungees); the viscous demo (zeta rising with frequency) left chi2/N at 12-14 in the README's diagnosis
    simulated, _ = _sim_structure("demo")
    f = np.linspace(1.0, 700.0, 2797)
    dofs = ["1+Z", "4+Z", "12+Z", "19+Z"]
    h_fe = model.structure().frf(f, responses=dofs, references=dofs[:2]).H
    h_sim = simulated.frf(f, responses=dofs, references=dofs[:2]).H
    assert np.max(np.abs(h_fe - h_sim) / np.abs(h_sim)) < 1e-4
    params = load_parameters(tmp_path / "m" / "params.toml")[0]
    assert [p.name for p in params] == ["E_fuselage", "rho_fuselage", "E_wing", "rho_wing"]


def test_sim_frf_info_chain(hits, tmp_path, capsys):
    out = tmp_path / "frf.uff"
    assert main(["frf", str(hits), "-o", str(out), "--exp-end", "0.05"]) == 0
    assert (tmp_path / "frf.png").stat().st_size > 10000
    frf = FRF.from_uff(out)
    # reciprocity: accelerometers became references, hit points responses
    assert [str(d) for d in frf.references] == ["19+Z", "1+Z"]
    assert {str(d) for d in frf.responses} == {"1+Z", "4+Z", "19+Z"}
    assert frf.window_beta_per_s > 0
    assert np.all((frf.coherence >= 0) & (frf.coherence <= 1 + 1e-12))
    assert frf.freq_hz[-1] <= 2048 / 2.56 + 1e-9
    capsys.readouterr()
    assert main(["info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["functions"] == {"FRF": 6, "coherence": 6}


def test_frf_against_exact(hits, tmp_path):
    from modalab.app.stages import _sim_structure

    out = tmp_path / "frf.uff"
    main(["frf", str(hits), "-o", str(out), "--no-plot"])
    frf = FRF.from_uff(out).band(10, 700)
    ex = _sim_structure("demo")[0].frf(frf.freq_hz, responses=frf.responses, references=frf.references)
    good = frf.coherence > 0.995
    rel = np.abs(frf.H[good] - ex.H[good]) / np.abs(ex.H[good])
    assert np.median(rel) < 0.03     # placement scatter of the simulated hammer (3 mm) dominates


def test_identify_cli(hits, tmp_path, capsys):
    frf_path = tmp_path / "frf.uff"
    main(["frf", str(hits), "-o", str(frf_path), "--no-plot"])
    modes_path = tmp_path / "modes.uff"
    assert main(["identify", str(frf_path), "--band", "10", "300", "-o", str(modes_path),
                 "--json", str(tmp_path / "m.json"), "--plots", str(tmp_path / "p")]) == 0
    from modalab.core.modes import ModeSet

    m = ModeSet.from_uff(modes_path)
    # demo structure elastic modes observable from fuselage/wing-tip points in 10-300 Hz
    assert np.min(np.abs(m.freq_hz - 18.97)) < 0.1
    assert np.min(np.abs(m.freq_hz - 118.4)) < 0.5
    assert (tmp_path / "p" / "stabilisation.png").exists()
    doc = json.loads((tmp_path / "m.json").read_text())
    validate(doc, "modes")
    assert [r["freq_hz"] for r in doc["table"]] == doc["freq_hz"] == m.freq_hz.tolist()
    # the JSON reads back as the same modes (correlate and update take it instead of the UFF)
    np.testing.assert_allclose(ModeSet.from_json(tmp_path / "m.json").shapes, m.shapes, rtol=1e-6, atol=1e-12)


@pytest.mark.parametrize("args,needle", [
    (["frf", "nope.uff", "-o", "x.uff"], "nope.uff"),
    (["info", "missing.uff"], "missing.uff"),
    (["acquire", "missing_plan.toml", "-o", "s"], "cannot read test plan"),
    (["correlate", "missing.bdf", "m.uff"], "missing.bdf"),
])
def test_bad_input_is_a_message(args, needle, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    code = main(args)
    err = capsys.readouterr().err
    assert code == 2
    assert needle in err and "Traceback" not in err


def test_the_cli_limits_blas_threads(monkeypatch, tmp_path):
    """Commands run with BLAS limited to MODALAB_BLAS_THREADS threads (default 1); a bad value is named."""
    import contextlib

    from modalab.app import cli

    limits, seen = [], []

    def recorder(limits=None, user_api=None, _log=limits):
        _log.append(limits)
        return contextlib.nullcontext()
    monkeypatch.setattr(cli, "threadpool_limits", recorder)      # threadpoolctl's, imported by cli

    def fake(a):
        seen.append(len(limits))
        return 0
    parser = cli.build_parser
    monkeypatch.setattr(cli, "build_parser", lambda: _with_func(parser(), fake))
    monkeypatch.delenv("MODALAB_BLAS_THREADS", raising=False)
    assert cli.main(["info", str(tmp_path / "x.uff")]) == 0
    monkeypatch.setenv("MODALAB_BLAS_THREADS", "3")
    assert cli.main(["info", str(tmp_path / "x.uff")]) == 0
    assert limits == [1, 3] and seen == [1, 2]          # the limit is in force while the command runs
    monkeypatch.setenv("MODALAB_BLAS_THREADS", "many")
    assert cli.main(["info", str(tmp_path / "x.uff")]) == 2


def _with_func(parser, func):
    orig = parser.parse_args

    def parse(args=None):
        a = orig(args)
        a.func = func
        return a
    parser.parse_args = parse
    return parser


def test_stage_progress_is_a_bar_on_a_terminal_and_lines_otherwise():
    import io

    from rich.console import Console

    from modalab.app._cli_run import _StageProgress

    def feed(console):
        p = _StageProgress(console=console)
        p("frf", "skip", "up to date")
        p("identify", "start", "")
        p("identify", "info", "order 12 of 40")
        p("identify", "done", "3.1 s")
        p.close()

    plain = io.StringIO()
    feed(Console(file=plain, force_terminal=False, width=100))
    assert plain.getvalue().splitlines() == ["[2/7] frf       up to date (skipped)", "[3/7] identify  done in 3.1 s"]
    tty = io.StringIO()
    feed(Console(file=tty, force_terminal=True, width=100))
    text = tty.getvalue()
    assert "stages" in text and "━" in text and "2/7" in text      # the live bar over the stages
    assert "identify  done in 3.1 s" in text


def test_info_into_a_pipe_already_closed_exits_quietly_like_a_unix_tool(hits):
    """``modalab info x.uff | head -3`` when head has gone: no message, no traceback, exit 141 (128 + SIGPIPE),
    as ``cat``/``grep`` killed by SIGPIPE report to the shell (was: exit 2)."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    env = dict(os.environ, PYTHONPATH=str(root) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    r, w = os.pipe()
    os.close(r)                                        # the reader is gone before the first line is written
    try:
        p = subprocess.run([sys.executable, "-c", "import sys; from modalab.app.cli import main; "
                            "sys.exit(main(sys.argv[1:]))", "info", str(hits)], stdout=w,
                           stderr=subprocess.PIPE, env=env, timeout=120)
    finally:
        os.close(w)
    assert p.stderr.decode() == ""
    assert p.returncode == 141
