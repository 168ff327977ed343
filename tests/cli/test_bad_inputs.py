"""Every command fed a corpus of bad inputs: exit code 2, one line naming the file, no traceback, nothing left behind.

The corpus is made from small valid files of each kind (raw hits, FRFs, modes UFF and JSON, a bulk-data deck,
a project file): truncated at 10, 50 and 99 % and in the middle of a line, random bytes, empty, a file of the
wrong type and a folder.  Commands run in-process through ``main([...])``; the broken-pipe case needs a real
pipe and runs ``python -m modalab.app.cli`` in a subprocess.
"""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import tomllib

import numpy as np
import pytest
import tomli_w

from modalab.app.cli import main
from modalab.core.modes import ModeSet

ROOT = Path(__file__).resolve().parents[2]
VARIANTS = ("cut10", "cut50", "cut99", "midline", "random", "empty", "wrongtype", "folder")


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    """Small valid inputs of every kind, in their own folder."""
    d = tmp_path_factory.mktemp("good")
    hits = d / "hits.uff"
    assert main(["sim", "-o", str(hits), "--points", "1+Z", "4+Z", "--references", "19+Z", "--hits", "1",
                 "--samples", "512", "--no-plot"]) == 0
    frf = d / "frf.uff"
    assert main(["frf", str(hits), "-o", str(frf), "--no-plot"]) == 0
    ms = ModeSet(freq_hz=[19.0, 71.0], damping=[0.01, 0.02], shapes=[[1.0, 0.5], [0.3, -1.0]],
                 dofs=["1+Z", "4+Z"])
    modes = d / "modes.uff"
    ms.to_uff(modes)
    modes_json = d / "modes.json"
    ms.to_json(modes_json)
    model = d / "model.bdf"
    shutil.copy(ROOT / "examples" / "concealed" / "bar_control" / "nominal.bdf", model)
    proj = d / "project.toml"
    shutil.copy(ROOT / "examples" / "demo_project" / "project_quick.toml", proj)
    # one line, no final newline: every cut of it is broken TOML (a cut at a line end could be valid)
    params = d / "params.toml"
    params.write_text('parameter = [{name = "E_seg1", field = "E", properties = ["seg1"], lower = 0.5, upper = 2.0}]')
    # a plan without comments whose last line is the point list, no final newline: every cut breaks it
    plan = tomllib.loads((ROOT / "examples" / "plans" / "demo_roving_hammer.toml").read_text())
    plan = {k: v for k, v in plan.items() if k not in ("roving", "hammer")} | {"roving": plan["roving"]}
    (d / "plan.toml").write_text(tomli_w.dumps(plan).rstrip("\n"))
    return {"hits": hits, "frf": frf, "modes": modes, "modes_json": modes_json, "model": model, "project": proj,
            "params": params, "plan": d / "plan.toml"}


def _bad(src: Path, variant: str, where: Path, wrong: Path) -> Path:
    """A damaged copy of ``src`` in ``where`` (same suffix, so only the content is wrong)."""
    out = where / f"{variant}_{src.name}"
    raw = src.read_bytes()
    if variant.startswith("cut"):
        out.write_bytes(raw[:len(raw) * int(variant[3:]) // 100])
    elif variant == "midline":
        lines = raw.split(b"\n")
        k = len(lines) // 2
        cut = sum(len(x) + 1 for x in lines[:k]) + max(len(lines[k]) // 2, 1)
        out.write_bytes(raw[:cut])
    elif variant == "random":
        out.write_bytes(np.random.default_rng(7).integers(0, 256, 2000, dtype=np.uint8).tobytes())
    elif variant == "empty":
        out.write_bytes(b"")
    elif variant == "wrongtype":
        out.write_bytes(wrong.read_bytes())
    elif variant == "folder":
        out.mkdir()
    return out


def _wrong_for(command, kind, good):
    if command == "info":                    # any UFF is right for info: a bulk-data deck is not
        return good["model"]
    return {"hits": good["model"], "frf": good["hits"], "modes": good["frf"], "modes_json": good["model"],
            "model": good["frf"], "project": good["hits"], "params": good["model"], "plan": good["project"]}[kind]


# (command, kind of the damaged input, argv builder: bad path, good files, output folder -> argv)
CASES = [
    ("info", "frf", lambda b, g, o: ["info", str(b)]),
    ("info", "hits", lambda b, g, o: ["info", str(b)]),
    ("info", "modes", lambda b, g, o: ["info", str(b)]),
    ("frf", "hits", lambda b, g, o: ["frf", str(b), "-o", str(o / "out.uff")]),
    ("identify", "frf", lambda b, g, o: ["identify", str(b), "-o", str(o / "m.uff"), "--json", str(o / "m.json")]),
    ("correlate", "model", lambda b, g, o: ["correlate", str(b), str(g["modes"]), "--json", str(o / "c.json")]),
    ("correlate", "modes", lambda b, g, o: ["correlate", str(g["model"]), str(b), "--json", str(o / "c.json")]),
    ("correlate", "modes_json", lambda b, g, o: ["correlate", str(g["model"]), str(b)]),
    ("update", "model", lambda b, g, o: ["update", str(b), "--modes", str(g["modes"]), "-o", str(o / "upd")]),
    ("update", "modes", lambda b, g, o: ["update", str(g["model"]), "--modes", str(b), "-o", str(o / "upd")]),
    ("diagnose", "model", lambda b, g, o: ["diagnose", str(b), str(g["frf"]), "--json", str(o / "d.json")]),
    ("diagnose", "frf", lambda b, g, o: ["diagnose", str(g["model"]), str(b), "--json", str(o / "d.json")]),
    ("run", "project", lambda b, g, o: ["run", str(b), "-o", str(o / "run")]),
    # issue 14 audit: the inputs the corpus did not reach
    ("sim", "model", lambda b, g, o: ["sim", "--structure", str(b), "-o", str(o / "h.uff"), "--points", "1+Z",
                                      "--hits", "1", "--samples", "256", "--no-plot"]),
    ("acquire", "plan", lambda b, g, o: ["acquire", str(b), "--backend", "sim", "--auto", "--quiet",
                                         "-o", str(o / "s")]),
    ("update", "params", lambda b, g, o: ["update", str(g["model"]), "--modes", str(g["modes"]), "--same-ids",
                                          "--params", str(b), "-o", str(o / "upd")]),
    ("update", "modes_json", lambda b, g, o: ["update", str(g["model"]), "--modes", str(b), "-o", str(o / "upd")]),
    ("diagnose", "params", lambda b, g, o: ["diagnose", str(g["model"]), str(g["frf"]), "--params", str(b),
                                            "--report", str(o / "diag")]),
    ("diagnose", "modes", lambda b, g, o: ["diagnose", str(g["model"]), "--modes", str(b), "--json",
                                           str(o / "d.json")]),
    ("diagnose", "modes_json", lambda b, g, o: ["diagnose", str(g["model"]), "--modes", str(b), "--report",
                                                str(o / "diag")]),
    ("identify", "frf-campaign", lambda b, g, o: ["identify", str(g["frf"]), str(b), "-o", str(o / "camp")]),
    ("diagnose", "frf-campaign", lambda b, g, o: ["diagnose", str(g["model"]), str(g["frf"]), str(b),
                                                  "--report", str(o / "camp")]),
]


def _tree(d: Path):
    return sorted(str(p.relative_to(d)) for p in d.rglob("*"))


@pytest.mark.parametrize("variant", VARIANTS)
@pytest.mark.parametrize("command,kind,argv", CASES, ids=[f"{c}-{k}" for c, k, _ in CASES])
def test_bad_input_is_one_line_exit_2_nothing_left(command, kind, argv, variant, good, tmp_path, capsys):
    bad_dir = tmp_path / "in"
    bad_dir.mkdir()
    base = kind.split("-")[0]                   # 'frf-campaign': a damaged FRF file among good ones
    bad = _bad(good[base], variant, bad_dir, _wrong_for(command, base, good))
    out = tmp_path / "out"
    out.mkdir()
    before_in, before_good = _tree(bad_dir), _tree(good["hits"].parent)
    rc = main(argv(bad, good, out))
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2, (variant, err)
    lines = [ln for ln in err if ln.startswith(f"modalab {command}: error: ")]
    assert len(lines) == 1 and "Traceback" not in "\n".join(err), err
    assert bad.name in lines[0], lines[0]
    if variant == "folder":
        assert "folder" in lines[0] or "directory" in lines[0].lower(), lines[0]
    assert _tree(out) == [], f"left behind: {_tree(out)}"
    assert _tree(bad_dir) == before_in and _tree(good["hits"].parent) == before_good


def test_modes_asked_of_raw_hits_say_which_commands_make_them(good, capsys):
    """correlate given the raw hits where modes belong: the error says what the file holds and what to run."""
    assert main(["correlate", str(good["model"]), str(good["hits"])]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and good["hits"].name in err[0], err
    assert "time response (raw hits)" in err[0] and "'modalab frf'" in err[0] and "'modalab identify'" in err[0], err


@pytest.mark.parametrize("argv,needle", [
    (lambda g, o: ["frf", str(g["hits"]), "-o", str(o)], "is a folder"),
    (lambda g, o: ["identify", str(g["frf"]), "-o", str(o / "m.uff"), "--json", str(o)], "is a folder"),
    (lambda g, o: ["correlate", str(g["model"]), str(g["modes"]), "--json", str(o)], "is a folder"),
    (lambda g, o: ["frf", str(g["hits"]), "-o", str(g["hits"])], "is also an input"),
    (lambda g, o: ["frf", str(g["hits"]), "-o", str(g["hits"]), "--force"], "is also an input"),
    (lambda g, o: ["identify", str(g["frf"]), "-o", str(g["frf"]), "--force"], "is also an input"),
    (lambda g, o: ["frf", str(g["hits"]), "-o", str(g["frf"])], "pass --force"),
    (lambda g, o: ["update", str(g["model"]), "--modes", str(g["modes"]), "-o", str(g["model"])], "is a file"),
    (lambda g, o: ["frf", str(g["hits"]), "-o", str(g["frf"] / "x.uff")], "is a file, not a folder"),
])
def test_unsafe_outputs_are_refused_before_any_work(argv, needle, good, tmp_path, capsys):
    stamp = {p: (p.stat().st_size, p.stat().st_mtime_ns) for p in good["hits"].parent.iterdir()}
    rc = main(argv(good, tmp_path))
    err = capsys.readouterr().err.strip()
    assert rc == 2 and needle in err and "\n" not in err, err
    assert {p: (p.stat().st_size, p.stat().st_mtime_ns) for p in good["hits"].parent.iterdir()} == stamp
    assert _tree(tmp_path) == []


def test_force_replaces_an_output_atomically_with_the_umask(good, tmp_path, capsys):
    out = tmp_path / "frf.uff"
    out.write_bytes(b"old")
    old = os.umask(0o022)
    try:
        assert main(["frf", str(good["hits"]), "-o", str(out), "--no-plot", "--force"]) == 0
        assert out.stat().st_mode & 0o777 == 0o644
        os.umask(0o027)
        out2 = tmp_path / "sub" / "h.uff"
        assert main(["sim", "-o", str(out2), "--points", "1+Z", "--references", "19+Z", "--hits", "1",
                     "--samples", "256", "--no-plot"]) == 0
        assert out2.stat().st_mode & 0o777 == 0o640
    finally:
        os.umask(old)
    assert out.read_bytes()[:6] == b"    -1"
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["frf.uff", "h.uff", "sub"]   # no temporary left


def test_a_failed_write_leaves_the_old_output(good, tmp_path, monkeypatch):
    """An exception while writing: the temporary file is removed and the previous output is untouched."""
    from modalab.core import uff

    out = tmp_path / "frf.uff"
    out.write_bytes(b"previous")
    frf = uff.read_frf(good["frf"])

    def boom(*a, **k):
        raise RuntimeError("disk full")

    monkeypatch.setattr("modalab.core._uff_core.format_58", boom)
    monkeypatch.setattr("modalab.core._uff_frf.format_58", boom)      # the FRF writer's binding
    with pytest.raises(RuntimeError):
        uff.write_frf(out, frf)
    assert out.read_bytes() == b"previous" and [p.name for p in tmp_path.iterdir()] == ["frf.uff"]


def test_writers_never_replace_a_protected_input(good, tmp_path):
    from modalab.core import uff
    from modalab.core._output import protect
    from modalab.core.errors import OutputError

    p = tmp_path / "in.uff"
    shutil.copy(good["frf"], p)
    before = p.read_bytes()
    with protect([p]):
        with pytest.raises(OutputError, match="input"):
            uff.write_frf(p, uff.read_frf(good["frf"]))
        with pytest.raises(OutputError, match="input"):
            uff.write_units(p, append=True)
    assert p.read_bytes() == before
    uff.write_units(tmp_path / "u.uff")        # outside the block nothing is protected


def test_info_into_a_closed_pipe_is_quiet(good):
    """``modalab info x.uff | head -1``: no BrokenPipeError traceback."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    code = ("import sys; from modalab.app.cli import main; sys.exit(main(sys.argv[1:]))")
    p1 = subprocess.Popen([sys.executable, "-c", code, "info", str(good["hits"])], stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, env=env)
    p1.stdout.readline()
    p1.stdout.close()                                  # the reader goes away after one line
    err = p1.stderr.read().decode()
    p1.wait(timeout=60)
    assert "Traceback" not in err and "BrokenPipe" not in err, err
