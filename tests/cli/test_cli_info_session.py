"""``modalab info`` on an acquisition session: its folder, its session.json or its session.uff.

A session's export holds raw hits and FRFs; their DOFs are shown once, in one table (where the hammer hit, where a
response channel measured, and what the DOF is in the FRFs), not as two 'responses' lines meaning different things.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from modalab.app.cli import main

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "acquisition"))
from _acq_session_util import small_plan  # noqa: E402


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("info_session")
    plan = small_plan(tmp, points=("1+Z", "14+Z", "19+Z"), averages=2)
    assert main(["acquire", str(plan), "--auto", "--quiet", "-o", str(tmp / "s")]) == 0
    return tmp / "s"


def _lines(capsys, args):
    capsys.readouterr()
    assert main(["info", *args]) == 0
    return capsys.readouterr().out.splitlines()


def test_each_dof_of_a_session_export_is_listed_once_with_its_roles(session, capsys):
    out = _lines(capsys, [str(session / "session.uff")])
    keys = [ln.split()[0] for ln in out if ln and not ln.startswith(" ")]
    assert len(keys) == len(set(keys)), out                    # no key twice (was: two 'responses' lines)
    assert "responses" not in keys and "references" not in keys and "hammer points" not in keys, out
    rows = {ln.split()[0]: ln.split()[1:] for ln in out if ln.startswith(" ") and ln.split()[0][0].isdigit()}
    # fixed accelerometers 19+Z, 12+Z, 1+Z; hammer at 1+Z, 14+Z, 19+Z; FRFs reordered by reciprocity
    assert set(rows) == {"1+Z", "12+Z", "14+Z", "19+Z"}, out
    assert rows["19+Z"] == ["2", "yes", "response,", "reference"]
    assert rows["1+Z"] == ["2", "yes", "response,", "reference"]
    assert rows["14+Z"] == ["2", "-", "response"]
    assert rows["12+Z"] == ["-", "yes", "reference"]
    assert any("ordered by reciprocity" in ln for ln in out), out


def test_info_takes_the_session_folder_or_its_session_json(session, capsys):
    by_file = _lines(capsys, [str(session / "session.uff")])
    for arg in (session, session / "session.json"):
        out = _lines(capsys, [str(arg)])
        assert out[0].split()[0] == "session" and "complete, 3 of 3 points done, backend sim" in out[0], out
        assert out[1:] == by_file
    capsys.readouterr()
    assert main(["info", str(session), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["path"] == str(session / "session.uff") and "complete" in d["session"]


def test_a_session_not_finished_says_how_to_finish_it(session, tmp_path, capsys):
    import shutil

    s = tmp_path / "s"
    shutil.copytree(session, s)
    (s / "session.uff").unlink()
    summ = json.loads((s / "summary.json").read_text())
    summ.update(complete=False, stopped="the operator quit")
    summ["points"][-1]["done"] = False
    (s / "summary.json").write_text(json.dumps(summ))
    capsys.readouterr()
    assert main(["info", str(s)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert "2 of 3 points done" in err and "no session.uff" in err and f"--resume -o {s}" in err, err


def test_a_folder_that_is_not_a_session_is_still_refused(tmp_path, capsys):
    assert main(["info", str(tmp_path)]) == 2
    assert "cannot read the file" in capsys.readouterr().err
