"""The labelled FRF container."""
import numpy as np
import pytest

from modalab.errors import DofError, ModalabValueError, ShapeError
from modalab.frf import FRF, concat


def make(n_out=3, n_in=2, n=16, seed=0):
    rng = np.random.default_rng(seed)
    H = rng.normal(size=(n_out, n_in, n)) + 1j * rng.normal(size=(n_out, n_in, n))
    coh = rng.uniform(size=(n_out, n_in, n))
    return FRF(freq_hz=np.arange(n) + 1.0, H=H, coherence=coh,
               responses=[f"{i + 1}+Z" for i in range(n_out)], references=[f"{10 + j}+Y" for j in range(n_in)])


class TestConstruction:
    def test_shape_mismatch_names_expected_shape(self):
        with pytest.raises(ShapeError, match=r"\(2, 1, 4\)"):
            FRF(freq_hz=np.arange(4.0), H=np.ones((3, 1, 4)), responses=["1+Z", "2+Z"], references=["1+Z"])

    def test_nonincreasing_frequency(self):
        with pytest.raises(ModalabValueError, match="increase"):
            FRF(freq_hz=[0, 2, 1.0], H=np.ones((1, 1, 3)), responses=["1+Z"], references=["1+Z"])

    def test_duplicate_labels(self):
        with pytest.raises(ModalabValueError, match="duplicate"):
            FRF(freq_hz=[1.0], H=np.ones((2, 1, 1)), responses=["1+Z", "1-Z"], references=["1+Z"])

    def test_unknown_quantity(self):
        with pytest.raises(ModalabValueError, match="accelerance"):
            FRF(freq_hz=[1.0], H=np.ones((1, 1, 1)), responses=["1+Z"], references=["1+Z"], quantity="force")

    def test_from_arrays_2d(self):
        f = FRF.from_arrays(np.arange(3.0), np.ones((2, 3)), ["1+Z", "2+Z"], ["1+Z"])
        assert f.shape == (2, 1, 3)


class TestSelection:
    def test_negated_selection(self):
        f = make()
        g = f.select(responses=["2-Z"], references=["11-Y"])
        np.testing.assert_array_equal(g.H[0, 0], f.H[1, 1])  # two sign flips cancel
        g = f.select(responses=["2-Z"], references=["11+Y"])
        np.testing.assert_array_equal(g.H[0, 0], -f.H[1, 1])
        assert str(g.responses[0]) == "2-Z"
        np.testing.assert_array_equal(g.coherence[0, 0], f.coherence[1, 1])

    def test_get_missing_dof(self):
        with pytest.raises(DofError, match="9\\+Z"):
            make().get("9+Z", "10+Y")

    def test_band(self):
        f = make().band(3, 6)
        np.testing.assert_array_equal(f.freq_hz, [3, 4, 5, 6])
        with pytest.raises(ModalabValueError, match="no frequency lines"):
            make().band(100, 200)

    def test_transpose_is_reciprocity(self):
        f = make()
        t = f.transpose()
        assert t.shape == (2, 3, 16)
        np.testing.assert_array_equal(t.get("11+Y", "1+Z"), f.get("1+Z", "11+Y"))
        np.testing.assert_array_equal(t.coherence[1, 0], f.coherence[0, 1])

    def test_concat_outputs_and_inputs(self):
        f = make()
        a, b = f.select(responses=["1+Z"]), f.select(responses=["2+Z", "3+Z"])
        c = concat([a, b])
        np.testing.assert_array_equal(c.H, f.H)
        d = concat([f.select(references=["10+Y"]), f.select(references=["11+Y"])], axis="references")
        np.testing.assert_array_equal(d.H, f.H)
        with pytest.raises(ShapeError):
            concat([f, f.band(1, 4)])


class TestQuantity:
    def test_exact_conversions(self):
        f = make()
        rec = f.to("receptance") if f.quantity != "receptance" else f
        acc = rec.to("accelerance")
        w = 2 * np.pi * f.freq_hz
        np.testing.assert_allclose(rec.H * -(w ** 2), f.H, rtol=1e-13)
        np.testing.assert_allclose(acc.H, f.H, rtol=1e-13)
        mob = f.to("mobility")
        np.testing.assert_allclose(mob.H, f.H / (1j * w), rtol=1e-13)
        assert mob.units == "m/s/N"

    def test_dc_is_nan_not_inf(self):
        f = FRF(freq_hz=[0.0, 1.0], H=np.ones((1, 1, 2)), responses=["1+Z"], references=["1+Z"])
        r = f.to("receptance")
        assert np.isnan(r.H[0, 0, 0]) and np.isfinite(r.H[0, 0, 1])


def test_select_and_band_slice_the_variance_with_the_data():
    f = np.linspace(1.0, 10.0, 10)
    H = np.arange(2 * 3 * 10, dtype=float).reshape(2, 3, 10) + 1j
    var = np.abs(H) * 1e-3
    frf = FRF(freq_hz=f, H=H, responses=["1+Z", "2+Z"], references=["1+Z", "3+Z", "4+Z"],
              metadata={"H_variance": var})
    sub = frf.select(responses=["2-Z"], references=["4+Z", "1+Z"]).band(3.0, 6.0)
    m = (f >= 3.0) & (f <= 6.0)
    assert sub.metadata["H_variance"].shape == sub.H.shape
    np.testing.assert_array_equal(sub.metadata["H_variance"], var[1][[2, 0]][None][..., m])   # a variance keeps its sign
    np.testing.assert_array_equal(sub.H, -H[1][[2, 0]][None][..., m])
    # a variance of another shape is left as it was (not silently cut)
    odd = FRF(freq_hz=f, H=H, responses=["1+Z", "2+Z"], references=["1+Z", "3+Z", "4+Z"],
              metadata={"H_variance": np.ones(3)})
    assert odd.band(3.0, 6.0).metadata["H_variance"].shape == (3,)
