"""Hypothesis round-trips of modalab.core.uff: write -> read returns the same DOFs, signs, units and values.

Binary 58b and dataset 2411 / exact dataset 55 are bit-exact; ASCII 58 carries
13 significant digits (the standard's E20.12 field), checked to rtol 1e-11.
"""
import tempfile
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings, strategies as st

from modalab import FRF, Dof, ModeSet, TimeRecord
from modalab.core import uff

SETTINGS = dict(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])

finite = st.floats(min_value=-1e200, max_value=1e200, allow_nan=False, allow_infinity=False, width=64).filter(
    lambda v: v == 0 or abs(v) > 1e-200)


@st.composite
def dof_lists(draw, n, axes=(1, 2, 3, 4, 5, 6)):
    keys = draw(st.lists(st.tuples(st.integers(1, 10 ** 6), st.sampled_from(axes)), min_size=n, max_size=n,
                         unique=True))
    signs = draw(st.lists(st.sampled_from([1, -1]), min_size=n, max_size=n))
    return [Dof(node, s * a) for (node, a), s in zip(keys, signs)]


def complex_array(draw, shape):
    size = int(np.prod(shape))
    re = draw(st.lists(finite, min_size=size, max_size=size))
    im = draw(st.lists(finite, min_size=size, max_size=size))
    return (np.array(re) + 1j * np.array(im)).reshape(shape)


@st.composite
def frfs(draw):
    n_out, n_in, n = draw(st.integers(1, 4)), draw(st.integers(1, 3)), draw(st.integers(1, 24))
    x0 = draw(st.floats(0, 1e4, allow_nan=False))
    dx = draw(st.floats(1e-3, 1e3, allow_nan=False))
    freq = x0 + np.arange(n) * dx
    H = complex_array(draw, (n_out, n_in, n))
    coh = None
    if draw(st.booleans()):
        coh = np.array(draw(st.lists(st.floats(0, 1), min_size=H.size, max_size=H.size))).reshape(H.shape)
    meta = {"estimator": draw(st.sampled_from(["H1", "H2", "Hv"])), "n_averages": draw(st.integers(1, 10 ** 6))}
    dofs = draw(dof_lists(n_out + n_in))
    return FRF(freq_hz=freq, H=H, responses=dofs[:n_out], references=dofs[n_out:], coherence=coh,
               quantity=draw(st.sampled_from(["receptance", "mobility", "accelerance"])), metadata=meta,
               window_beta_per_s=draw(st.floats(0, 1e3, allow_nan=False)))


def _tmp():
    d = tempfile.TemporaryDirectory()
    return d, Path(d.name) / "x.uff"


@settings(**SETTINGS)
@given(frf=frfs(), binary=st.booleans())
def test_frf_round_trip(frf, binary):
    d, p = _tmp()
    with d:
        H0 = frf.H.copy()
        uff.write_frf(p, frf, binary=binary)
        np.testing.assert_array_equal(frf.H, H0)          # input untouched
        g = uff.read_frf(p)
    assert g.responses == frf.responses and g.references == frf.references
    assert [d.direction for d in g.responses] == [d.direction for d in frf.responses]
    assert g.quantity == frf.quantity and g.units == frf.units
    np.testing.assert_allclose(g.freq_hz, frf.freq_hz, rtol=4 * np.finfo(float).eps, atol=0)
    if binary:
        np.testing.assert_array_equal(g.H, frf.H)
    else:
        np.testing.assert_allclose(g.H.real, frf.H.real, rtol=1e-11, atol=0)
        np.testing.assert_allclose(g.H.imag, frf.H.imag, rtol=1e-11, atol=0)
    if frf.coherence is None:
        assert g.coherence is None
    else:
        np.testing.assert_allclose(g.coherence, frf.coherence, rtol=0 if binary else 1e-11, atol=0)
    assert g.window_beta_per_s == frf.window_beta_per_s
    for k, v in frf.metadata.items():
        assert g.metadata[k] == v


@st.composite
def hits(draw):
    n_hits = draw(st.integers(1, 3))
    n_ch, n = draw(st.integers(1, 4)), draw(st.integers(2, 40))
    fs = draw(st.floats(1.0, 1e6, allow_nan=False))
    ids = draw(st.lists(st.integers(0, 2 ** 31 - 1), min_size=n_hits, max_size=n_hits, unique=True))
    out = []
    for h in ids:
        roles = draw(st.lists(st.sampled_from(["force", "response"]), min_size=n_ch, max_size=n_ch))
        units = [draw(st.sampled_from(["N"])) if r == "force" else draw(st.sampled_from(["m/s^2", "m/s", "m"]))
                 for r in roles]
        data = np.array(draw(st.lists(finite, min_size=n_ch * n, max_size=n_ch * n))).reshape(n_ch, n)
        sens = draw(st.lists(st.floats(1e-6, 10, allow_nan=False), min_size=n_ch, max_size=n_ch))
        ovl = draw(st.lists(st.booleans(), min_size=n_ch, max_size=n_ch))
        dofs = draw(st.lists(st.tuples(st.integers(1, 10 ** 5), st.sampled_from([-3, -2, -1, 1, 2, 3])),
                             min_size=n_ch, max_size=n_ch))
        out.append(TimeRecord(sample_rate_hz=fs, data=data, dofs=dofs, roles=roles, units=units,
                              sensitivity=sens, trigger_index=draw(st.integers(0, n - 1)), overload=ovl, hit_id=h,
                              metadata={"point": draw(st.sampled_from(["1+Z", "7-X", "a b"]))}))
    return out


@settings(**SETTINGS)
@given(recs=hits(), binary=st.booleans())
def test_records_round_trip(recs, binary):
    d, p = _tmp()
    with d:
        uff.write_records(p, recs, binary=binary)
        back = uff.read_records(p)
    assert [r.hit_id for r in back] == [r.hit_id for r in recs]
    for a, b in zip(recs, back):
        assert b.dofs == a.dofs and b.roles == a.roles and b.units == a.units
        assert b.sample_rate_hz == a.sample_rate_hz and b.trigger_index == a.trigger_index
        np.testing.assert_array_equal(b.sensitivity, a.sensitivity)
        np.testing.assert_array_equal(b.overload, a.overload)
        assert b.metadata == a.metadata
        if binary:
            np.testing.assert_array_equal(b.data, a.data)
        else:
            np.testing.assert_allclose(b.data, a.data, rtol=1e-11, atol=0)


@st.composite
def modesets(draw):
    n_dof, n_modes = draw(st.integers(1, 6)), draw(st.integers(1, 3))
    dofs = draw(dof_lists(n_dof))
    cplx = draw(st.booleans())
    phi = complex_array(draw, (n_dof, n_modes)) if cplx else \
        np.array(draw(st.lists(finite, min_size=n_dof * n_modes, max_size=n_dof * n_modes))).reshape(n_dof, n_modes)
    f = draw(st.lists(st.floats(1e-2, 1e5, allow_nan=False), min_size=n_modes, max_size=n_modes))
    z = draw(st.lists(st.floats(0, 0.5, allow_nan=False), min_size=n_modes, max_size=n_modes))
    return ModeSet(freq_hz=f, damping=z, shapes=phi, dofs=dofs,
                   scaling=draw(st.sampled_from(["unit_modal_mass", "unit_max", "arbitrary"])))


@settings(**SETTINGS)
@given(m=modesets())
def test_modes_round_trip(m):
    d, p = _tmp()
    with d:
        uff.write_modes(p, m)
        back = uff.read_modes(p, dofs=m.dofs)
        plain = uff.read_modes(p)
    assert back.dofs == m.dofs and back.scaling == m.scaling
    np.testing.assert_array_equal(back.shapes, m.shapes)
    np.testing.assert_array_equal(back.freq_hz, m.freq_hz)
    np.testing.assert_array_equal(back.damping, m.damping)
    # without dofs=: every non-zero row, labelled with + signs, values sign-adjusted
    nonzero = {(d.node, d.axis) for d, row in zip(m.dofs, m.shapes) if np.any(row != 0)}
    assert {(d.node, d.axis) for d in plain.dofs} == nonzero and all(d.direction > 0 for d in plain.dofs)


@settings(**SETTINGS)
@given(geo=st.dictionaries(st.integers(1, 2 ** 31 - 1), st.tuples(finite, finite, finite), min_size=1,
                           max_size=20))
def test_geometry_round_trip(geo):
    d, p = _tmp()
    with d:
        uff.write_geometry(p, geo)
        back = uff.read_geometry(p)
    assert back == geo
