"""A test mode that merges close analysis modes is not paired (issue 14 #1).

Judged on an analytic model, not on the FE code: a simply supported rectangular plate of sides 1 and 1.02,
whose modes (m, n) and (n, m) are close (f_mn ∝ (m/a)² + (n/b)², shapes sin(mπx/a)·sin(nπy/b)), sampled at
a 3 x 4 grid of sensors.  Identification that sees one peak where (1, 2) and (2, 1) lie 2.5 % apart returns
one mode whose shape mixes the two: paired with either it would pull an updated model towards a wrong
frequency and a wrong shape.
"""
import numpy as np
import pytest

from modalab.core.modes import ModeSet
from updating.correlation.metrics import correlate, mac, pair_modes, shape_noise, span_mac

A_SIDE, B_SIDE = 1.0, 1.02
XS, YS = np.meshgrid(np.array([0.2, 0.45, 0.8]), np.array([0.15, 0.4, 0.6, 0.85]) * B_SIDE)
MN = [(1, 1), (1, 2), (2, 1), (2, 2), (1, 3), (3, 1), (2, 3), (3, 2)]
DOFS = [f"{k + 1}+Z" for k in range(XS.size)]


def plate():
    f = np.array([10.0 * ((m / A_SIDE) ** 2 + (n / B_SIDE) ** 2) for m, n in MN])
    phi = np.column_stack([(np.sin(m * np.pi * XS / A_SIDE) * np.sin(n * np.pi * YS / B_SIDE)).ravel()
                           for m, n in MN])
    o = np.argsort(f)
    return f[o], phi[:, o], [MN[k] for k in o]


def test_plate_has_a_close_pair():
    f, _, mn = plate()
    i, j = mn.index((1, 2)), mn.index((2, 1))
    assert 0.01 < abs(f[i] - f[j]) / f[i] < 0.03


def _test_set(merge: bool, seed=0):
    f, phi, mn = plate()
    i, j = mn.index((1, 2)), mn.index((2, 1))
    rng = np.random.default_rng(seed)
    keep = [k for k in range(len(f)) if k not in (i, j)]
    fx = list(f[keep] * 1.003)
    X = [phi[:, k] for k in keep]
    if merge:
        fx.append(0.5 * (f[i] + f[j]))
        X.append(0.8 * phi[:, i] + 0.6 * phi[:, j])
    else:
        fx += [f[i] * 1.003, f[j] * 1.003]
        X += [phi[:, i], phi[:, j]]
    X = np.column_stack(X) + 0.01 * rng.normal(size=(phi.shape[0], len(fx)))
    return f, phi, np.array(fx), X, (i, j)


def test_a_merged_test_mode_is_left_unpaired_with_its_reason():
    f, phi, fx, X, (i, j) = _test_set(merge=True)
    M = mac(phi, X)
    assert M[:, -1].max() >= 0.5                       # alone, the MAC floor would let it pair
    pr = pair_modes(M, f, fx, mode_shapes=(phi, X))
    merged = X.shape[1] - 1
    assert merged in pr.unpaired_test
    why = pr.unpaired_reason[merged]
    assert why.startswith("merged or ambiguous") and f"FE modes {i + 1} (" in why and f", {j + 1} (" in why
    assert len(pr.pairs) == X.shape[1] - 1             # every other mode keeps its partner
    # without the shapes the old rule pairs it: the check is what leaves it out
    assert merged in [x for _, x in pair_modes(M, f, fx).pairs]


def test_a_close_pair_identified_as_two_modes_stays_paired():
    f, phi, fx, X, (i, j) = _test_set(merge=False)
    pr = pair_modes(mac(phi, X), f, fx, mode_shapes=(phi, X))
    assert pr.unpaired_test == []
    assert {(i, X.shape[1] - 2), (j, X.shape[1] - 1)} <= set(pr.pairs)


def test_correlate_reports_the_merge():
    f, phi, fx, X, (i, j) = _test_set(merge=True)
    res = correlate(ModeSet(freq_hz=f, shapes=phi, dofs=DOFS), ModeSet(freq_hz=fx, shapes=X, dofs=DOFS))
    assert res.pairing.unpaired_test == [X.shape[1] - 1]
    assert "merged or ambiguous" in res.pairing.to_dict()["unpaired_reason"][str(X.shape[1])]


@pytest.mark.parametrize("seed", range(4))
def test_pairing_with_shapes_is_deterministic(seed):
    f, phi, fx, X, _ = _test_set(merge=bool(seed % 2), seed=seed)
    a = pair_modes(mac(phi, X), f, fx, mode_shapes=(phi, X))
    b = pair_modes(mac(phi, X), f, fx, mode_shapes=(phi, X))
    assert a.pairs == b.pairs and a.unpaired_reason == b.unpaired_reason


def test_span_mac_and_shape_noise():
    f, phi, _ = plate()
    x = phi[:, 1] + phi[:, 2]
    assert span_mac(x, phi[:, [1]]) == pytest.approx(mac(phi[:, [1]], x[:, None])[0, 0])
    assert span_mac(x, phi[:, [1, 2]]) == pytest.approx(1.0)
    # a real shape under any common phase has no noise; an out-of-phase part of 10 % reads as about 14 %
    rng = np.random.default_rng(1)
    assert shape_noise(np.exp(0.7j) * phi)[0] == pytest.approx(0.0, abs=1e-12)
    noisy = phi[:, :1] + 0.1 * np.linalg.norm(phi[:, 0]) / np.sqrt(phi.shape[0]) * (
        rng.normal(size=(phi.shape[0], 1)) + 1j * rng.normal(size=(phi.shape[0], 1)))
    assert 0.05 < shape_noise(noisy)[0] < 0.3


def test_a_close_pair_rotated_between_the_models_is_not_called_a_merge():
    """Two test modes where the model has two close modes, their shapes mixed differently (a rotation of the
    pair, as for a symmetric structure slightly detuned): not a merge, both keep a partner."""
    f, phi, mn = plate()
    i, j = mn.index((1, 2)), mn.index((2, 1))
    c, s = np.cos(0.5), np.sin(0.5)
    keep = [k for k in range(len(f)) if k not in (i, j)]
    fx = np.array(list(f[keep]) + [f[i] * 1.002, f[i] * 1.004])
    X = np.column_stack([phi[:, k] for k in keep] + [c * phi[:, i] + s * phi[:, j], -s * phi[:, i] + c * phi[:, j]])
    pr = pair_modes(mac(phi, X), f, fx, mode_shapes=(phi, X))
    assert not any(r.startswith("merged") for r in pr.unpaired_reason.values())
    assert {x for _, x in pr.pairs} >= set(range(len(keep)))
