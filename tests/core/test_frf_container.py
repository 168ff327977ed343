"""The labelled FRF container."""
import numpy as np
import pytest

from modalab.core.errors import DofError, ModalabValueError, ShapeError
from modalab.core.frf import FRF, concat


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
    frf = FRF(freq_hz=f, H=H, responses=["1+Z", "2+Z"], references=["1+Z", "3+Z", "4+Z"], variance=var)
    sub = frf.select(responses=["2-Z"], references=["4+Z", "1+Z"]).band(3.0, 6.0)
    m = (f >= 3.0) & (f <= 6.0)
    assert sub.variance.shape == sub.H.shape
    np.testing.assert_array_equal(sub.variance, var[1][[2, 0]][None][..., m])   # a variance keeps its sign
    np.testing.assert_array_equal(sub.H, -H[1][[2, 0]][None][..., m])
    np.testing.assert_array_equal(frf.transpose().variance, var.transpose(1, 0, 2))
    # new data without a variance drop it (it described the old data)
    assert frf._replace(H=2 * H).variance is None
    # a variance of another shape is refused with the expected shape, not silently kept
    with pytest.raises(ShapeError, match=r"expected \(2, 3, 10\)"):
        FRF(freq_hz=f, H=H, responses=["1+Z", "2+Z"], references=["1+Z", "3+Z", "4+Z"], variance=np.ones(3))


class TestTypedWindow:
    """``window_beta_per_s`` and ``variance`` are fields; the former metadata keys map onto them."""

    def _frf(self, beta=0.0, **kw):
        f = np.linspace(1.0, 50.0, 50)
        lam = -2.0 + 2j * np.pi * 20.0
        s = 2j * np.pi * f + (beta if isinstance(beta, float) else 0.0)
        rec = 1.0 / ((s - lam) * (s - lam.conjugate()))                 # receptance at s = iω + β
        return FRF(freq_hz=f, H=(s ** 2 * rec)[None, None], responses=["1+Z"], references=["1+Z"],
                   window_beta_per_s=beta, **kw), rec

    def test_s_and_to_use_the_window_decay(self):
        frf, rec = self._frf(beta=3.0)
        np.testing.assert_allclose(frf.s, 1j * frf.omega + 3.0)
        np.testing.assert_allclose(frf.to("receptance").H[0, 0], rec, rtol=1e-12)
        # (iω)² would leave a relative error of order 2β/ω at the low lines
        wrong = frf.H[0, 0] / (1j * frf.omega) ** 2
        assert np.max(np.abs(wrong / rec - 1)) > 0.05
        assert frf.to("receptance").window_beta_per_s == 3.0

    def test_to_scales_the_variance(self):
        frf, _ = self._frf(beta=1.0, variance=np.ones((1, 1, 50)))
        np.testing.assert_allclose(frf.to("mobility").variance[0, 0], 1.0 / np.abs(frf.s) ** 2)

    def test_legacy_metadata_keys_are_the_fields(self):
        frf = FRF(freq_hz=[1.0, 2.0], H=np.ones((1, 1, 2)), responses=["1+Z"], references=["1+Z"],
                  metadata={"exp_window_beta": 0.5, "n_averages": 4})
        assert frf.window_beta_per_s == 0.5 and dict(frf.metadata) == {"n_averages": 4}
        with pytest.warns(DeprecationWarning, match="window_beta_per_s"):
            frf.metadata["exp_window_beta"] = 0.25
        assert frf.window_beta_per_s == 0.25
        with pytest.warns(DeprecationWarning):
            assert frf.metadata.get("exp_window_beta") == 0.25
        assert "H_variance" not in frf.metadata
        frf.metadata = {"estimator": "H1", "exp_window_beta": 0.125}
        assert frf.window_beta_per_s == 0.125 and "exp_window_beta" not in dict(frf.metadata)

    def test_copies_and_pickles_keep_the_fields(self):
        import pickle

        frf, _ = self._frf(beta=2.0, variance=np.full((1, 1, 50), 0.5), metadata={"n_averages": 3})
        for other in (frf.copy(), pickle.loads(pickle.dumps(frf))):
            assert other.window_beta_per_s == 2.0 and other.metadata == {"n_averages": 3}
            np.testing.assert_array_equal(other.variance, frf.variance)
            with pytest.warns(DeprecationWarning):
                other.metadata["exp_window_beta"] = 1.0            # still the typed field, not a stray key
            assert other.window_beta_per_s == 1.0 and frf.window_beta_per_s == 2.0

    @pytest.mark.parametrize("bad", [-0.1, float("nan"), "fast"])
    def test_bad_beta_is_refused(self, bad):
        with pytest.raises(ModalabValueError, match="window_beta_per_s"):
            self._frf(beta=bad)

    def test_concat_refuses_two_windows(self):
        a, _ = self._frf(beta=1.0)
        b, _ = self._frf(beta=2.0)
        b = b._replace(references=["2+Z"])
        with pytest.raises(ModalabValueError, match="different exponential windows"):
            concat([a, b], axis="references")
        c = concat([a, a._replace(references=["2+Z"])], axis="references")
        assert c.window_beta_per_s == 1.0
