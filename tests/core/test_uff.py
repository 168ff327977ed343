"""Unit tests of modalab.core.uff with hand-built tiny universal files.

The ASCII files below are written by hand from the UFF dataset 58 description
(SDRL "Universal Dataset Number 58", records 1-12; record 6 is
2(I5,I10),2(1X,10A1,I10,I4), record 7 is 3I10,3E13.5, records 8-11 are
I10,3I5,2(1X,20A1), data 6E13.5 for single precision, 4E20.12 / E13.5,2E20.12
for double precision).
"""
import numpy as np
import pytest

import pyuff
from modalab import FRF, ModeSet, TimeRecord
from modalab.core.errors import UffError
from modalab.core.units import G
from modalab.core import uff


# ----------------------------------------------------------------------------- hand-built files
TESTLAB_FRF = "\r\n".join([
    "    -1",
    "   151",
    "Model1",
    "NONE",
    "Simcenter Testlab",
    "12-Jun-23 10:11:12",
    "12-Jun-23 10:11:12",
    "Simcenter Testlab Universal File Export",
    "12-Jun-23 10:11:12",
    "    -1",
    "    -1",
    "   164",
    "         1SI - mks (Newton)           2",
    "  1.00000000000000000D+00  1.00000000000000000D+00  1.00000000000000000D+00",
    "  2.73150000000000000D+02",
    "    -1",
    "    -1",
    "    58",
    "H1_2:+Z/1:+Z",
    "NONE",
    "12-Jun-23 10:11:12",
    "Point2",
    "NONE",
    "    4         1    0         0 NONE               2   3 NONE               1   3",
    "         5         3         1  0.00000E+00  2.50000E-01  0.00000E+00",
    "        18    0    0    0 Frequency            Hz",
    "        12    1    0    0 Acceleration         m/s2",
    "        13    0    1    0 Force                N",
    "         0    0    0    0 NONE                 NONE",
    "  1.00000E+00  2.00000E+00 -3.00000E-01  4.00000E-01  5.00000E+00 -6.00000E+00",
    "    -1",
    "    -1",
    "    58",
    "H1_3:-Z/1:+Z",
    "NONE",
    "12-Jun-23 10:11:12",
    "Point3",
    "NONE",
    "    4         2    0         0 NONE               3  -3 NONE               1   3",
    "         5         3         1  0.00000E+00  2.50000E-01  0.00000E+00",
    "        18    0    0    0 Frequency            Hz",
    "        12    1    0    0 Acceleration         m/s2",
    "        13    0    1    0 Force                N",
    "         0    0    0    0 NONE                 NONE",
    "  7.00000E-01  8.00000E-01 -9.00000E+00  1.00000E+01  1.10000E-03  1.20000E+02",
    "    -1",
    "    -1",
    "    58",
    "Coh_2:+Z/1:+Z",
    "NONE",
    "12-Jun-23 10:11:12",
    "Point2",
    "NONE",
    "    6         3    0         0 NONE               2   3 NONE               1   3",
    "         2         3         1  0.00000E+00  2.50000E-01  0.00000E+00",
    "        18    0    0    0 Frequency            Hz",
    "         0    0    0    0 Coherence            NONE",
    "         0    0    0    0 NONE                 NONE",
    "         0    0    0    0 NONE                 NONE",
    "  1.00000E+00  9.50000E-01  5.00000E-01",
    "    -1",
    "",
])

# ME'scope-like: blank-separated free format, D exponents, uneven complex double, g/N in one label
MESCOPE_FRF = "\n".join([
    "    -1",
    "    58",
    "FRF 7X:1Z",
    "NONE",
    "NONE",
    "NONE",
    "NONE",
    "4 0 0 0 NONE 7 1 NONE 1 3",
    "6 3 0 0.0 0.0 0.0",
    "18 0 0 0 Hz Hz",
    "12 0 0 0 Accel g/N",
    "0 0 0 0 NONE NONE",
    "0 0 0 0 NONE NONE",
    "  1.00000D+00  1.000000000000D+00  2.000000000000D+00",
    "  2.50000D+00 -3.000000000000D-01  4.000000000000D+00",
    "  4.00000D+00  5.000000000000D+00 -6.000000000000D-02",
    "    -1",
])


def _write(tmp_path, name, text):
    p = tmp_path / name
    p.write_bytes(text.encode("latin-1") if isinstance(text, str) else text)
    return p


def _dataphysics_58b(byte_order=">", wrong_count=True, newline_before_end=True):
    """58b, big endian, complex single precision, CRLF header, header byte count halved (as pyuff writes)."""
    vals = np.array([1.0, -2.0, 0.5, 0.25, -8.0, 16.0], dtype=byte_order + "f4")
    payload = vals.tobytes()
    nbytes = len(payload) // 2 if wrong_count else len(payload)
    bo = 1 if byte_order == "<" else 2
    head = "\r\n".join([
        "    -1",
        "%6i%1s%6i%6i%12i%12i%6i%6i%12i%12i" % (58, "b", bo, 2, 11, nbytes, 0, 0, 0, 0),
        "DataPhysics FRF", "NONE", "NONE", "NONE", "NONE",
        "    4         1    0         0 NONE              10   2 NONE              20  -1",
        "         5         3         1  1.00000E+01  5.00000E-01  0.00000E+00",
        "        18    0    0    0 Frequency            Hz",
        "        11    0    0    0 Velocity             m/s",
        "        13    0    0    0 Force                N",
        "         0    0    0    0 NONE                 NONE",
    ]) + "\r\n"
    tail = ("\r\n" if newline_before_end else "") + "    -1\r\n"
    return head.encode() + payload + tail.encode()


def _frf(n_out=3, n_in=2, n=16, coherence=True, seed=0, quantity="accelerance"):
    rng = np.random.default_rng(seed)
    H = rng.normal(size=(n_out, n_in, n)) + 1j * rng.normal(size=(n_out, n_in, n))
    coh = rng.uniform(size=H.shape) if coherence else None
    resp = [f"{i + 1}{'+' if i % 2 == 0 else '-'}Z" for i in range(n_out)]
    ref = [f"{100 + j}{'-' if j % 2 else '+'}Y" for j in range(n_in)]
    return FRF(freq_hz=np.arange(n) * 0.125 + 2.0, H=H, responses=resp, references=ref, coherence=coh,
               quantity=quantity, window_beta_per_s=3.25,
               metadata={"estimator": "H1", "n_averages": 5,
                         "force_window": {"kind": "cosine taper", "fraction": 0.1}})


def _records(n_hits=3, seed=1):
    rng = np.random.default_rng(seed)
    return [TimeRecord(sample_rate_hz=51200.0, data=rng.normal(size=(3, 64)), dofs=["1+Z", "1+Z", "4-X"],
                       roles=["force", "response", "response"], units=["N", "m/s^2", "m/s^2"],
                       sensitivity=[0.00225, 0.0101, 0.0099], trigger_index=7, overload=[False, h == 2, False],
                       hit_id=h, metadata={"point": "1+Z"}) for h in range(1, n_hits + 1)]


# ----------------------------------------------------------------------------- reading other writers
class TestForeignFiles:
    def test_testlab_ascii_crlf(self, tmp_path):
        p = _write(tmp_path, "testlab.unv", TESTLAB_FRF)
        f = uff.read_frf(p)
        assert [str(d) for d in f.responses] == ["2+Z", "3-Z"]
        assert [str(d) for d in f.references] == ["1+Z"]
        assert f.quantity == "accelerance"
        np.testing.assert_array_equal(f.freq_hz, [0.0, 0.25, 0.5])
        np.testing.assert_allclose(f.H[0, 0], [1 + 2j, -0.3 + 0.4j, 5 - 6j], rtol=1e-6)
        np.testing.assert_allclose(f.H[1, 0], [0.7 + 0.8j, -9 + 10j, 0.0011 + 120j], rtol=1e-6)
        np.testing.assert_allclose(f.coherence[0, 0], [1.0, 0.95, 0.5])
        assert np.all(np.isnan(f.coherence[1, 0]))   # no coherence stored for 3-Z: NaN, not zero
        # the hand-built file is valid for pyuff too (cross-check of the column layout)
        ps = pyuff.UFF(str(p)).read_sets()
        s58 = [s for s in ps if s["type"] == 58]
        assert (s58[1]["rsp_node"], s58[1]["rsp_dir"], s58[1]["ref_node"]) == (3, -3, 1)

    def test_testlab_info(self, tmp_path):
        p = _write(tmp_path, "testlab.unv", TESTLAB_FRF)
        d = uff.info(p)
        assert d["datasets"] == {"151": 1, "164": 1, "58": 3}
        assert d["functions"] == {"FRF": 2, "coherence": 1}
        assert d["frf"]["responses"] == ["2+Z", "3-Z"] and d["frf"]["references"] == ["1+Z"]
        assert d["frf"]["freq_range_hz"] == [0.0, 0.5]
        assert d["units"]["code"] == 1 and d["frf"]["quantity"] == "accelerance"

    def test_mescope_free_format_g_per_newton(self, tmp_path):
        p = _write(tmp_path, "mescope.uff", MESCOPE_FRF)
        f = uff.read_frf(p)
        assert [str(d) for d in f.responses] == ["7+X"] and [str(d) for d in f.references] == ["1+Z"]
        np.testing.assert_array_equal(f.freq_hz, [1.0, 2.5, 4.0])
        np.testing.assert_allclose(f.H[0, 0], G * np.array([1 + 2j, -0.3 + 4j, 5 - 0.06j]), rtol=1e-12)

    @pytest.mark.parametrize("bo", [">", "<"])
    @pytest.mark.parametrize("wrong", [True, False])
    @pytest.mark.parametrize("nl", [True, False])
    def test_dataphysics_binary_variants(self, tmp_path, bo, wrong, nl):
        p = _write(tmp_path, "dp.uff", _dataphysics_58b(bo, wrong, nl))
        f = uff.read_frf(p)
        assert f.quantity == "mobility"
        assert [str(d) for d in f.responses] == ["10+Y"] and [str(d) for d in f.references] == ["20-X"]
        np.testing.assert_allclose(f.freq_hz, [10.0, 10.5, 11.0])
        np.testing.assert_array_equal(f.H[0, 0], [1 - 2j, 0.5 + 0.25j, -8 + 16j])

    def test_pyuff_written_binary_with_wrong_byte_count(self, tmp_path):
        p = tmp_path / "py.uff"
        x = np.arange(5) * 0.5
        data = np.array([1 + 1j, 2 - 1j, 3, 4j, -5 + 0.5j])
        sets = [pyuff.prepare_58(binary=1, func_type=4, rsp_node=3, rsp_dir=-3, ref_node=1, ref_dir=3,
                                 data=data.copy(), x=x, id1="x", abscissa_spacing=1, abscissa_spec_data_type=18,
                                 ordinate_spec_data_type=12, orddenom_spec_data_type=13)]
        pyuff.UFF(str(p)).write_sets(sets, mode="add")
        assert b"          40" in p.read_bytes()   # pyuff's header claims 40 bytes for 80 bytes of data
        f = uff.read_frf(p)
        np.testing.assert_array_equal(f.H[0, 0], data)
        assert str(f.responses[0]) == "3-Z"

    def test_minus_one_pattern_inside_binary_data(self, tmp_path):
        pattern = np.frombuffer(b"\n    -1\n" + b"\x00" * 8, dtype="<f8")
        H = np.array([[[complex(pattern[0], pattern[1]), 1 + 1j]]])
        frf = FRF(freq_hz=[1.0, 2.0], H=H, responses=["1+Z"], references=["1+Z"])
        p = tmp_path / "pat.uff"
        uff.write_frf(p, frf)
        assert b"\n    -1\n" in p.read_bytes()[200:-8]
        np.testing.assert_array_equal(uff.read_frf(p).H, H)

    def test_quantity_needs_override_for_unknown_ordinate(self, tmp_path):
        text = MESCOPE_FRF.replace("12 0 0 0 Accel g/N", "1 0 0 0 Ratio NONE")
        p = _write(tmp_path, "gen.uff", text)
        with pytest.raises(UffError, match="quantity="):
            uff.read_frf(p)
        f = uff.read_frf(p, quantity="mobility")
        assert f.quantity == "mobility"
        np.testing.assert_allclose(f.H[0, 0, 0], 1 + 2j)

    def test_transmissibility_is_not_an_frf(self, tmp_path):
        text = MESCOPE_FRF.replace("0 0 0 0 NONE NONE", "12 0 0 0 Accel m/s^2", 1)
        with pytest.raises(UffError, match="denominator data type 12.*not force"):
            uff.read_frf(_write(tmp_path, "t.uff", text))

    def test_units_164_mm_converts(self, tmp_path):
        text = TESTLAB_FRF.replace("m/s2", "NONE").replace(
            "         1SI - mks (Newton)           2\r\n  1.00000000000000000D+00",
            "         5MM (milli newton)           2\r\n  1.00000000000000000D+03")
        p = _write(tmp_path, "mm.unv", text)
        f = uff.read_frf(p)
        np.testing.assert_allclose(f.H[0, 0], 1e-3 * np.array([1 + 2j, -0.3 + 0.4j, 5 - 6j]), rtol=1e-6)


# ----------------------------------------------------------------------------- round trips and layout
class TestFrfIO:
    @pytest.mark.parametrize("binary", [True, False])
    def test_round_trip(self, tmp_path, binary):
        frf = _frf()
        p = tmp_path / "f.uff"
        uff.write_frf(p, frf, binary=binary)
        g = uff.read_frf(p)
        assert g.responses == frf.responses and g.references == frf.references
        np.testing.assert_array_equal(g.freq_hz, frf.freq_hz)
        if binary:
            np.testing.assert_array_equal(g.H, frf.H)
            np.testing.assert_array_equal(g.coherence, frf.coherence)
        else:
            np.testing.assert_allclose(g.H, frf.H, rtol=1e-12)
            np.testing.assert_allclose(g.coherence, frf.coherence, rtol=1e-12)
        for k in ("estimator", "n_averages", "force_window"):
            assert g.metadata[k] == frf.metadata[k]
        assert g.window_beta_per_s == frf.window_beta_per_s > 0
        assert g.quantity == "accelerance"

    @pytest.mark.parametrize("binary", [True, False])
    def test_pyuff_reads_our_files(self, tmp_path, binary):
        frf = _frf(coherence=True)
        p = tmp_path / "f.uff"
        uff.write_frf(p, frf, binary=binary)
        sets = pyuff.UFF(str(p)).read_sets()
        assert len(sets) == 12
        s = sets[1]   # H for response 1+Z, reference 101-Y
        assert (s["func_type"], s["rsp_node"], s["rsp_dir"], s["ref_node"], s["ref_dir"]) == (4, 1, 3, 101, -2)
        assert (s["ordinate_spec_data_type"], s["orddenom_spec_data_type"], s["abscissa_spec_data_type"]) == \
               (12, 13, 18)
        assert s["ord_data_type"] == 6 and sets[6]["ord_data_type"] == 4 and sets[6]["func_type"] == 6
        np.testing.assert_allclose(s["data"], frf.H[0, 1], rtol=0 if binary else 1e-11)
        np.testing.assert_allclose(s["x"], frf.freq_hz, rtol=1e-6)

    def test_quantities_and_types(self, tmp_path):
        for q, code, unit in (("receptance", 8, "m"), ("mobility", 11, "m/s"), ("accelerance", 12, "m/s^2")):
            p = tmp_path / f"{q}.uff"
            uff.write_frf(p, _frf(quantity=q, coherence=False), binary=False)
            lines = p.read_text().splitlines()
            assert lines[10].split()[0] == str(code) and lines[10].split()[-1] == unit
            assert lines[11].split()[0] == "13" and lines[11].split()[-1] == "N"
            assert uff.read_frf(p).quantity == q

    def test_ascii_layout_and_full_precision_abscissa(self, tmp_path):
        frf = FRF(freq_hz=np.arange(5) * (51200 / 4096), H=np.ones((1, 1, 5)) * (1 - 2j),
                  responses=["12-Z"], references=["1+Z"])
        p = tmp_path / "a.uff"
        uff.write_frf(p, frf, binary=False)
        lines = p.read_text().splitlines()
        assert lines[1].strip() == "58"
        assert lines[3].startswith("modalab x0=0.0 dx=12.5")
        assert lines[7][:5] == "    4" and lines[7][41:55] == "        12  -3"
        assert lines[8][:30] == "         6         5         1"
        assert all(len(ln) == 80 for ln in lines[2:8]) and len(lines[8]) == 69
        assert lines[13] == "  1.000000000000E+00 -2.000000000000E+00  1.000000000000E+00 -2.000000000000E+00"
        assert lines[-1] == "    -1"
        g = uff.read_frf(p)
        np.testing.assert_array_equal(g.freq_hz, frf.freq_hz)

    def test_input_not_modified_and_nan_kept(self, tmp_path):
        frf = _frf(coherence=False)
        frf.H[0, 0, 3] = np.nan
        before = frf.H.copy()
        p = tmp_path / "n.uff"
        uff.write_frf(p, frf)
        np.testing.assert_array_equal(frf.H, before)
        g = uff.read_frf(p)
        assert np.isnan(g.H[0, 0, 3]) and np.array_equal(g.H[0, 1], before[0, 1])

    def test_uneven_axis_binary_exact(self, tmp_path):
        f = np.array([1.0, 1.5, 3.0, 3.25])
        frf = FRF(freq_hz=f, H=np.arange(4)[None, None] * (1 + 1j), responses=["1+X"], references=["2+Y"])
        p = tmp_path / "u.uff"
        uff.write_frf(p, frf)
        g = uff.read_frf(p)
        np.testing.assert_array_equal(g.freq_hz, f)
        np.testing.assert_array_equal(g.H, frf.H)

    def test_signs_relabelled_consistently(self, tmp_path):
        """A DOF stored with both signs is labelled as first seen; the other set is negated."""
        p = tmp_path / "s.uff"
        a = FRF(freq_hz=[1.0, 2.0], H=[[[1 + 1j, 2]]], responses=["5-Z"], references=["1+Z"])
        b = FRF(freq_hz=[1.0, 2.0], H=[[[3j, 4]]], responses=["5+Z"], references=["2+Z"])
        uff.write_frf(p, a)
        uff.write_frf(p, b, append=True)
        g = uff.read_frf(p)
        assert [str(d) for d in g.responses] == ["5-Z"]
        np.testing.assert_array_equal(g.H[0, 1], [-3j, -4])
        np.testing.assert_array_equal(g.get("5+Z", "2+Z"), [3j, 4])

    def test_binary_header_byte_count(self, tmp_path):
        """Our 58b header states the true byte count (pyuff writes half of it for complex data)."""
        frf = _frf(n_out=1, n_in=1, n=10, coherence=True)
        p = tmp_path / "f.uff"
        uff.write_frf(p, frf)
        raw = p.read_bytes()
        heads = [ln for ln in raw.split(b"\n") if ln.startswith(b"    58b")]
        assert [int(h.split()[4]) for h in heads] == [10 * 16, 10 * 8]   # complex FRF, real coherence

    def test_unknown_label_requested(self, tmp_path):
        from modalab.core.errors import DofError
        p = tmp_path / "f.uff"
        uff.write_frf(p, _frf())
        with pytest.raises(DofError, match="99\\+Z"):
            uff.read_frf(p, responses=["99+Z"])

    def test_subset_selection(self, tmp_path):
        frf = _frf()
        p = tmp_path / "f.uff"
        uff.write_frf(p, frf)
        g = uff.read_frf(p, responses=["3+Z"], references=["100+Y"])
        np.testing.assert_array_equal(g.H[0, 0], frf.H[2, 0])


class TestFrfErrors:
    def test_incomplete_matrix_names_pairs(self, tmp_path):
        frf = _frf(n_out=2, n_in=2, coherence=False)
        p = tmp_path / "f.uff"
        uff.write_frf(p, frf.select(references=["100+Y"]))
        uff.write_frf(p, frf.select(responses=["1+Z"], references=["101-Y"]), append=True)
        with pytest.raises(UffError, match=r"2-Z/101-Y.*responses=\[") as e:
            uff.read_frf(p)
        assert "f.uff" in str(e.value)
        g = uff.read_frf(p, references=["100+Y"])
        assert g.shape == (2, 1, 16)

    def test_different_frequency_axes(self, tmp_path):
        p = tmp_path / "f.uff"
        a = FRF(freq_hz=[1.0, 2.0], H=[[[1, 2]]], responses=["1+Z"], references=["1+Z"])
        b = FRF(freq_hz=[1.0, 3.0], H=[[[1, 2]]], responses=["2+Z"], references=["1+Z"])
        uff.write_frf(p, a)
        uff.write_frf(p, b, append=True)
        with pytest.raises(UffError, match="frequency axis"):
            uff.read_frf(p)

    def test_duplicate_pair(self, tmp_path):
        p = tmp_path / "f.uff"
        a = FRF(freq_hz=[1.0, 2.0], H=[[[1, 2]]], responses=["1+Z"], references=["1+Z"])
        uff.write_frf(p, a)
        uff.write_frf(p, a, append=True)
        with pytest.raises(UffError, match="appears twice"):
            uff.read_frf(p)

    def test_truncated_names_file_dataset_line(self, tmp_path):
        p = _write(tmp_path, "t.unv", TESTLAB_FRF[:TESTLAB_FRF.index("7.00000E-01")])
        with pytest.raises(UffError) as e:
            uff.read_frf(p)
        msg = str(e.value)
        assert "t.unv" in msg and "dataset 58" in msg and "line 32" in msg and "truncated" in msg

    def test_truncated_binary(self, tmp_path):
        raw = _dataphysics_58b()
        p = _write(tmp_path, "t.uff", raw[:-20])
        with pytest.raises(UffError, match="58b.*truncated"):
            uff.read_frf(p)

    def test_bad_number_names_line(self, tmp_path):
        p = _write(tmp_path, "b.unv", TESTLAB_FRF.replace("-3.00000E-01", "-3.0000XE-01"))
        with pytest.raises(UffError, match="line 30.*not numeric"):
            uff.read_frf(p)

    def test_unwritable_path(self, tmp_path):
        for append in (False, True):
            with pytest.raises(UffError, match="cannot write"):
                uff.write_units(tmp_path / "no" / "such" / "dir.uff", append=append)

    def test_missing_file_and_wrong_content(self, tmp_path):
        with pytest.raises(UffError, match="cannot read"):
            uff.read_frf(tmp_path / "nope.uff")
        p = _write(tmp_path, "x.txt", "hello\nworld\n")
        with pytest.raises(UffError, match="line 1.*-1"):
            uff.read_frf(p)
        q = tmp_path / "r.uff"
        uff.write_records(q, _records(1))
        with pytest.raises(UffError, match="no FRFs.*time response.*read_records"):
            uff.read_frf(q)


class TestWriterSpeedShape:
    def test_sets_written_in_one_pass_and_append(self, tmp_path):
        """Units, geometry, FRFs and modes appended into one file all read back."""
        p = tmp_path / "all.uff"
        uff.write_units(p)
        uff.write_geometry(p, {1: (0.0, 0.1, 0.2), 2: (1.0, -2.0, 3.5)}, append=True)
        frf = _frf()
        uff.write_frf(p, frf, append=True)
        uff.write_modes(p, ModeSet(freq_hz=[5.0], damping=[0.01], shapes=[[1.0], [-2.0]], dofs=["1+Z", "2+Z"]),
                        append=True)
        d = uff.info(p)
        assert d["datasets"] == {"164": 1, "2411": 1, "58b": 12, "55": 1}
        assert d["nodes"] == 2 and d["modes"]["n_modes"] == 1
        np.testing.assert_array_equal(uff.read_frf(p).H, frf.H)
        assert uff.read_geometry(p)[2] == (1.0, -2.0, 3.5)
        assert uff.read_units(p)["length"] == 1.0


# ----------------------------------------------------------------------------- records
class TestRecords:
    @pytest.mark.parametrize("binary", [True, False])
    def test_round_trip(self, tmp_path, binary):
        recs = _records()
        p = tmp_path / "r.uff"
        uff.write_records(p, recs, binary=binary)
        back = uff.read_records(p)
        assert [r.hit_id for r in back] == [1, 2, 3]
        for a, b in zip(recs, back):
            assert b.dofs == a.dofs and b.roles == a.roles and b.units == a.units
            assert b.trigger_index == a.trigger_index and b.sample_rate_hz == a.sample_rate_hz
            np.testing.assert_array_equal(b.sensitivity, a.sensitivity)
            np.testing.assert_array_equal(b.overload, a.overload)
            assert b.metadata == a.metadata
            if binary:
                np.testing.assert_array_equal(b.data, a.data)
            else:
                np.testing.assert_allclose(b.data, a.data, rtol=1e-12)

    def test_layout(self, tmp_path):
        p = tmp_path / "r.uff"
        uff.write_records(p, _records(1), binary=False)
        sets = pyuff.UFF(str(p)).read_sets()
        assert len(sets) == 3
        s = sets[2]
        assert (s["func_type"], s["load_case_id"], s["rsp_node"], s["rsp_dir"], s["ref_node"], s["ref_dir"]) == \
               (1, 1, 4, -1, 1, 3)
        assert (s["abscissa_spec_data_type"], sets[0]["ordinate_spec_data_type"], s["ordinate_spec_data_type"]) == \
               (17, 13, 12)
        assert s["ordinate_axis_units_lab"] == "m/s^2" and sets[0]["ordinate_axis_units_lab"] == "N"
        assert s["id2"].split()[:4] == ["modalab", "role=response", "sens=0.0099", "ovl=0"]
        assert s["id4"] == "modalab fs=51200.0 trig=7"
        np.testing.assert_allclose(s["x"][7], 0.0, atol=1e-9)

    def test_ac_coupling_corners_round_trip_in_id_line_4(self, tmp_path):
        """The channels' AC-coupling corners (metadata highpass_hz), which the FRF estimator's force window needs,
        survive the file (ID line 4 ``hp=``): before, they were dropped with the other metadata too long for
        ID line 5, and ``modalab frf`` of simulated hits cut the coupling's undershoot from the force."""
        recs = _records(2)
        for r in recs:
            r.metadata = {"point": "1+Z", "highpass_hz": [0.5, 0.5, 0.15915494309189535],
                          "range_v": [5.0, 5.0, 5.0], "source": "hardware_sim", "aa_filter": "delta-sigma"}
        p = tmp_path / "r.uff"
        uff.write_records(p, recs, binary=False)
        assert pyuff.UFF(str(p)).read_sets()[2]["id4"] == "modalab fs=51200.0 trig=7 hp=0.15915494309189535"
        assert [r.metadata["highpass_hz"] for r in uff.read_records(p)] == [[0.5, 0.5, 0.15915494309189535]] * 2
        bad = p.read_text().replace("trig=7 hp=0.5 ", "trig=7 hp=x.5 ", 1)
        (tmp_path / "bad.uff").write_text(bad)
        with pytest.raises(UffError, match=r"AC-coupling corner hp='x.5' in ID line 4 is not a number"):
            uff.read_records(tmp_path / "bad.uff")
        recs[0].metadata["highpass_hz"] = [0.5]
        with pytest.raises(UffError, match="one AC-coupling corner >= 0 Hz per channel"):
            uff.write_records(tmp_path / "w.uff", recs)

    def test_missing_channel_detected(self, tmp_path):
        p = tmp_path / "r.uff"
        rec = _records(1)[0]
        uff.write_records(p, [rec])
        raw = p.read_bytes()
        second = raw.index(b"    -1\n    58b", 10)
        third = raw.index(b"    -1\n    58b", second + 10)
        p.write_bytes(raw[:second] + raw[third:])
        with pytest.raises(UffError, match="2 time record datasets of write .* writer wrote 3; datasets were lost"):
            uff.read_records(p)

    def test_foreign_time_record(self, tmp_path):
        """A time record from another writer: role from the ordinate type, trigger from the start time."""
        text = "\n".join([
            "    -1", "    58", "Force", "NONE", "NONE", "NONE", "NONE",
            "    1         1    1         4 NONE               9   3 NONE               9   3",
            "         4         4         1 -2.00000E-03  1.00000E-03  0.00000E+00",
            "        17    0    0    0 Time                 s",
            "        13    0    1    0 Force                lbf",
            "         0    0    0    0 NONE                 NONE",
            "         0    0    0    0 NONE                 NONE",
            "  1.000000000000E+00  2.000000000000E+00  3.000000000000E+00  4.000000000000E+00",
            "    -1", ""])
        p = _write(tmp_path, "t.uff", text)
        (r,) = uff.read_records(p)
        assert r.hit_id == 4 and r.roles == ["force"] and r.trigger_index == 2 and r.units == ["N"]
        assert r.sample_rate_hz == pytest.approx(1000.0)
        np.testing.assert_allclose(r.data[0], 4.4482216152605 * np.arange(1, 5))


# ----------------------------------------------------------------------------- geometry, modes, units
class TestGeometryModesUnits:
    def test_geometry_2411_exact_and_15(self, tmp_path):
        geo = {1: (0.1, -0.2, 1 / 3), 7: (1e-9, 2.5, -1e5)}
        p = tmp_path / "g.uff"
        uff.write_geometry(p, geo)
        assert uff.read_geometry(p) == geo
        ps = pyuff.UFF(str(p)).read_sets()
        np.testing.assert_array_equal(ps["z"], [1 / 3, -1e5])
        q = tmp_path / "g15.uff"
        uff.write_geometry(q, geo, dataset=15)
        back = uff.read_geometry(q)
        np.testing.assert_allclose(back[1], geo[1], rtol=1e-6)
        assert pyuff.UFF(str(q)).read_sets()["node_nums"] == [1.0, 7.0]

    def test_geometry_hand_written_15(self, tmp_path):
        text = "    -1\n    15\n         1         0         0        11 1.00000E+00-2.50000E-01 3.00000E+00\n" \
               "         2         0         0        11-1.00000E+00 0.00000E+00 1.00000E-03\n    -1\n"
        p = _write(tmp_path, "n.unv", text)
        assert uff.read_geometry(p) == {1: (1.0, -0.25, 3.0), 2: (-1.0, 0.0, 0.001)}

    def test_geometry_duplicate_node(self, tmp_path):
        text = "    -1\n  2411\n         1         1         1        11\n  1.0  2.0  3.0\n" \
               "         1         1         1        11\n  1.0  2.0  4.0\n    -1\n"
        with pytest.raises(UffError, match="node 1 is listed twice"):
            uff.read_geometry(_write(tmp_path, "d.unv", text))

    @pytest.mark.parametrize("cplx", [False, True])
    def test_modes_round_trip(self, tmp_path, cplx):
        rng = np.random.default_rng(3)
        phi = rng.normal(size=(4, 2)) + (1j * rng.normal(size=(4, 2)) if cplx else 0)
        m = ModeSet(freq_hz=[10.0, 25.5], damping=[0.01, 0.02], shapes=phi, dofs=["1+Z", "2-Z", "2+X", "3+RZ"],
                    scaling="unit_modal_mass")
        p = tmp_path / "m.uff"
        uff.write_modes(p, m)
        back = uff.read_modes(p, dofs=m.dofs)
        assert back.dofs == m.dofs and back.scaling == "unit_modal_mass"
        np.testing.assert_array_equal(back.shapes, m.shapes)
        np.testing.assert_array_equal(back.freq_hz, m.freq_hz)
        np.testing.assert_array_equal(back.damping, m.damping)
        plain = uff.read_modes(p)
        assert [str(d) for d in plain.dofs] == ["1+Z", "2+X", "2+Z", "3+RZ"]
        np.testing.assert_array_equal(plain.shapes[2], -phi[1])

    def test_modes_standard_format_read_by_pyuff(self, tmp_path):
        m = ModeSet(freq_hz=[12.5], damping=[0.03], shapes=[[1.0], [-0.5]], dofs=["1+Z", "2-Y"],
                    indicators={"modal_mass": [2.5]})
        p = tmp_path / "m.uff"
        uff.write_modes(p, m, exact=False)
        s = pyuff.UFF(str(p)).read_sets()
        assert s["analysis_type"] == 2 and s["freq"] == 12.5 and s["modal_m"] == 2.5
        np.testing.assert_array_equal(s["r2"], [0.0, 0.5])
        back = uff.read_modes(p)
        np.testing.assert_array_equal(back.indicators["modal_mass"], [2.5])
        np.testing.assert_allclose(back.select_dofs(["2-Y"]).shapes, [[-0.5]])

    def test_units(self, tmp_path):
        p = tmp_path / "u.uff"
        uff.write_units(p)
        u = uff.read_units(p)
        assert (u["code"], u["length"], u["force"], u["temperature_offset"]) == (1, 1.0, 1.0, 273.15)
        assert pyuff.UFF(str(p)).read_sets()["units_code"] == 1


def test_mode_id_line_tokens_that_are_not_numbers_fall_back_to_record_8_with_a_warning(tmp_path, caplog):
    import logging
    import re

    ms = ModeSet(freq_hz=[12.5, 30.0], damping=[0.01, 0.02], shapes=np.array([[1.0, 0.5], [0.3, -1.0]]),
                 dofs=["1+Z", "2+Z"])
    p = tmp_path / "m.uff"
    uff.write_modes(p, ms)
    text = p.read_text()
    p.write_text(re.sub(r"modalab f=\S+ z=", "modalab f=abc z=", text, count=1))
    with caplog.at_level(logging.WARNING, logger="modalab.core.uff"):
        back = uff.read_modes(p)
    np.testing.assert_allclose(back.freq_hz, [12.5, 30.0], rtol=1e-12)      # record 8 is exact (25-char fields)
    assert "are not numbers; using record 8" in caplog.text
