"""Stabilisation flags, the order bookkeeping (no off-by-one), pole selection and the diagram figure."""
import dataclasses

import numpy as np
import pytest

from identification import (PolyMAX, SelectionOptions, StabilisationCriteria, auto_select, load_selection_file,
                            modal_system, plot_stabilisation, select_frequencies, select_poles, stabilise)
from modalab.core.errors import ModalabValueError


def _pole(f, z):
    w = 2 * np.pi * f
    return -z * w + 1j * w * np.sqrt(1 - z ** 2)


class TestCriteria:
    def test_defaults_and_frozen(self):
        c = StabilisationCriteria()
        assert (c.freq_tol, c.damping_tol, c.mac_min) == (0.01, 0.05, 0.98)
        with pytest.raises(dataclasses.FrozenInstanceError):
            c.freq_tol = 0.1

    def test_validation(self):
        with pytest.raises(ModalabValueError, match="freq_tol"):
            StabilisationCriteria(freq_tol=-1)
        with pytest.raises(ModalabValueError, match="mac_min"):
            StabilisationCriteria(mac_min=1.5)


class TestStabilise:
    def test_flags_compare_with_the_previous_order_only(self):
        L1 = np.ones((1, 1), complex)
        poles = [np.array([_pole(100, 0.02)]),        # order 3
                 np.array([_pole(100.5, 0.0201)]),    # order 4: within 1 % and 5 % of order 3
                 np.array([_pole(103, 0.02)]),        # order 5: 2.5 % off order 4
                 np.array([_pole(103.2, 0.03)])]      # order 6: freq ok, damping 50 % off
        d = stabilise([3, 4, 5, 6], poles, [L1] * 4)
        assert d.order.tolist() == [3, 4, 5, 6]
        assert d.stable.tolist() == [False, True, False, False]
        assert d.stable_freq.tolist() == [False, True, False, True]
        assert d.status.tolist() == ["o", "s", "o", "v"]   # one reference: the vector test is trivially met

    def test_vector_criterion(self):
        a = np.array([[1.0], [0.0]], complex)
        b = np.array([[0.6], [0.8]], complex)
        d = stabilise([1, 2, 3], [np.array([_pole(50, 0.01)])] * 3, [a, a, b])
        assert d.stable.tolist() == [False, True, False]
        assert d.stable_vector.tolist() == [False, True, False] and d.stable_damping[2]

    def test_rows_are_model_orders(self):
        """A single noise-free mode needs order 2 (one conjugate pair) with one reference.

        Order 1 gives one real root (no upper-half pole); the pole appears in the row of
        order 2 and is flagged stable first at order 3.  sdypy-EMA draws order n in
        column n-1 and compares with column n-2; here each row carries its order.
        """
        mm, _ = modal_system([60.0], [0.01], 2, rng=0)
        frf = mm.frf(np.linspace(1, 200, 600), references=[mm.dofs[0]], quantity="receptance")
        pm = PolyMAX(max_order=5, select=[60.0]).fit(frf)
        d = pm.stabilisation_
        assert d.orders.tolist() == [1, 2, 3, 4, 5]
        near = np.abs(d.freq_hz - 60.0) < 0.1          # the z-domain model approximates: 60.02 Hz at order 2
        assert not np.any(near & (d.order == 1))
        assert np.sum(near & (d.order == 2)) == 1
        assert not np.any(d.stable & (d.order == 2))
        assert np.any(near & d.stable & (d.order == 3))
        assert pm.selected_.order[0] == 5
        # with a step the rows are still the orders themselves
        ps = PolyMAX(max_order=6, min_order=2, order_step=2, select=[60.0]).fit(frf)
        assert ps.orders_.tolist() == [2, 4, 6]
        assert np.sum(np.abs(ps.stabilisation_.freq_hz[ps.stabilisation_.at_order(2)] - 60) < 0.1) == 1
        with pytest.raises(ModalabValueError, match="not evaluated"):
            ps.stabilisation_.at_order(3)


def _diagram(rng, modes, orders=range(10, 41), spurious=3, bad=()):
    """Poles of `modes` (f, ζ, l) at every order with tiny scatter, plus random spurious poles."""
    poles, parts = [], []
    for n in orders:
        lam = [_pole(f * (1 + 1e-5 * rng.normal()), z * (1 + 1e-3 * rng.normal())) for f, z, _ in modes + list(bad)]
        L = [l for _, _, l in modes + list(bad)]
        for _ in range(spurious):
            lam.append(_pole(rng.uniform(20, 500), rng.uniform(0.001, 0.3)))
            v = rng.normal(size=2) + 1j * rng.normal(size=2)
            L.append(v / np.linalg.norm(v))
        poles.append(np.array(lam))
        parts.append(np.array(L).T)
    return stabilise(list(orders), poles, parts)


class TestSelection:
    def test_close_modes_with_different_damping_are_two(self):
        rng = np.random.default_rng(0)
        la = np.array([1.0, 0.2j]) / np.linalg.norm([1.0, 0.2])
        lb = np.array([0.3, 1.0]) / np.linalg.norm([0.3, 1.0])
        modes = [(240.0, 0.006, la), (247.0, 0.012, lb), (90.0, 0.01, la)]
        d = _diagram(rng, modes)
        sel = auto_select(d, band_hz=(10, 600))
        np.testing.assert_allclose(sel.freq_hz, [90, 240, 247], rtol=1e-4)
        np.testing.assert_allclose(sel.damping, [0.01, 0.006, 0.012], rtol=1e-2)
        assert np.all(sel.cluster_size >= 25)

    def test_crowded_blocks_are_split_without_losing_modes(self):
        rng = np.random.default_rng(3)
        la = np.array([1.0, 0.3]) / np.linalg.norm([1.0, 0.3])
        d = _diagram(rng, [(240.0, 0.006, la), (247.0, 0.012, la), (90.0, 0.01, la)])
        small = auto_select(d, SelectionOptions(max_block=20), band_hz=(10, 600))
        np.testing.assert_allclose(small.freq_hz, [90, 240, 247], rtol=1e-4)

    def test_unphysical_and_spurious_rejected(self):
        rng = np.random.default_rng(1)
        l0 = np.array([1.0, 0.0], complex)
        good = [(150.0, 0.01, l0)]
        bad = [(200.0, -0.01, l0), (300.0, 0.4, l0)]               # negative and excessive damping
        d = _diagram(rng, good, bad=bad, spurious=6)
        sel = auto_select(d, band_hz=(10, 600))
        np.testing.assert_allclose(sel.freq_hz, [150.0], rtol=1e-4)
        loose = auto_select(d, SelectionOptions(max_damping=0.5), band_hz=(10, 600))
        np.testing.assert_allclose(loose.freq_hz, [150.0, 300.0], rtol=1e-3)

    def test_manual_selection(self, tmp_path):
        rng = np.random.default_rng(2)
        l0 = np.array([1.0, 0.0], complex)
        d = _diagram(rng, [(100.0, 0.01, l0), (180.0, 0.02, l0)], spurious=0)
        sel = select_frequencies(d, [181.0, 99.5])
        np.testing.assert_allclose(sel.freq_hz, [100, 180], rtol=1e-4)
        assert sel.source == "manual" and np.all(sel.order == 40)
        with pytest.raises(ModalabValueError, match="no pole within"):
            select_frequencies(d, [140.0])
        with pytest.raises(ModalabValueError, match=r"99.5 Hz and 101 Hz both resolve to the pole at 99.99"):
            select_frequencies(d, [99.5, 101.0])        # one pole is one mode, never two
        f = tmp_path / "s.json"
        f.write_text('{"freq_hz": [100, 180]}')
        assert len(select_poles(d, f)) == 2
        with pytest.raises(ModalabValueError, match="does not exist"):
            load_selection_file(tmp_path / "missing.toml")
        (tmp_path / "bad.json").write_text("{nope")
        with pytest.raises(ModalabValueError, match="cannot parse"):
            load_selection_file(tmp_path / "bad.json")
        # a misspelt key is named with the closest (it read 'freq_hz must be a list of numbers; got None')
        (tmp_path / "typo.toml").write_text("freq_hzz = [100.0, 180.0]\n")
        with pytest.raises(ModalabValueError, match="unknown key 'freq_hzz'; did you mean 'freq_hz'"):
            load_selection_file(tmp_path / "typo.toml")
        # a modes.json (freq_hz among other keys) selects its frequencies
        (tmp_path / "modes.json").write_text('{"freq_hz": [100, 180], "damping": [0.01, 0.02]}')
        assert load_selection_file(tmp_path / "modes.json") == [100.0, 180.0]

    def test_diagram_figure(self, tmp_path):
        mm, _ = modal_system([60.0, 130.0], [0.01, 0.02], 3, rng=0)
        frf = mm.frf(np.linspace(1, 200, 400), references=[mm.dofs[0], mm.dofs[1]])
        pm = PolyMAX(max_order=10).fit(frf)
        for ind in ("cmif", "sum"):
            path = tmp_path / f"stab_{ind}.png"
            fig = plot_stabilisation(pm.stabilisation_, pm.frf_, selected_hz=pm.modes_.freq_hz, path=path,
                                     indicator=ind)
            assert path.stat().st_size > 10_000 and len(fig.axes) == 2


def test_duplicate_shapes_keep_a_close_pair_and_drop_a_repeated_mode():
    from identification.polymax import duplicate_shapes

    rng = np.random.default_rng(0)
    a, b = rng.normal(size=30), rng.normal(size=30)
    psi = np.column_stack([a, a * (1 + 1e-3j) + 0.01 * b, b, a]).astype(complex)
    f = np.array([100.0, 100.2, 100.3, 150.0])
    dup = duplicate_shapes(f, psi, np.array([10, 5, 4, 9]), 0.01, 0.9)
    # 100.2 repeats the shape of the larger 100.0 cluster; 100.3 is a distinct mode 0.3 % away; 150 Hz is far
    assert dup.tolist() == [False, True, False, False]
    # the larger cluster stays whichever comes first
    assert duplicate_shapes(f, psi, np.array([5, 10, 4, 9]), 0.01, 0.9).tolist() == [True, False, False, False]
