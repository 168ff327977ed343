"""Acquisition sessions with injected faults: no trigger, device lost mid-record (reconnect, or a clean stop
and --resume), overload storms, double hits, a noisy channel and a dead accelerometer.

Every session's exported FRFs (read back from the UFF) are compared with the exact accelerance at
s = iω + β on the channels the fault leaves intact.
"""
import numpy as np
import pytest

from _acq_session_util import Recorder, accepted_hits, journal, rel_errors, small_plan
from acquisition.session import ScriptedPrompter
from acquisition.windows import beta_from_end_level
from modalab.core import uff
from modalab.app.stages import AcquireOptions, acquire

BETA = beta_from_end_level(0.01, 2048, 2048.0, 64)


def _exact_ok(exported, model, **select):
    frf = uff.read_frf(exported)
    if select:
        frf = frf.select(**select)
    err, good = rel_errors(frf, model, BETA)
    assert good.mean() > 0.9
    assert np.median(err) < 5e-3 and np.percentile(err, 95) < 3e-2
    return frf


def test_no_trigger_for_two_arms_then_hits(tmp_path):
    plan = small_plan(tmp_path, points=("14+Z",), sim={"faults": {"no_trigger_on": [1, 2]}})
    rec = Recorder()
    r = acquire(plan, tmp_path / "s", AcquireOptions(auto=True), observer=rec)
    sess, summary, exported = r.result.session, r.result.summary, r.result.uff
    no_hit = [m for m in rec.messages if "no hit within" in m]
    assert len(no_hit) == 4                               # two waits per arm, two arms without a trigger
    assert sess.backend.n_armed == 3 + 2                   # 3 hits + the 2 silent arms
    p = summary.points[0]
    assert summary.complete and (p.taken, p.accepted) == (3, 2) and not p.skipped
    _exact_ok(exported, sess.backend.model)


def test_trigger_never_comes_skips_the_point_in_auto_mode(tmp_path):
    plan = small_plan(tmp_path, points=("14+Z", "19+Z"),
                      sim={"faults": {"no_trigger_on": [1, 2, 3]}})   # 2 waits per arm
    r = acquire(plan, tmp_path / "s", AcquireOptions(auto=True))
    sess, summary, exported = r.result.session, r.result.summary, r.result.uff
    p0, p1 = summary.points
    assert p0.skipped == "no trigger in 6 waits" and p0.accepted == 0 and p0.taken == 0
    assert p1.accepted == 2 and summary.complete
    frf = _exact_ok(exported, sess.backend.model)
    assert [str(d) for d in frf.responses] == ["19+Z"]


def test_trigger_never_comes_operator_skips(tmp_path):
    plan = small_plan(tmp_path, points=("14+Z",), sim={"faults": {"no_trigger_probability": 1.0}})
    prompter = ScriptedPrompter("ws")
    r = acquire(plan, tmp_path / "s", prompter=prompter)
    summary, exported = r.result.summary, r.result.uff
    assert [q.startswith("No hit at 14+Z") for q in prompter.asked] == [True, True]
    assert summary.points[0].skipped == "skipped by the operator after no trigger"
    assert summary.complete and exported is None          # nothing accepted, nothing to export


def test_device_lost_mid_record_reconnects_and_completes(tmp_path):
    plan = small_plan(tmp_path, points=("1+Z", "19+Z"), sim={"faults": {"device_lost_on": [2, 5]}})
    rec = Recorder()
    r = acquire(plan, tmp_path / "s", AcquireOptions(auto=True), observer=rec)
    sess, summary, exported = r.result.session, r.result.summary, r.result.uff
    assert sess.reconnects == 2
    assert sum("the DAQ was lost" in m for m in rec.messages) == 2
    assert sum(m.startswith("reconnected") for m in rec.messages) == 2
    assert summary.complete and [p.taken for p in summary.points] == [3, 3]
    _exact_ok(exported, sess.backend.model)


def test_device_lost_without_reconnect_stops_cleanly_and_resumes(tmp_path):
    faulty = small_plan(tmp_path, points=("1+Z", "14+Z", "19+Z"), sim={"faults": {"device_lost_on": [5]}},
                        name="faulty.toml")
    out = tmp_path / "s"
    r = acquire(faulty, out, AcquireOptions(auto=True, max_reconnects=0))
    sess, summary, exported = r.result.session, r.result.summary, r.result.uff
    assert not summary.complete and exported is None
    assert "--resume" in summary.stopped and "lost" in summary.stopped
    assert sess.backend.state == "closed"
    before = accepted_hits(journal(out))
    cands_before = {ev["hit"] for ev in journal(out) if ev["event"] == "hit" and ev["status"] == "candidate"}
    assert sorted(p for p, _ in before.values()) == [0, 0]                 # point 0 done, point 1 started
    assert len(cands_before - set(before)) == 1 + 1                         # 1 unselected + 1 candidate at point 1
    clean = small_plan(tmp_path, points=("1+Z", "14+Z", "19+Z"), name="clean.toml")
    r = acquire(clean, out, AcquireOptions(auto=True, resume=True))
    sess, summary, exported = r.result.session, r.result.summary, r.result.uff
    assert summary.complete and [p.accepted for p in summary.points] == [2, 2, 2]
    after = accepted_hits(journal(out))
    assert all(after[h] == v for h, v in before.items())
    # the candidate taken at point 1 before the loss took part in the best-2-of-3 choice after resume
    sel = [ev for ev in journal(out) if ev["event"] == "select" and ev["point"] == 1][0]
    cands1 = [ev["hit"] for ev in journal(out) if ev["event"] == "hit" and ev["point"] == 1
              and ev["status"] == "candidate"]
    assert len(cands1) == 3 and set(sel["accepted"]) <= set(cands1) and min(cands1) in cands_before
    ids = [r.hit_id for r in uff.read_records(exported)]
    assert sorted(ids) == sorted(after) and len(set(ids)) == 6
    _exact_ok(exported, sess.backend.model)


def test_overload_storm_hits_are_rejected(tmp_path):
    plan = small_plan(tmp_path, points=("14+Z",), sim={"faults": {"overload_storm_on": [2, 3]}})
    rec = Recorder()
    r = acquire(plan, tmp_path / "s", AcquireOptions(auto=True), observer=rec)
    sess, summary, exported = r.result.session, r.result.summary, r.result.uff
    stormy = {h[1].hit_id for h in rec.hits if h[1].metadata["sim"]["overload_storm"]}
    assert len(stormy) == 2
    for _, hid, decision, reasons in rec.decisions:
        assert (decision == "rejected" and "overload" in reasons) == (hid in stormy)
    p = summary.points[0]
    assert (p.taken, p.accepted) == (5, 2) and p.rejected_reasons["overload"] == 2
    assert not set(accepted_hits(journal(tmp_path / "s"))) & stormy
    _exact_ok(exported, sess.backend.model)


def test_double_hits_are_rejected(tmp_path):
    plan = small_plan(tmp_path, points=("14+Z",), sim={"faults": {"double_hit_on": [1, 3]}})
    rec = Recorder()
    r = acquire(plan, tmp_path / "s", AcquireOptions(auto=True), observer=rec)
    sess, summary, exported = r.result.session, r.result.summary, r.result.uff
    doubles = {h[1].hit_id for h in rec.hits if h[1].metadata["sim"]["double_hit"]}
    assert len(doubles) == 2
    rejected = {hid for _, hid, d, r in rec.decisions if d == "rejected" and "double_hit" in r}
    assert rejected == doubles
    assert summary.points[0].rejected_reasons["double_hit"] == 2
    _exact_ok(exported, sess.backend.model)


def test_noisy_channel_shows_as_low_coherence(tmp_path):
    plan = small_plan(tmp_path, points=("14+Z", "19+Z"), sim={"noisy": {"acc_12Z": 0.05}})
    r = acquire(plan, tmp_path / "s", AcquireOptions(auto=True))
    sess, summary, exported = r.result.session, r.result.summary, r.result.uff
    for p in summary.points:
        assert p.channel_coherence["acc_12Z"] < 0.8
        assert p.channel_coherence["acc_19Z"] > 0.99 and p.channel_coherence["acc_1Z"] > 0.99
        assert p.warnings.get("low_coherence:acc_12Z") == 1
        assert "low_coherence:acc_19Z" not in p.warnings
    assert "low_coherence:acc_12Z" in summary.table()
    _exact_ok(exported, sess.backend.model, references=["19+Z", "1+Z"])


def test_dead_accelerometer_is_reported_and_the_others_are_exact(tmp_path):
    plan = small_plan(tmp_path, points=("14+Z", "19+Z"), sim={"dead": ["acc_1Z"]})
    rec = Recorder()
    r = acquire(plan, tmp_path / "s", AcquireOptions(auto=True), observer=rec)
    sess, summary, exported = r.result.session, r.result.summary, r.result.uff
    assert all("dead_channel:acc_1Z" in r for _, _, d, r in rec.decisions)
    assert not any("dead_channel:acc_19Z" in r or "dead_channel:acc_12Z" in r for _, _, d, r in rec.decisions)
    for p in summary.points:
        assert p.warnings["dead_channel:acc_1Z"] == 2 and "low_coherence:acc_1Z" in p.warnings
        assert p.accepted == 2
    _exact_ok(exported, sess.backend.model, references=["19+Z", "12+Z"])


@pytest.mark.parametrize("bad,match", [
    ({"dead": ["acc_9Z"]}, r"\[sim\] dead/noisy names channel 'acc_9Z'"),
    ({"typo_key": 1}, r"unknown key sim\.typo_key; valid keys: "),
    ({"hamer_tip": "soft"}, r"unknown key sim\.hamer_tip; did you mean sim\.hammer_tip\?"),
    ({"faults": {"no_such_fault": [1]}}, r"unknown key sim\.faults\.no_such_fault"),
    ({"faults": {"double_hit_onn": [1]}}, r"sim\.faults\.double_hit_onn; did you mean sim\.faults\.double_hit_on\?"),
    ({"hammer_tip": "rubber"}, r"sim\.hammer_tip = 'rubber'; expected one of hard, medium, soft"),
    ({"hammer_mass_kg": 0}, r"sim\.hammer_mass_kg = 0\.0 must be positive"),
    ({"seed": -3}, r"sim\.seed = -3 must be a whole number >= 0"),
])
def test_sim_section_errors_are_clear(tmp_path, bad, match):
    from modalab.core.errors import PlanError

    plan = small_plan(tmp_path, points=("14+Z",), sim=bad)
    with pytest.raises(PlanError, match=r"plan\.toml: .*" + match):
        acquire(plan, tmp_path / "s", AcquireOptions(auto=True))
