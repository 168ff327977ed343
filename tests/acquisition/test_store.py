"""The crash-safe hit store: durable, exactly once, partial writes detected."""
import json

import numpy as np
import pytest

from acquisition.store import HitStore
from modalab.errors import StoreError
from modalab.records import TimeRecord


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
