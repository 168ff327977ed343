"""Deck files that are empty, not text or cut short name the file and line and say they look truncated."""
import logging
import warnings

import pytest

from modalab.core.errors import BulkDataError
from updating.fe.bulk import read_bdf

DECK = ("GRID    1               0.      0.      0.\n"
        "GRID    2               1.      0.      0.\n"
        "CROD    1       1       1       2\n"
        "PROD    1       1       1.-4\n"
        "MAT1    1       7.+10           .3      2700.\n"
        "ENDDATA\n")


def _file(tmp_path, text, name="m.bdf"):
    p = tmp_path / name
    p.write_bytes(text if isinstance(text, bytes) else text.encode())
    return p


def test_complete_deck_reads(tmp_path):
    assert sorted(read_bdf(_file(tmp_path, DECK), whole_model=True).grids) == [1, 2]


@pytest.mark.parametrize("text,line,needle", [
    ("", 1, "empty"),
    ("$ only a comment\n", 1, "empty"),
    (DECK[:DECK.index("CROD") + 12], 3, "looks truncated"),          # cut inside line 3
    (DECK[:DECK.index("CROD")], 2, "looks truncated"),               # cut at a line end: grids only
    (b"GRID\x00\x01\x02binary", 1, "not text"),
])
def test_broken_decks_name_file_line_and_truncation(tmp_path, text, line, needle):
    p = _file(tmp_path, text)
    with pytest.raises(BulkDataError) as ei:
        read_bdf(p, whole_model=True)
    e = ei.value
    assert e.path == str(p) and e.line == line and needle in str(e), str(e)


def test_cut_deck_with_a_dangling_reference_says_truncated(tmp_path):
    cut = DECK[:DECK.index("MAT1")]                                  # PROD refers to a MAT1 that was cut off
    with pytest.raises(BulkDataError, match="no ENDDATA.*cut short"):
        read_bdf(_file(tmp_path, cut))


def test_unknown_cards_listed_once_with_lines(tmp_path, caplog):
    deck = DECK.replace("ENDDATA", "FORCE   1       2       0       1.      0.      0.      1.\n"
                                   "CQUAD8  9       1       1       2\nFORCE   2       2\nENDDATA")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with caplog.at_level(logging.WARNING):
            read_bdf(_file(tmp_path, deck))
    msgs = [r.getMessage() for r in caplog.records if "not modelled" in r.getMessage()]
    assert len(msgs) == 1
    assert "m.bdf" in msgs[0] and "FORCE (2: lines 6, 8)" in msgs[0]      # CQUAD8: build_model refuses it
    assert all(r.pathname.endswith("reader.py") for r in caplog.records if "not modelled" in r.getMessage())


def test_a_deck_cut_at_a_line_break_after_its_elements_begin_warns(tmp_path, caplog):
    """Cut after the first CROD of two: the deck reads (a partial deck is a valid one), and a warning names the
    file, the grid left without an element and the last line; a complete deck, or one with ENDDATA, is quiet."""
    full = DECK.replace("CROD    1       1       1       2\n", "CROD    1       1       1       2\n"
                        "CROD    2       1       2       3\nGRID    3               2.      0.      0.\n")
    cut = full.split("CROD    2")[0].replace("GRID    2", "GRID    3               2.      0.      0.\nGRID    2")
    cut = cut + "PROD    1       1       1.-4\nMAT1    1       7.+10           .3      2700.\n"
    with caplog.at_level(logging.WARNING):
        read_bdf(_file(tmp_path, cut, "cut.bdf"))
    msgs = [r.getMessage() for r in caplog.records if "no ENDDATA" in r.getMessage()]
    assert len(msgs) == 1 and "cut.bdf" in msgs[0] and "(3)" in msgs[0] and "after line 6" in msgs[0], msgs
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        read_bdf(_file(tmp_path, full, "full.bdf"))
        read_bdf(_file(tmp_path, cut + "ENDDATA\n", "ended.bdf"))
    assert not [r for r in caplog.records if "no ENDDATA" in r.getMessage()]
