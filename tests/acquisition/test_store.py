"""The crash-safe hit store: durable, exactly once, partial writes detected."""
import json

import numpy as np
import pytest

from acquisition.store import HitStore
from modalab.core.errors import StoreError
from modalab.core.records import TimeRecord


def rec(seed=0):
    rng = np.random.default_rng(seed)
    return TimeRecord(sample_rate_hz=1000.0, data=rng.normal(size=(2, 64)), dofs=["1+Z", "2+Z"],
                      roles=["force", "response"], trigger_index=4, overload=[False, True],
                      metadata={"point": "1+Z"})


def test_add_and_reload_exact(tmp_path):
    s = HitStore(tmp_path, plan={"a": 1})
    r = rec()
    h = s.add(r, point=0, status="accepted")
    s2 = HitStore(tmp_path, resume=True)
    back = s2.load(h)
    np.testing.assert_array_equal(back.data, r.data)
    assert [str(d) for d in back.dofs] == ["1+Z", "2+Z"] and back.trigger_index == 4
    assert list(back.overload) == [False, True] and back.metadata == {"point": "1+Z"}
    assert s2.points()[0].accepted == [h]
    assert s2.next_hit_id == h + 1


def test_refuses_to_overwrite_or_resume_nothing(tmp_path):
    HitStore(tmp_path / "a")
    with pytest.raises(StoreError, match="--resume"):
        HitStore(tmp_path / "a")
    with pytest.raises(StoreError, match="nothing to resume"):
        HitStore(tmp_path / "b", resume=True)


def test_torn_journal_line_is_cut_and_hit_ids_not_reused(tmp_path):
    s = HitStore(tmp_path)
    s.add(rec(1), point=0, status="accepted")
    s.add(rec(2), point=0, status="accepted")
    with open(tmp_path / "journal.jsonl", "ab") as fh:
        fh.write(b'{"event": "hit", "hit": 3, "po')          # crash mid-append
    s2 = HitStore(tmp_path, resume=True)
    assert any("torn" in m for m in s2.discarded)
    assert s2.points()[0].accepted == [1, 2]
    h = s2.add(rec(3), point=0, status="accepted")
    assert h == 3
    s3 = HitStore(tmp_path, resume=True)
    assert s3.points()[0].accepted == [1, 2, 3]


def test_stray_file_without_journal_is_removed(tmp_path):
    s = HitStore(tmp_path)
    s.add(rec(), point=0, status="accepted")
    (tmp_path / "hits" / "hit_000099.npz").write_bytes(b"partial")
    (tmp_path / "hits" / "hit_000100.npz.tmp").write_bytes(b"partial")
    s2 = HitStore(tmp_path, resume=True)
    assert sorted(p.name for p in (tmp_path / "hits").iterdir()) == ["hit_000001.npz"]
    assert len([m for m in s2.discarded if "stray" in m]) == 2


def test_corrupt_hit_file_is_detected_not_used(tmp_path):
    s = HitStore(tmp_path)
    s.add(rec(), point=0, status="accepted")
    s.add(rec(5), point=1, status="accepted")
    p = tmp_path / "hits" / "hit_000001.npz"
    b = bytearray(p.read_bytes()); b[100] ^= 0xFF; p.write_bytes(bytes(b))
    s2 = HitStore(tmp_path, resume=True)
    assert any("corrupt" in m for m in s2.discarded)
    st = s2.points()
    assert st[0].accepted == [] and st[1].accepted == [2]
    assert s2.next_hit_id == 3  # id 1 is never reused even though it was discarded


def test_selection_reset_and_skip_replay(tmp_path):
    s = HitStore(tmp_path)
    a = [s.add(rec(i), point=0, status="candidate") for i in range(3)]
    s.add(rec(9), point=0, status="rejected", reasons=["double hit"])
    s.select(0, [a[0], a[2]])
    s.point_done(0)
    s.skip_point(1, "no trigger")
    st = s.points()
    assert st[0].accepted == [a[0], a[2]] and st[0].done
    assert (a[1], ["lower coherence than the kept hits"]) in st[0].rejected
    assert (4, ["double hit"]) in st[0].rejected
    assert st[1].skipped == "no trigger"
    s.reset_point(0)
    st = s.points()
    assert st[0].accepted == [] and not st[0].done
    assert not (tmp_path / "hits" / "hit_000004.npz").exists()   # rejected hits keep no raw data
    lines = (tmp_path / "journal.jsonl").read_text().splitlines()
    assert all(json.loads(x)["event"] for x in lines)


def _flip(path, at=100):
    b = bytearray(path.read_bytes())
    b[at] ^= 0xFF
    path.write_bytes(bytes(b))


def test_a_damaged_accepted_hit_is_journalled_as_lost_and_reopens_its_point(tmp_path):
    s = HitStore(tmp_path)
    for i in range(2):
        s.add(rec(i), point=0, status="accepted")
    s.point_done(0)
    assert s.points()[0].done
    _flip(tmp_path / "hits" / "hit_000001.npz")
    s2 = HitStore(tmp_path, resume=True)
    msg = [m for m in s2.discarded if "hit 1" in m]
    assert len(msg) == 1 and msg[0].startswith("LOST hit 1 (accepted, point index 0)") and "corrupt" in msg[0]
    assert not any("stray" in m for m in s2.discarded)            # it was journalled: not a stray file
    st = s2.points()[0]
    assert st.accepted == [2] and st.lost == [1] and st.reopened and not st.done
    assert any(h == 1 and r[0].startswith("lost: raw file hit_000001.npz corrupt") for h, r in st.rejected)
    assert (tmp_path / "corrupt" / "hit_000001.npz").exists()      # kept aside as evidence
    assert not (tmp_path / "hits" / "hit_000001.npz").exists()
    # reopening again reports nothing new and journals the loss once
    s3 = HitStore(tmp_path, resume=True)
    assert s3.discarded == [] and s3.points()[0].lost == [1]
    assert sum(ev["event"] == "hit_lost" for ev in s3.events) == 1
    # measured again: done once more with a new hit, the lost one never comes back
    s3.add(rec(7), point=0, status="accepted")
    s3.point_done(0)
    st = HitStore(tmp_path, resume=True).points()[0]
    assert st.accepted == [2, 3] and st.done and not st.reopened


def test_a_missing_candidate_file_is_lost_without_touching_done_points(tmp_path):
    s = HitStore(tmp_path)
    a = s.add(rec(1), point=0, status="candidate")
    s.add(rec(2), point=0, status="candidate")
    (tmp_path / "hits" / f"hit_{a:06d}.npz").unlink()
    s2 = HitStore(tmp_path, resume=True)
    assert any("missing" in m and f"hit {a}" in m for m in s2.discarded)
    assert s2.points()[0].candidates == [2] and not s2.points()[0].reopened


@pytest.mark.parametrize("damage", ["missing", "garbage", "empty"])
def test_session_json_is_rebuilt_from_the_journal(tmp_path, damage):
    s = HitStore(tmp_path, plan={"acquisition": {"averages": 3}})
    s.add(rec(), point=0, status="accepted")
    p = tmp_path / "session.json"
    if damage == "missing":
        p.unlink()
    else:
        p.write_bytes(b"\x00\xffnot json" if damage == "garbage" else b"")
    s2 = HitStore(tmp_path, resume=True)
    assert s2.plan == {"acquisition": {"averages": 3}}
    assert any(m.startswith("session.json was") and "rebuilt from the journal" in m for m in s2.discarded)
    assert json.loads(p.read_text())["plan"] == {"acquisition": {"averages": 3}}
    assert s2.points()[0].accepted == [1]


def test_a_session_json_lost_without_a_journal_header_is_refused(tmp_path):
    # a journal from before the header line: the plan cannot be checked, so no resume
    s = HitStore(tmp_path, plan={"a": 1})
    s.add(rec(), point=0, status="accepted")
    lines = (tmp_path / "journal.jsonl").read_bytes().splitlines(keepends=True)
    (tmp_path / "journal.jsonl").write_bytes(b"".join(lines[1:]))
    (tmp_path / "session.json").unlink()
    with pytest.raises(StoreError, match="session.json' is missing and the journal does not hold the session's plan"):
        HitStore(tmp_path, resume=True)
    assert (tmp_path / "hits" / "hit_000001.npz").exists()          # nothing deleted


def test_a_damaged_line_before_the_last_refuses_and_truncates_nothing(tmp_path):
    s = HitStore(tmp_path)
    for i in range(3):
        s.add(rec(i), point=0, status="accepted")
    j = tmp_path / "journal.jsonl"
    lines = j.read_bytes().splitlines(keepends=True)
    lines[2] = b'{"event": "hit", garbage\n'
    j.write_bytes(b"".join(lines))
    before = j.read_bytes()
    with pytest.raises(StoreError, match=r"line 3 is damaged and is not the last line"):
        HitStore(tmp_path, resume=True)
    assert j.read_bytes() == before and len(list((tmp_path / "hits").iterdir())) == 3


def test_output_path_that_is_a_file_is_refused(tmp_path):
    f = tmp_path / "f"
    f.write_text("keep")
    with pytest.raises(StoreError, match="is a file"):
        HitStore(f)
    with pytest.raises(StoreError, match="cannot create the session folder"):
        HitStore(f / "sub")
    assert f.read_text() == "keep"
