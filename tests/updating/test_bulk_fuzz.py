"""Fuzzing the bulk-data reader: a damaged deck gives BulkDataError or a correct parse, nothing else.

Valid decks (four writing styles and a small deck) are truncated, corrupted byte
by byte, have fields shuffled within a line, lines deleted or duplicated.  For
every mutant, ``read_bdf`` must either raise :class:`BulkDataError` or return
bulk data that writes and reads back identically, and ``build_model`` on it must
either raise :class:`BulkDataError` or return a model.
"""
import warnings
from pathlib import Path

from hypothesis import HealthCheck, given, settings, strategies as st

from modalab.core.errors import BulkDataError
from updating.fe.bulk import BulkData, build_model, read_bdf, write_bdf
from updating.fe import FEModel

DATA = Path(__file__).parent / "data"
SMALL = ("GRID    1               0.      0.      0.\n"
         "GRID    2               1.      0.      0.\n"
         "MAT1    1       7.+10           .3      2700.\n"
         "PBARL   1       1               BAR                                     +A\n"
         "+A      .02     .01\n"
         "CBAR    1       1       1       2       0.      0.      1.\n"
         "CELAS2  2       1000.   2       3\n"
         "CONM2   3       2               .5      .01\n"
         "        1.-3            2.-3                    3.-3\n"
         "SPC1    1       123456  1\n"
         "PARAM,COUPMASS,1\n"
         "TABDMP1,4,CRIT\n,0.,.01,100.,.02,ENDT\n")
CORPUS = [SMALL] + [(DATA / n).read_text() for n in
                    ("frame_small.bdf", "frame_large_femap.bdf", "frame_free.bdf", "frame_pynastran.bdf")]
CHARS = list("0123456789.+-*,$ \tE\nDTHRUABCGXYZ'é\x00") + ["\r\n", "  ", ",,", "1.-", "THRU", "ENDT", "+A"]


def _shuffle_fields(line: str, i: int, j: int) -> str:
    if "," in line:
        f = line.split(",")
    else:
        f = [line[k:k + 8] for k in range(0, max(len(line), 8), 8)]
    if len(f) < 2:
        return line
    i, j = i % len(f), j % len(f)
    f[i], f[j] = f[j], f[i]
    return ",".join(f) if "," in line else "".join(x.ljust(8) for x in f)


@st.composite
def mutants(draw):
    text = draw(st.sampled_from(CORPUS))
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["truncate", "corrupt", "insert", "shuffle", "delete", "duplicate"]))
        n = max(len(text), 1)
        pos = draw(st.integers(0, n - 1))
        if kind == "truncate":
            text = text[:pos]
        elif kind == "corrupt":
            text = text[:pos] + draw(st.sampled_from(CHARS)) + text[pos + 1:]
        elif kind == "insert":
            text = text[:pos] + draw(st.sampled_from(CHARS)) + text[pos:]
        else:
            lines = text.split("\n")
            k = pos % len(lines)
            if kind == "shuffle":
                lines[k] = _shuffle_fields(lines[k], draw(st.integers(0, 12)), draw(st.integers(0, 12)))
            elif kind == "delete":
                del lines[k]
            else:
                lines.insert(k, lines[k])
            text = "\n".join(lines)
    return text


def _check(text: str) -> str:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            bulk = read_bdf(text + "\n", base_dir=DATA)
        except BulkDataError:
            return "error"
        assert isinstance(bulk, BulkData)
        # a correct parse: what was read writes and reads back identically in every format
        for fmt in ("small", "large", "free"):
            try:
                again = read_bdf(write_bdf(bulk, format=fmt), base_dir=DATA)
            except BulkDataError:
                assert bulk.unsupported, "a deck of supported cards must write back"
                continue
            assert again == bulk, fmt
        try:
            model = build_model(bulk)
        except BulkDataError:
            return "parsed"
        assert isinstance(model, FEModel)
        return "built"


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutants())
def test_mutated_decks_fail_only_with_bulk_data_error(text):
    _check(text)


@settings(max_examples=150, deadline=None)
@given(st.lists(st.sampled_from(CHARS + ["GRID ", "CBAR,", "PARAM,", "\n+", "\n"]), max_size=120).map("".join))
def test_random_text(text):
    _check(text)


def test_corpus_is_valid():
    assert all(_check(t) == "built" for t in CORPUS)
