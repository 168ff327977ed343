"""Field-level parsing and formatting of Nastran bulk data (updating.fe.bulk.fields)."""
import math

import pytest
from hypothesis import given, settings, strategies as st

from modalab.core.errors import BulkDataError
from updating.fe.bulk.fields import (Line, card_lines, fits_exactly, format_real, group_cards, parse_int,
                                  parse_real)


def lines(text, path=None):
    return [Line(t, i + 1, path) for i, t in enumerate(text.splitlines())]


class TestParseReal:
    @pytest.mark.parametrize("text, value", [
        ("1.-3", 1e-3), (".5+2", 50.0), ("7.E3", 7000.0), ("-1.2D-3", -1.2e-3), ("1.0E+3", 1000.0),
        ("-.5", -0.5), ("+1.5", 1.5), ("1.5e-2", 0.015), ("3.", 3.0), ("1.+10", 1e10), ("-2.5-12", -2.5e-12),
        ("1E3", 1000.0), ("  .25  ", 0.25), ("1.D0", 1.0), ("0.", 0.0),
    ])
    def test_nastran_forms(self, text, value):
        assert parse_real(text) == pytest.approx(value, rel=1e-15)

    @pytest.mark.parametrize("text", ["5", "-12", "1.2.3", "abc", "1.e", "1-", "", "1. 5", "1.E999", "--1."])
    def test_not_reals(self, text):
        with pytest.raises(Exception):
            parse_real(text)

    def test_integers(self):
        assert parse_int(" 12 ") == 12 and parse_int("-3") == -3
        with pytest.raises(Exception):
            parse_int("1.")
        with pytest.raises(Exception):
            parse_int("99999999999")


class TestFormatReal:
    @pytest.mark.parametrize("x, text8", [(1e-3, ".001"), (7e10, "7.+10"), (2700.0, "2700."), (-0.0012, "-.0012"),
                                          (0.0, "0."), (123456.7, "123456.7"), (1e-20, "1.-20")])
    def test_short_forms(self, x, text8):
        assert format_real(x, 8) == text8

    @settings(max_examples=300, deadline=None)
    @given(st.floats(min_value=-1e99, max_value=1e99, allow_nan=False, allow_infinity=False)
           .filter(lambda v: v == 0 or abs(v) >= 1e-99))
    def test_round_trip_precision(self, x):
        # two-digit exponents: at least 3 significant digits in 8 columns, 10 in 16
        for width, rel in ((8, 5e-3), (16, 5e-10)):
            s = format_real(x, width)
            assert len(s) <= width
            y = parse_real(s)
            assert y == x or abs(y - x) <= rel * abs(x) + 1e-300
            if fits_exactly(x, width):
                assert y == x

    @settings(max_examples=200, deadline=None)
    @given(st.integers(-999, 999), st.integers(-9, 9))
    def test_short_decimals_exact_in_small_field(self, mant, exp):
        x = float(f"{mant}e{exp}")
        assert fits_exactly(x, 8)
        assert parse_real(format_real(x, 8)) == x


class TestGrouping:
    def test_small_large_free_same_card(self):
        small = "GRID    12      3       1.5     -2.     .25     4\n"
        large = ("GRID*                 12               3             1.5             -2.\n"
                 "*                   .25               4\n")
        free = "GRID,12,3,1.5,-2.,.25,4\n"
        free_large = "GRID*,12,3,1.5,-2.\n*,.25,4\n"
        got = [group_cards(lines(t))[0].fields[1:7] for t in (small, large, free, free_large)]
        for g in got:
            assert [f.strip() for f in g] == ["12", "3", "1.5", "-2.", ".25", "4"]

    def test_continuations_explicit_implicit(self):
        text = ("PBAR    1       2       .1      1.-3    2.-3    3.-3                    +PB1\n"
                "+PB1    1.      2.                                                      +PB2\n"
                "+PB2    .8      .9\n"
                "CBAR    1       1       1       2       0.      0.      1.\n"
                "        a\n")
        cards = group_cards(lines(text))
        assert [c.name for c in cards] == ["PBAR", "CBAR"]
        assert cards[0].raw(9) == "1." and cards[0].raw(17) == ".8" and cards[0].raw(18) == ".9"
        assert cards[1].raw(9) == "A" or cards[1].raw(9) == "a"

    def test_free_field_continuations(self):
        cards = group_cards(lines("TABDMP1,5,CRIT\n+,0.,.01,100.,.02,ENDT\nPARAM,G,.02\n,5.\n"))
        assert cards[0].raw(9) == "0." and cards[0].raw(13) == "ENDT"
        assert cards[1].name == "PARAM" and cards[1].raw(9) == "5."

    def test_comments_and_tabs(self):
        text = "$ name: wing\nGRID\t1\t\t0.\t1.\t2. $ trailing\n"
        c = group_cards(lines(text))[0]
        assert c.comment == ["$ name: wing"]
        assert [c.raw(i) for i in range(1, 6)] == ["1", "", "0.", "1.", "2."]

    def test_marker_mismatch(self):
        text = "PBAR    1       2       .1                                              +A\n+B      1.\n"
        with pytest.raises(BulkDataError, match=r"line 2.*PBAR.*does not match"):
            group_cards(lines(text))

    def test_missing_continuation(self):
        text = "PBAR    1       2       .1                                              +A\nGRID    1\n"
        with pytest.raises(BulkDataError, match=r"line 1.*card PBAR.*missing continuation"):
            group_cards(lines(text, "deck.bdf"))
        with pytest.raises(BulkDataError, match="missing continuation"):
            group_cards(lines("PBAR    1       2       .1                                              +A\n"))

    def test_orphan_continuation(self):
        with pytest.raises(BulkDataError, match=r"line 1.*no parent card"):
            group_cards(lines("+       1.      2.\n"))

    def test_bad_field_width(self):
        # a value straddles the boundary between fields 3 and 4
        with pytest.raises(BulkDataError, match=r"line 1.*embedded blank"):
            group_cards(lines("GRID    " + "1       " + "   1.5 2" + ".5      \n"))

    def test_line_too_long(self):
        with pytest.raises(BulkDataError, match="column 80"):
            group_cards(lines("GRID    1               0.      0.      0." + " " * 40 + "123\n"))

    def test_too_many_free_fields(self):
        with pytest.raises(BulkDataError, match="at most 8 data"):
            group_cards(lines("GRID,1,,0.,0.,0.,,,,+,5,6\n"))

    def test_bad_name(self):
        with pytest.raises(BulkDataError, match="not a card name"):
            group_cards(lines("1GRID   1\n"))


class TestCardLines:
    @pytest.mark.parametrize("fmt", ["small", "large", "free"])
    def test_round_trip(self, fmt):
        vals = [7, None, 1.5, -2.0, 0.25, None, None, None, None, 3.0, "ENDT"]
        text = "\n".join(card_lines("TABX", vals, fmt))
        c = group_cards(lines(text))[0]
        assert c.name == "TABX"
        assert [c.raw(i) for i in range(1, 12)] == ["7", "", "1.5", "-2.", ".25", "", "", "", "", "3.", "ENDT"]

    def test_blank_continuation_is_kept(self):
        text = card_lines("PBAR", [1, 2, 0.1, None, None, None, None, None] + [None] * 8 + [0.8], "small")
        assert len(text) == 3 and text[1].strip() == "+"
        c = group_cards(lines("\n".join(text)))[0]
        assert c.raw(17) == ".8"

    def test_unknown_format(self):
        with pytest.raises(BulkDataError):
            card_lines("GRID", [1], "tiny")

    def test_integer_too_wide(self):
        with pytest.raises(BulkDataError, match="does not fit"):
            card_lines("GRID", [123456789], "small")
        assert math.isfinite(parse_real(format_real(1.0 / 3.0, 16)))
