"""Ritz-basis receptance (fast FRF fits of large models) and the exact single-candidate FRF screening."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from modalab.core.frf import FRF
from updating.correlation.condensation import solve_columns
from updating.diagnosis.fit import fit_frf, frf_data, frf_error, model_frf
from updating.diagnosis.frfscreen import frf_screen
from updating.diagnosis.library import build_library
from updating.diagnosis.ritz import RitzBasis
from updating.fe import Damper, Parameter, ParametricFEModel, Spring
from updating.fe.models.beams import thesis_beam
from updating.fe.models.garteur import garteur_model


@pytest.fixture(scope="module")
def frame():
    m = garteur_model(suspension=True)
    m.global_ge = 0.02
    m._changed()
    return m


def _rows(st_, n=24, seed=0, axes=(2, 3)):
    """Z and Y DOFs of some nodes (the directions a test measures; in-plane X of a free frame is ~0)."""
    cand = [i for i, d in enumerate(st_.dofs) if d.axis in axes]
    rng = np.random.default_rng(seed)
    return np.sort(rng.choice(cand, n, replace=False))


@pytest.mark.parametrize("local_damper", [False, True])
def test_ritz_receptance_matches_the_full_solve(frame, local_damper):
    m = frame.copy()
    if local_damper:             # non-proportional damping: the dense path of the reduced solve
        m.add_element(Damper(99002, (204, 3), None, 50.0))
        m._changed()
    st_ = m.structure()
    assert st_.n_dof > 300
    rows = _rows(st_)
    refs = rows[:3]
    s = 2j * np.pi * np.linspace(1.0, 100.0, 120)
    rb = RitzBasis(st_, np.r_[rows, refs], 100.0)
    assert rb.size < st_.n_dof / 4
    H, _ = rb.responses(st_, s, rows, refs)
    X = solve_columns(st_.K, st_.M, st_.C, st_.D, s, refs)[rows]
    # relative to each reference's response level (structurally zero cross terms, e.g. Y to a Z force on the
    # symmetric frame, are numerical noise in both)
    scale = np.sqrt(np.mean(np.abs(X) ** 2, axis=(0, 2), keepdims=True))
    err = np.abs(H - X) / (np.abs(X) + 0.01 * scale)
    assert np.median(err) < 1e-4 and err.max() < 2e-2


def test_ritz_jacobian_matches_finite_differences(frame):
    pm = ParametricFEModel(frame, [Parameter("E_wing", "E", properties=("wing",)),
                                   Parameter("rho_fin", "rho", properties=("fin",))])
    st0 = pm.structure(pm.p0)
    rows = _rows(st0, 10, seed=1)
    refs = rows[:2]
    s = 2j * np.pi * np.linspace(3.0, 80.0, 40)
    rb = RitzBasis(st0, np.r_[rows, refs], 80.0)
    H0, ctx = rb.responses(st0, s, rows, refs)
    ders = pm.derivatives(pm.p0)
    for k in range(2):
        h = 1e-6
        p = np.array(pm.p0, float)
        p[k] += h
        H1, _ = rb.responses(pm.structure(p), s, rows, refs)
        fd = (H1 - H0) / h
        an = RitzBasis.jacobian(ctx, ders[k], s)
        assert np.linalg.norm(an - fd) < 1e-3 * np.linalg.norm(fd)


def _wing_modulus_case(frame):
    """The frame's wing modulus as the one parameter, and noise-free receptances of the frame with it at 1.06
    (12 Z responses, 2 references, 2-90 Hz): ``(pm, data)``."""
    pm = ParametricFEModel(frame, [Parameter("E_wing", "E", properties=("wing",))])
    st_t = ParametricFEModel(frame.copy(), [Parameter("E_wing", "E", properties=("wing",))]).structure([1.06])
    labels = [str(st_t.dofs[i]) for i in _rows(st_t, 12, seed=2, axes=(3,))]
    f = np.linspace(2.0, 90.0, 300)
    H = st_t.frf(f, labels, labels[:2], quantity="receptance")
    meas = FRF(freq_hz=f, H=H.H, responses=H.responses, references=H.references,
               coherence=np.ones(H.H.shape), quantity="receptance")
    return pm, frf_data(meas, max_lines=100)


def test_reduced_fit_recovers_the_parameter_and_reports_the_exact_error(frame):
    pm, data = _wing_modulus_case(frame)
    res = fit_frf(pm, data, [1.0], lower=[0.5], upper=[2.0], reduced=True)
    assert "Ritz" in res.message
    assert res.p[0] == pytest.approx(1.06, rel=2e-3)
    assert res.error == pytest.approx(frf_error(model_frf(pm.structure(res.p), data), data), rel=1e-12)
    assert res.error < 1e-2


# --------------------------------------------------------------------------- FRF screening (exact path)
def _beam_case(k_true, node, noise=0.0):
    nominal = thesis_beam()
    nominal.global_ge = 0.01                     # lightly damped, as measured structures are
    nominal._changed()
    truth = nominal.copy()
    truth.add_element(Spring(99001, (node, 3), None, k_true))
    truth._changed()
    labels = [str(d) for d in nominal.structure().dofs if d.axis == 3]
    f = np.linspace(0.5, 60.0, 240)
    H = truth.frf(f, labels, [labels[2]], quantity="receptance")
    rng = np.random.default_rng(3)
    Hn = H.H * (1 + noise * rng.standard_normal(H.H.shape))
    meas = FRF(freq_hz=f, H=Hn, responses=H.responses, references=H.references,
               coherence=np.ones(H.H.shape), quantity="receptance")
    return nominal, frf_data(meas, max_lines=120)


@settings(max_examples=6, deadline=None)
@given(k=st.floats(min_value=50.0, max_value=5000.0), node=st.sampled_from([1, 4, 7, 10]))
def test_frf_screen_names_and_sizes_an_omitted_spring_exactly(k, node):
    nominal, data = _beam_case(k, node)
    lib = build_library(nominal, kinds=("ground_spring", "added_mass"))
    ranked = frf_screen(nominal.structure(), lib, data, loss_factor=nominal.global_ge)
    c, value, gain = ranked[0]
    assert c.physics == "ground_spring" and c.nodes == (node,) and c.dofs == (f"{node}+Z",)
    assert value == pytest.approx(k, rel=1e-2)              # fine grid, refined, polished by Brent
    assert gain > 0.97


def test_frf_screen_finds_nothing_to_gain_on_a_correct_model():
    nominal, data = _beam_case(0.0, 4)
    lib = build_library(nominal, kinds=("ground_spring", "added_mass"))
    ranked = frf_screen(nominal.structure(), lib, data)
    assert all(g < 1e-3 for _, _, g in ranked)


def test_added_mass_candidates_are_bounded_by_a_plausible_size():
    m = garteur_model(suspension=True)
    lib = build_library(m, kinds=("added_mass",))
    st_ = m.structure()
    u = np.array([1.0 if d.axis == 3 else 0.0 for d in st_.dofs])
    total = float(u @ (st_.M @ u))
    masses = [c for c in lib if c.value_name == "m"]
    assert masses and all(c.upper == pytest.approx(0.5 * total) for c in masses)
    assert 30.0 < total < 60.0                              # the GARTEUR test bed is about 44 kg


def test_ritz_basis_of_a_larger_model_uses_lanczos_and_stays_accurate():
    import modalab.core.dense as dense
    m = garteur_model(16, suspension=True)
    m.global_ge = 0.02
    m._changed()
    st_ = m.structure()
    assert st_.n_dof > dense.MODES_LIMIT
    rows = _rows(st_, 20, seed=4)
    refs = rows[:2]
    s = 2j * np.pi * np.linspace(1.0, 100.0, 60)
    rb = RitzBasis(st_, np.r_[rows, refs], 100.0)
    w = np.sqrt(np.linalg.eigvalsh(rb.V.T @ (st_.K @ rb.V)).clip(0)) / (2 * np.pi)
    assert rb.n_modes >= 12 and np.sort(w)[rb.n_modes - 1] > 100.0       # modes reach past the band
    H, _ = rb.responses(st_, s, rows, refs)
    X = solve_columns(st_.K, st_.M, st_.C, st_.D, s, refs)[rows]
    scale = np.sqrt(np.mean(np.abs(X) ** 2, axis=(0, 2), keepdims=True))
    err = np.abs(H - X) / (np.abs(X) + 0.01 * scale)
    assert np.median(err) < 1e-4 and err.max() < 2e-2


def test_reduced_fit_keeps_its_start_when_the_basis_leads_every_step_astray(frame, monkeypatch):
    """The guard of :func:`fit_frf`: a Ritz basis too poor for the band (modes to 0.3x its top only) moves the
    reduced optimum off the truth; started at the truth on noise-free data, every round raises the exact error,
    so the start is returned, with its exact error and finite standard deviation, and the message says so."""
    import updating.diagnosis.ritz as ritzmod          # where the fit builds each round's basis (round_basis)

    class PoorBasis(RitzBasis):
        def __init__(self, structure, cols, f_max_hz, **kw):
            super().__init__(structure, cols, f_max_hz, mode_factor=0.3, min_modes=2)

    pm, data = _wing_modulus_case(frame)
    start_error = frf_error(model_frf(pm.structure([1.06]), data), data)

    # the same basis class, configured too poor for the band: the reduced model is wrong, not faked
    monkeypatch.setattr(ritzmod, "RitzBasis", PoorBasis)
    res = fit_frf(pm, data, [1.06], lower=[0.5], upper=[2.0], reduced=True)
    assert "start kept" in res.message
    assert res.p[0] == 1.06
    assert res.error == pytest.approx(start_error, rel=1e-12)
    assert np.isfinite(res.std[0]) and res.std[0] > 0

    # with the basis as configured in the library the same fit moves nowhere worse either, and says nothing of it
    monkeypatch.undo()
    good = fit_frf(pm, data, [1.0], lower=[0.5], upper=[2.0], reduced=True)
    assert "start kept" not in good.message and good.p[0] == pytest.approx(1.06, rel=2e-3)


@settings(max_examples=40, deadline=None)
@given(st.integers(2, 12), st.floats(1e-4, 0.1), st.integers(0, 2 ** 31 - 1), st.booleans())
def test_hysteretic_resolvent_from_one_eigendecomposition_equals_a_solve_per_line(m, eta, seed, repeated):
    """``(diag(ω²) + i Dq + s² I)⁻¹ rhs`` by :func:`_hysteretic_solve` (one eigen-decomposition) is the solve
    at every line, for symmetric loss matrices of any pattern, repeated ω² (a symmetric frame's pairs) included;
    where the eigenvectors are too ill-conditioned it declines (None) rather than return a worse answer."""
    from updating.diagnosis.ritz import _hysteretic_solve
    rng = np.random.default_rng(seed)
    w2 = np.sort(rng.uniform(1.0, 1e4, m)) * (2 * np.pi) ** 2
    if repeated:
        w2[1] = w2[0]
    R = rng.standard_normal((m, m))
    Dq = eta * (np.diag(w2) + 0.3 * np.sqrt(np.outer(w2, w2)) * (R + R.T) / 2)
    s = 2j * np.pi * np.linspace(0.5, 1.2 * np.sqrt(w2.max()) / (2 * np.pi), 50)
    rhs = rng.standard_normal((m, 3))
    Y = _hysteretic_solve(w2, Dq, s, rhs)
    Z = np.diag(w2)[None] + 1j * Dq[None] + (s ** 2)[:, None, None] * np.eye(m)[None]
    want = np.linalg.solve(Z, np.broadcast_to(rhs, (s.size, m, 3))).transpose(1, 2, 0)
    assert Y is not None or repeated            # distinct ω² and a small loss: W is well conditioned
    if Y is not None:                           # every line to 1e-9 of its own largest response
        err = np.abs(Y - want).max(axis=(0, 1)) / np.abs(want).max(axis=(0, 1))
        assert err.max() < 1e-9


def test_a_model_between_100_and_200_dofs_is_fitted_in_a_basis_to_the_exact_fits_answer():
    """RITZ_LIMIT (100 DOFs) decides the FRF fits' numerics: a 138-DOF frame takes the Ritz basis by
    default and lands where the exact fit lands, with the exact error reported."""
    from updating.diagnosis.fit import RITZ_LIMIT
    small = garteur_model(2, suspension=True)
    small.global_ge = 0.02
    small._changed()
    assert RITZ_LIMIT < small.structure().n_dof <= 200
    pm, data = _wing_modulus_case(small)
    auto = fit_frf(pm, data, [1.0], lower=[0.5], upper=[2.0])
    exact = fit_frf(pm, data, [1.0], lower=[0.5], upper=[2.0], reduced=False)
    assert "Ritz" in auto.message and "Ritz" not in exact.message
    assert auto.p[0] == pytest.approx(1.06, rel=2e-3)
    assert auto.p[0] == pytest.approx(exact.p[0], rel=1e-3)
    assert auto.error == pytest.approx(frf_error(model_frf(pm.structure(auto.p), data), data), rel=1e-12)


def test_reduced_fit_stops_when_a_rebuilt_basis_leaves_the_exact_error_where_it_was(frame, monkeypatch, caplog):
    """A basis whose reduced model keeps a bias (modes to 0.3x the band's top) never brings the reduced and exact
    errors within ``tol``; rebuilding it at the new parameters moved the exact error by less than ``tol``, so
    a third round would only repeat the second: the fit stops after two rounds (it ran all three before), and
    its result is still the best round's."""
    import logging
    import updating.diagnosis.ritz as ritzmod

    class PoorBasis(RitzBasis):
        def __init__(self, structure, cols, f_max_hz, **kw):
            super().__init__(structure, cols, f_max_hz, mode_factor=0.3, min_modes=2)

    pm, data = _wing_modulus_case(frame)
    monkeypatch.setattr(ritzmod, "RitzBasis", PoorBasis)
    with caplog.at_level(logging.DEBUG, logger="updating.diagnosis.fit"):
        res = fit_frf(pm, data, [1.0], lower=[0.5], upper=[2.0], reduced=True, rounds=3, tol=0.01)
    rounds = [r.args for r in caplog.records if r.msg.startswith("Ritz fit round")]
    assert len(rounds) == 2
    (_, red0, ex0), (_, red1, ex1) = rounds
    assert abs(ex0 - red0) > 0.01 * ex0 and abs(ex1 - red1) > 0.01 * ex1       # the bias stays
    assert abs(ex1 - ex0) <= 0.01 * ex1                                        # the exact error does not move
    assert res.error == pytest.approx(min(ex0, ex1, frf_error(model_frf(pm.structure([1.0]), data), data)),
                                      rel=1e-9)


def test_a_fit_continued_from_another_takes_its_exact_error_and_lands_where_it_would_have(frame, monkeypatch):
    """``err_start`` (the error a continued fit's start already has, as ``_fit_converged`` passes it): the same
    result bit for bit as computing it again, with one exact receptance fewer."""
    import updating.diagnosis.fit as fitmod

    pm, data = _wing_modulus_case(frame)
    short = fit_frf(pm, data, [1.0], lower=[0.5], upper=[2.0], reduced=True, max_nfev=2)
    calls = []
    real = fitmod.model_frf
    monkeypatch.setattr(fitmod, "model_frf", lambda *a, **k: calls.append(1) or real(*a, **k))
    again = fit_frf(pm, data, short.p, lower=[0.5], upper=[2.0], reduced=True)
    n_again = len(calls)
    taken = fit_frf(pm, data, short.p, lower=[0.5], upper=[2.0], reduced=True, err_start=short.error)
    assert len(calls) - n_again == n_again - 1
    assert taken.p.tobytes() == again.p.tobytes() and taken.std.tobytes() == again.std.tobytes()
    assert taken.error == again.error
    assert short.error == frf_error(real(pm.structure(short.p), data), data)      # what err_start stands for
