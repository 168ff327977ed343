"""An exact model stays exact (issue 14 #1-#2): test data made from the nominal model itself leave the
parameters at nominal for every modal method that ``modalab update`` offers, also when the test set holds a
spurious mode (the issue's 311 Hz mode whose best MAC, 0.58, is with a 70 Hz FE mode) and a mode the model
does not have.  The noise is drawn with fixed seeds (deterministic)."""
import numpy as np
import pytest

from modalab.core.modes import ModeSet
from updating.correlation.metrics import correlate


@pytest.fixture(scope="module")
def nominal():
    from updating.fe import ParametricFEModel
    from updating.fe.models.garteur import garteur_model, garteur_parameters

    m = garteur_model(mesh=4)
    pm = ParametricFEModel(m, garteur_parameters(m))
    ms = m.modes(24)
    el = np.flatnonzero(ms.freq_hz > 1.0)[:10]
    dofs = [d for d in pm.dofs if d.axis == 3 and d.node % 2 == 0][:30]
    return m, pm, ms.select_dofs(dofs).select_modes(el)


#: the elastic mode the test misses; a spurious test mode carries its shape (plus noise) at 4.5x its frequency,
#: like the issue's 311 Hz test mode whose best MAC was with the 69.6 Hz FE mode
MISSED = 5


def noisy(test, seed, f_noise=1e-4, s_noise=0.01, spurious=True):
    rng = np.random.default_rng(seed)
    keep = [k for k in range(test.n_modes) if k != MISSED] if spurious else list(range(test.n_modes))
    f = test.freq_hz[keep] * (1 + f_noise * rng.normal(size=len(keep)))
    X = test.shapes[:, keep] + s_noise * np.abs(test.shapes[:, keep]).max(axis=0) * \
        rng.normal(size=(test.n_dof, len(keep)))
    if spurious:
        x0 = test.shapes[:, MISSED]
        # a sign of its own (positive at the first DOF above 10 % of the largest): the solver's sign convention
        # is arbitrary for a mode with two equal largest components (a symmetric structure), and x0 + noise
        # would otherwise change with rounding
        x0 = x0 * np.sign(x0[np.flatnonzero(np.abs(x0) >= 0.1 * np.abs(x0).max())[0]])
        x = x0 + 0.5 * np.abs(x0).max() * rng.normal(size=test.n_dof)
        f = np.r_[f, 4.5 * test.freq_hz[MISSED]]
        X = np.column_stack([X, x])
    return ModeSet(freq_hz=f, shapes=X, dofs=test.dofs, scaling=test.scaling)


@pytest.mark.parametrize("seed", [0, 1])
def test_inverse_eigensensitivity_stays_at_nominal(nominal, seed):
    from updating.methods.eigensensitivity import InverseEigensensitivity

    _, pm, test = nominal
    t = noisy(test, seed)
    r = correlate(pm.model_at(pm.p0).modes(30, full=True), t)
    assert t.n_modes - 1 in r.pairing.unpaired_test           # the spurious mode stays out
    up = InverseEigensensitivity(freq_sigma=1e-4, shape_sigma=0.01).fit(pm, t)
    assert up.unpaired_test_ == [t.n_modes - 1]
    z = (up.p_ - pm.p0) / up.std_
    assert np.all(np.abs(z) < 4), (up.p_, up.std_)
    assert np.all(np.abs(up.p_ - 1) < 5e-3)
    assert up.identifiable_ and np.isfinite(up.condition_)


def test_mac_only_pairing_would_have_moved_the_exact_model(nominal):
    """The same data paired by MAC alone (the old rule) pair the spurious mode and move the parameters."""
    from updating.methods.eigensensitivity import InverseEigensensitivity

    _, pm, test = nominal
    t = noisy(test, 2)              # a draw whose spurious shape MAC alone pairs (about half of the draws do)
    up = InverseEigensensitivity(freq_sigma=1e-4, shape_sigma=0.01,
                                 pairing={"max_freq_error": None, "freq_weight": 0.0}).fit(pm, t)
    assert t.n_modes - 1 in [x for _, x in up.initial_pairs_]
    assert np.max(np.abs(up.p_ - 1)) > 0.02


def test_eigendynamic_stays_at_nominal(nominal):
    from updating.methods.eigendynamic import EigendynamicConstraint

    _, pm, test = nominal
    t = noisy(test, 0, f_noise=0.0, s_noise=0.0)
    up = EigendynamicConstraint().fit(pm, t)
    assert up.pairing_.unpaired_test == [t.n_modes - 1]
    np.testing.assert_allclose(up.p_, pm.p0, atol=1e-6)


def test_frequency_only_set_stays_at_nominal_with_its_covariance(nominal):
    """Frequencies only (no shapes), correlated repeats: parameters at nominal within 4 sigma of the
    propagated covariance, and the covariance of the mean is used (not a fixed 1 %)."""
    from updating.methods.eigensensitivity import InverseEigensensitivity

    _, pm, test = nominal
    rng = np.random.default_rng(5)
    n = test.n_modes
    corr = 0.8 * np.ones((n, n)) + 0.2 * np.eye(n)
    sd = 1e-3 * test.freq_hz
    reps = test.freq_hz + rng.multivariate_normal(np.zeros(n), corr * np.outer(sd, sd), size=100)
    fo = ModeSet.from_repeats(reps)
    up = InverseEigensensitivity(use_shapes=True).fit(pm, fo)      # no shapes: frequencies only, said in the log
    z = (up.p_ - pm.p0) / up.std_unregularised_
    assert np.all(np.abs(z) < 4)
    # the std reflects the covariance of the mean (~1e-4 relative), not the 1 % default
    assert np.all(up.std_unregularised_ < 0.02)


def test_frequencies_alone_cannot_move_e_and_rho_of_one_material(tmp_path):
    """Issue 16 #14: frequencies scale with sqrt(E/rho), so E and rho of one material (``modalab update``'s
    default parameters) are not identifiable from frequencies alone: S has a null direction, resolved only to
    round-off (condition ~1e10).  The Gauss-Newton step must not divide by that round-off: data from the nominal
    itself leave both at nominal (they walked to ~1e7 x nominal, 'did not converge'), with infinite
    unregularised std and the not-identifiable verdict."""
    from updating.diagnosis.priors import default_parameters
    from updating.fe.bulk import build_model, read_bdf
    from updating.fe.parameters import ParametricFEModel
    from updating.methods.eigensensitivity import InverseEigensensitivity

    lines = ["SOL 103", "CEND", "BEGIN BULK", "MAT1,1,7.e10,,.33,2700.", "PBARL,1,1,,BAR", "+,.01,.04"]
    lines += [f"GRID,{i + 1},,{0.1 * i:.3f},0.,0." for i in range(21)]
    lines += [f"CBAR,{i + 1},1,{i + 1},{i + 2},0.,1.,0." for i in range(20)]
    (tmp_path / "beam.bdf").write_text("\n".join(lines + ["ENDDATA", ""]))
    model = build_model(read_bdf(tmp_path / "beam.bdf"))
    pm = ParametricFEModel(model, default_parameters(model))
    assert len(pm.p0) == 2
    ms = pm.model_at(pm.p0).modes(16)
    f = ms.freq_hz[ms.freq_hz > 1.0][:4]
    up = InverseEigensensitivity().fit(pm, ModeSet(freq_hz=f, shapes=np.zeros((0, 4)), dofs=[]))
    assert np.all(np.abs(up.p_ - pm.p0) < 1e-6), up.p_
    assert up.converged_
    assert not up.identifiable_ and up.condition_ > 1e3
    assert np.all(np.isinf(up.std_unregularised_))
