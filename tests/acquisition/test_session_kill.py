"""Kill -9 an acquisition at random points, resume, and show that no accepted hit is lost or duplicated.

``python -m modalab.app.cli acquire PLAN --backend sim --auto -o DIR`` runs with a real-time simulated
lab (``[sim] realtime = true``, a small ``hit_interval_s``); the test SIGKILLs it at random moments
(chosen as a random number of journal lines plus a random delay), then tears the journal's last
line as a power loss would, and resumes with ``--resume`` until the session completes.  The simulator
draws every hit from (seed, point, hit), so the killed-and-resumed session's FRFs equal, to the last bit,
those of the same plan acquired without interruption.
"""
import os
import random
import signal
import subprocess
import sys
import time

import numpy as np

from _acq_session_util import ROOT, accepted_hits, journal, small_plan
from modalab.core import uff
from modalab.app.stages import AcquireOptions, acquire


def _start(plan, out, resume):
    cmd = [sys.executable, "-m", "modalab.app.cli", "acquire", str(plan), "--backend", "sim", "--auto", "--quiet",
           "-o", str(out)] + (["--resume"] if resume else [])
    env = {**os.environ, "MPLBACKEND": "Agg"}
    env.pop("DISPLAY", None)
    return subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _lines(out):
    p = out / "journal.jsonl"
    return p.read_bytes().count(b"\n") if p.exists() else 0


def test_sigkill_at_random_points_then_resume_loses_nothing(tmp_path):
    rng = random.Random(20261122)
    plan = small_plan(tmp_path, points=("1+Z", "5+Z", "14+Z", "19+Z"), record_s=0.25,
                      sim={"realtime": True, "hit_interval_s": 0.05})
    out = tmp_path / "session"
    seen: dict[int, tuple] = {}          # every hit accepted before some kill: id -> (point, sha256)
    kills = 0
    resume = False
    for attempt in range(4):
        proc = _start(plan, out, resume)
        target = _lines(out) + rng.randint(1, 3)
        t0 = time.monotonic()
        while proc.poll() is None and _lines(out) < target and time.monotonic() - t0 < 60:
            time.sleep(0.01)
        time.sleep(rng.uniform(0.0, 0.3))
        if proc.poll() is not None:          # it finished first
            break
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
        assert proc.returncode == -signal.SIGKILL
        kills += 1
        seen.update(accepted_hits(journal(out)))
        resume = True
    assert kills >= 3, "the acquisition finished before it could be killed three times; slow it down"
    assert seen, "no hit was accepted before any kill; the test would prove nothing"
    with open(out / "journal.jsonl", "ab") as fh:      # and a power loss tears the journal's last line
        fh.write(b'{"event": "hit", "hit": 999, "point": 3, "sta')
    proc = _start(plan, out, True)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 0, stderr
    assert "session complete" in stdout and "Traceback" not in stderr
    assert "on resume: torn last journal line (partial write) discarded" in stdout
    assert "on resume: recovered " in stdout and " points complete, " in stdout
    final = accepted_hits(journal(out))
    # none accepted before a kill is lost (same file content), each point has its N hits
    assert all(final.get(h) == v for h, v in seen.items())
    assert sorted(p for p, _ in final.values()) == [0, 0, 1, 1, 2, 2, 3, 3]
    assert 999 not in final
    # every accepted hit is in the exported UFF exactly once
    ids = [r.hit_id for r in uff.read_records(out / "session.uff")]
    assert sorted(ids) == sorted(final) and len(ids) == len(set(ids))
    # nothing stray is left in the hit folder: only journalled files
    files = {p.name for p in (out / "hits").iterdir()}
    named = {ev["file"] for ev in journal(out) if ev["event"] == "hit" and ev.get("file")}
    assert files == named
    # and the FRFs equal those of an uninterrupted session of the same plan (issue 14 #14)
    r = acquire(plan, tmp_path / "uninterrupted", AcquireOptions(auto=True))
    summary, ref = r.result.summary, r.result.uff
    assert summary.complete
    a, b = uff.read_frf(out / "session.uff"), uff.read_frf(ref)
    assert [str(d) for d in a.references] == [str(d) for d in b.references]
    np.testing.assert_array_equal(a.H, b.H)
    np.testing.assert_array_equal(a.coherence, b.coherence)
