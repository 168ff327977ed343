"""Thesis section 5.2: the 20-DOF free-free tube beam updated by MCI minimisation (Tables 3 and 4).

Set-up (``updating.fe.models.beams.thesis_beam``: nine Euler–Bernoulli elements of 0.3 m, steel-like
nominal E = 210 GPa, ρ = 7850 kg/m³).  Pseudo-experimental receptances of
``thesis_beam('experimental', cord_stiffness=k)`` (Table 3 experimental diameters, Table 4 ratios,
grounded cords of k N/m on w at nodes 1 and 10), excitation at ``5+Z``, all 20 DOFs measured,
no noise, no damping, lines 1.25, 2.25, ... 120.25 rad/s.  Analytical model
``thesis_beam('analytical', cord_stiffness=None)``.

Parameters: a multiplier on E and one on ρ per element (18).  Why these: an Euler–Bernoulli
element's stiffness is ``EI·K̂(L)`` and its consistent mass ``ρA·M̂(L)`` (no rotary inertia, no
shear), so the E multiplier of element e is exactly its EI ratio and the ρ multiplier its ρA ratio —
the Table 3 diameter changes and the Table 4 material ratios together are represented exactly by
``p_E = r_E·I_x/I_a`` and ``p_ρ = r_ρ·A_x/A_a`` (:func:`true_multipliers`).  Poisson's ratio (Table 4,
third column) does not enter the beam, and diameters and material cannot be told apart (only EI and
ρA are observable), so anything beyond these 18 is unidentifiable.

What is achieved (asserted below with these tolerances):

* Without cords, updating frequencies 40–80 rad/s: the 18 multipliers are recovered to 1e-9
  (achieved ~1e-13) in 5 iterations and the final MCI is zero (< 1e-8) at every DOF.
* With cords, at the *true* multipliers the MCI is exactly zero (< 1e-9 relative) everywhere except
  at ``1+Z`` and ``10+Z`` — the Figure 34–35 pattern: element multipliers cannot represent a
  connection to ground, so the error stays at the corded coordinates only.
* With cords, MCI minimisation over 40–80 rad/s (what the least-squares minimiser actually does):
  with this beam the cords are *not* soft in the updating band (at 60 rad/s the 100 N/m cord is about
  80 % of the end node's inertia force ω²m, 1000 N/m eight times it; the pseudo-experimental cord modes
  sit at 13/31 rad/s and 17/65 rad/s, and the cords raise its first elastic mode from 43.9 rad/s
  free-free to 45.9 (10 N/m), 61.6 (100 N/m) and 122 rad/s (1000 N/m: ends nearly pinned)).  The least-squares solution therefore absorbs the cord error
  into the end elements: multipliers move by up to ~100 % from the truth (asserted: no convergence
  to the truth, max error > 30 %), the in-band MCI falls (100 N/m: largest per-DOF maximum
  5.9 → 0.85; 1000 N/m: 21.8 → 9.4) and the FRF misfit above 40 rad/s falls (median |log|H_A/H_X||
  1.13 → 0.76 and 1.66 → 1.30).  The thesis' "parameters converge to the element values" is reproduced
  only without cords (first bullet); we report the corded result as it is.
* Including the cord-dominated 0–20 rad/s band (updating lines 0–80 rad/s): the minimiser cannot
  fit its own equations — the largest final MCI over its updating lines stays at 7.6 (100 N/m,
  from 9.8) and 21.6 (1000 N/m, from 43.5) against 0.85 and 9.4 for the 40–80 rad/s fit (asserted:
  more than 2× larger, and a smaller reduction) — the thesis' observation that the algorithm then
  "seeks an analytical model connected to the ground".  Measured on the 40–80 rad/s lines only, the
  two fits are alike with this beam (0.85 vs 0.78, 9.4 vs 8.9), because here the cords already
  matter inside 40–80 rad/s (previous bullet); the thesis' contrast between the bands is therefore
  weaker than in its Figures 28–33.

* Where the thesis' behaviour does hold: with softer cords (1 and 10 N/m — 2 % and 20 % of the end
  node's inertia force ω²m at 40 rad/s) the 40–80 rad/s MCI minimisation converges (7 iterations), the
  multipliers come within 0.8 % and 8.2 % of the truth (asserted 1 % and 10 %), the FRF misfit above
  40 rad/s falls from ~0.5 to 0.004 and 0.046 (asserted 0.01 / 0.06), and the final MCI is left at the
  corded DOFs: ``1+Z`` and ``10+Z`` rank first and every other DOF's maximum is below 0.3× the smaller
  corded one (achieved 0.26, 0.29; asserted 0.35) — Figures 34–35.  So the thesis' picture needs cords
  that are soft against the beam in the updating band, which its 100/1000 N/m were on its (unknown)
  beam but are not on the one chosen in ``thesis_beam``.

Runtime about 10 s (iterations capped at 15 for the corded fits; the cost no longer changes by then).
BLAS threads are limited to one (set before numpy is first imported) as on this shared two-core
machine threaded small dense solves are many times slower.
"""
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from updating.fe import ParametricFEModel  # noqa: E402
from updating.methods.mci import MCIUpdater, mci  # noqa: E402
from updating.fe.models.beams import (THESIS_TABLE3_MM, THESIS_TABLE4_RATIOS, thesis_beam,  # noqa: E402
                                   thesis_beam_parameters)

OMEGA = np.arange(1, 121) + 0.25            # rad/s
BAND = (40.0, 80.0)                           # thesis' updating frequencies, rad/s
CORDED = ("1+Z", "10+Z")


def hz(band):
    return [(band[0] / (2 * np.pi), band[1] / (2 * np.pi))]


def true_multipliers():
    """EI and ρA ratios (experimental/analytical) per element: Table 3 diameters × Table 4 ratios."""
    pE, pr = [], []
    for (dox, dix), (doa, dia), (rE, rr, _) in zip(THESIS_TABLE3_MM["experimental"], THESIS_TABLE3_MM["analytical"],
                                                   THESIS_TABLE4_RATIOS):
        pE.append(rE * (dox ** 4 - dix ** 4) / (doa ** 4 - dia ** 4))
        pr.append(rr * (dox ** 2 - dix ** 2) / (doa ** 2 - dia ** 2))
    return np.array(pE + pr)


@pytest.fixture(scope="module")
def analytical():
    A = thesis_beam("analytical", cord_stiffness=None)
    return ParametricFEModel(A, thesis_beam_parameters(A))


def experiment(kc):
    X = thesis_beam("experimental", cord_stiffness=kc)
    return X.frf(OMEGA / (2 * np.pi), references=["5+Z"], quantity="receptance")


def misfit(pm, frf, p, lo=40.0):
    H = pm.model_at(p).frf(OMEGA / (2 * np.pi), references=["5+Z"], quantity="receptance").H
    sel = OMEGA >= lo
    return float(np.median(np.abs(np.log(np.abs(H[:, :, sel]) / np.abs(frf.H[:, :, sel])))))


@pytest.fixture(scope="module")
def corded_fits(analytical):
    out = {}
    for kc in (100.0, 1000.0):
        frf = experiment(kc)
        for band in (BAND, (0.0, 80.0)):
            u = MCIUpdater(bands=hz(band), max_iter=15, tol=1e-6).fit(analytical, frf)
            out[kc, band] = (u, frf)
    return out


class TestIdentifiability:
    def test_parameters_are_the_element_ei_and_rho_a(self, analytical):
        assert analytical.parameter_names == [f"E_e{i}" for i in range(1, 10)] + [f"rho_e{i}" for i in range(1, 10)]
        X = thesis_beam("experimental", cord_stiffness=None).structure()
        S = analytical.structure(true_multipliers())
        np.testing.assert_allclose(S.K.toarray(), X.K.toarray(), rtol=1e-12, atol=1e-9 * abs(X.K).max())
        np.testing.assert_allclose(S.M.toarray(), X.M.toarray(), rtol=1e-12, atol=1e-12 * abs(X.M).max())

    def test_no_cords_exact_recovery_in_40_80(self, analytical):
        frf = experiment(None)
        u = MCIUpdater(bands=hz(BAND), tol=1e-10).fit(analytical, frf)
        assert u.converged_ and u.n_iter_ <= 10
        np.testing.assert_allclose(u.p_, true_multipliers(), rtol=1e-9)
        assert u.mci_final_.max_per_dof().max() < 1e-8
        assert u.mci_initial_.max_per_dof().max() > 1.0


class TestCordedMCI:
    @pytest.mark.parametrize("kc", [100.0, 1000.0])
    def test_true_multipliers_leave_mci_only_at_corded_dofs(self, analytical, kc):
        r = mci(analytical, experiment(kc), true_multipliers())
        mx = r.max_per_dof()
        lab = [str(d) for d in r.dofs]
        cord = [lab.index(c) for c in CORDED]
        rest = np.setdiff1d(np.arange(mx.size), cord)
        assert mx[cord].min() > 1.0
        assert mx[rest].max() < 1e-9 * mx[cord].max()
        assert set(r.ranked_dofs()[:2]) == {d for d in r.dofs if str(d) in CORDED}

    @pytest.mark.parametrize("kc, mci_before, mci_after, fit_before, fit_after",
                             [(100.0, 5.5, 1.0, 1.0, 0.85), (1000.0, 20.0, 10.5, 1.5, 1.4)])
    def test_40_80_updating_reduces_mci_and_misfit(self, analytical, corded_fits, kc, mci_before, mci_after,
                                                   fit_before, fit_after):
        u, frf = corded_fits[kc, BAND]
        assert u.mci_initial_.max_per_dof().max() > mci_before
        assert u.mci_final_.max_per_dof().max() < mci_after
        assert misfit(analytical, frf, analytical.p0) > fit_before
        assert misfit(analytical, frf, u.p_) < fit_after
        # the cords are absorbed into the element multipliers: no convergence to the truth (honest result)
        assert np.abs(u.p_ / true_multipliers() - 1).max() > 0.3

    @pytest.mark.parametrize("kc, p_tol, fit_tol", [(1.0, 0.01, 0.01), (10.0, 0.10, 0.06)])
    def test_soft_cords_reproduce_figures_34_35(self, analytical, kc, p_tol, fit_tol):
        frf = experiment(kc)
        u = MCIUpdater(bands=hz(BAND), tol=1e-8).fit(analytical, frf)
        assert u.converged_
        np.testing.assert_allclose(u.p_, true_multipliers(), rtol=p_tol)
        assert misfit(analytical, frf, analytical.p0) > 0.4
        assert misfit(analytical, frf, u.p_) < fit_tol
        mx = u.mci_final_.max_per_dof()
        lab = [str(d) for d in u.mci_final_.dofs]
        cord = [lab.index(c) for c in CORDED]
        rest = np.setdiff1d(np.arange(mx.size), cord)
        assert {str(d) for d in u.mci_final_.ranked_dofs()[:2]} == set(CORDED)
        assert mx[rest].max() < 0.35 * mx[cord].min()

    @pytest.mark.parametrize("kc", [100.0, 1000.0])
    def test_including_low_band_fails_to_fit(self, corded_fits, kc):
        good, _ = corded_fits[kc, BAND]
        bad, _ = corded_fits[kc, (0.0, 80.0)]
        # over its own updating lines the 0-80 rad/s fit leaves a much larger MCI than the 40-80 one
        assert bad.mci_final_.max_per_dof().max() > 2 * good.mci_final_.max_per_dof().max()
        # and it removes less of the initial MCI
        red_good = good.mci_initial_.max_per_dof().max() / good.mci_final_.max_per_dof().max()
        red_bad = bad.mci_initial_.max_per_dof().max() / bad.mci_final_.max_per_dof().max()
        assert red_bad < red_good
