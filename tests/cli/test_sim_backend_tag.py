"""Data made by ``modalab sim`` say they are simulated (README: the backend is recorded in every hit's and FRF's
UFF ID lines): the backend entry is written before the long ones (the input ranges) that used to push it out of
the 80-character ID line, so ``frf`` and the report of commands run one by one see it (found by a fresh user:
the ``sim`` route lost the tag, the ``acquire --backend sim`` route kept it)."""
from __future__ import annotations

from modalab.app.cli import main
from modalab.core import uff
from modalab.core.dof import Dof
from modalab.core.records import TimeRecord


def test_sim_hits_and_their_frfs_carry_the_backend(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["sim", "-o", "hits.uff", "--no-plot"]) == 0
    recs = uff.read_records("hits.uff")
    assert recs and all((r.metadata or {}).get("backend") == "sim" for r in recs)
    assert main(["frf", "hits.uff", "-o", "frf.uff", "--exp-end", "0.01", "--no-plot"]) == 0
    assert "simulated (backend sim)" in capsys.readouterr().out
    assert uff.read_frf("frf.uff").metadata.get("backend") == "sim"


def test_the_point_and_backend_fit_the_id_line_before_long_entries(tmp_path):
    import numpy as np

    rec = TimeRecord(data=np.zeros((2, 64)), sample_rate_hz=1024.0, dofs=[Dof(1, 3), Dof(2, 3)],
                     roles=["force", "response"], units=["N", "m/s^2"], sensitivity=[1.0, 1.0], hit_id=1,
                     metadata={"range_v": [10.0] * 8, "aa_filter": "delta-sigma", "point": "1+Z", "backend": "nidaqmx"})
    uff.write_records(tmp_path / "h.uff", [rec])
    back = uff.read_records(tmp_path / "h.uff")[0].metadata
    assert back["point"] == "1+Z" and back["backend"] == "nidaqmx", back


def test_frf_given_frfs_says_they_are_frfs_already(tmp_path, monkeypatch, capsys):
    """A user mistake a fresh user made: ``modalab frf`` on a file of FRFs.  One line, exit 2, no output file,
    and it says what the file holds and which command takes it."""
    monkeypatch.chdir(tmp_path)
    assert main(["sim", "-o", "hits.uff", "--no-plot"]) == 0
    assert main(["frf", "hits.uff", "-o", "frf.uff", "--no-plot"]) == 0
    capsys.readouterr()
    assert main(["frf", "frf.uff", "-o", "again.uff", "--no-plot"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "frf.uff" in err and "FRFs already" in err and "identify" in err, err
    assert not (tmp_path / "again.uff").exists()
