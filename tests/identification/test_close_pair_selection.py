"""Automatic selection of a close pair that the lower model orders merge into one pole (issue 16 item 2).

Hand-built diagrams (poles per order, through :func:`stabilise`): a pair 0.3 % apart with parallel
participation vectors (only one pole per order up to order 32, two from 33 on), a mode with lightly
damped noise poles wandering beside it, and a pair whose second pole is only emerging (unstable) at the
top orders.  The end-to-end case from FRFs is ``test_roving_plate_cli``.
"""
import numpy as np

from identification import SelectionOptions, auto_select, stabilise
from identification.selection import unresolved_modes


def _pole(f, z):
    w = 2 * np.pi * f
    return -z * w + 1j * w * np.sqrt(1 - z ** 2)


def _diagram(*, resolved_from=33, companion_stable=True, seed=0):
    rng = np.random.default_rng(seed)
    orders = np.arange(1, 41)
    poles, parts = [], []
    for n in orders:
        lam, L = [], []
        jit = 1 + 2e-5 * rng.standard_normal(8)
        if n >= 5:                                                       # a clean mode at 50 Hz
            lam.append(_pole(50.0 * jit[0], 0.010))
            L.append([1.0, 0.5, 0.2])
        if 10 <= n < resolved_from:                                      # the pair, merged
            lam.append(_pole(100.15 * jit[1], 0.006))
            L.append([1.0, -1.0, 0.0])
        elif n >= resolved_from:
            lam.append(_pole(100.0 * jit[2], 0.005))
            L.append([1.0, -1.0, 0.0])
            if companion_stable:
                lam.append(_pole(100.3 * jit[3], 0.005))
            else:                                                        # emerging: damping still settling
                lam.append(_pole(100.3 * jit[3], 0.012 - 0.0006 * (n - resolved_from) + 0.001 * (n % 2)))
            L.append([1.0, -1.0, 0.0])
        if n >= 8:                                                       # a mode at 150 Hz ...
            lam.append(_pole(150.0 * jit[4], 0.008))
            L.append([0.3, 1.0, 0.7])
        if n >= 30:                                                      # ... and noise poles wandering beside it
            lam.append(_pole(150.0 + 0.6 * np.sin(1.7 * n), 0.02 + 0.004 * np.cos(n)))
            L.append(list(rng.standard_normal(3)))
        poles.append(np.array(lam))
        parts.append(np.array(L, complex).reshape(-1, 3).T)
    return stabilise(orders, poles, parts)


def test_a_pair_resolved_only_at_the_upper_orders_is_two_modes():
    d = _diagram()
    sel = auto_select(d, band_hz=(1.0, 200.0))
    np.testing.assert_allclose(sel.freq_hz, [50.0, 100.0, 100.3, 150.0], rtol=1e-4)
    np.testing.assert_allclose(sel.damping, [0.010, 0.005, 0.005, 0.008], rtol=1e-3)
    # the pair's estimates come from the resolved orders only (not the merged pole below)
    assert sel.order[1] >= 33 and sel.order[2] >= 33
    assert unresolved_modes(d, sel).size == 0


def test_a_pair_resolved_at_too_few_orders_stays_one_mode():
    # two poles at the last 3 orders only (< min_poles): not enough to call it two modes
    d = _diagram(resolved_from=38)
    sel = auto_select(d, band_hz=(1.0, 200.0))
    assert np.sum(np.abs(sel.freq_hz - 100.15) < 0.5) == 1


def test_an_emerging_second_pole_flags_the_mode_as_unresolved():
    d = _diagram(companion_stable=False)
    sel = auto_select(d, band_hz=(1.0, 200.0))
    k = np.flatnonzero(np.abs(sel.freq_hz - 100.1) < 0.3)
    assert k.size >= 1
    # the merged mode is flagged; the 150 Hz mode with its wandering, more damped noise poles is not
    assert unresolved_modes(d, sel).tolist() == k[:1].tolist()
    opts = SelectionOptions()
    assert not np.any(np.abs(sel.freq_hz[unresolved_modes(d, sel, opts)] - 150.0) < 1.0)
