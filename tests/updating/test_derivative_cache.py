"""The cache of exact parameter derivatives (updating.methods.mci_condensed.derivatives): on a model whose
parameters enter the matrices linearly it returns, at every point, what the complex-step assembly returns there,
with the damping values and the linear parameters moved between calls; a model with a non-linear parameter (a
section dimension, or two parameters that scale the same elements' E) is assembled directly at every call."""
import dataclasses

import numpy as np
import scipy.sparse as sp
from hypothesis import given, settings, strategies as st

import updating.methods.mci_condensed as mc
from updating.diagnosis.priors import _GroupLossFactorTotal
from updating.fe import Beam3D, Parameter, ParametricFEModel, Timoshenko3D
from updating.methods.mci_condensed import derivatives

from tests.updating.test_fe_parameters import PARAMS, build

#: linear fields and damping values: what the cache's affine forms may move
MOVING_FIELDS = ("E", "rho", "k", "c", "mass", "inertia", "nsm", "ge", "global_ge", "rayleigh_alpha",
                 "rayleigh_beta")
#: the frame's parameters of linear fields and damping values (no section dimension): the cache is used
LINEAR = [par for par in PARAMS if par.field in MOVING_FIELDS]
PM = ParametricFEModel(build(Beam3D), LINEAR)
#: the frame's parameters plus the E of material 1 beside the E of its property "plate" (the same elements)
OVERLAP = PARAMS + [Parameter("E_mat1", "E", materials=[1])]
PM_OVERLAP = ParametricFEModel(build(Beam3D), OVERLAP)
MOVING = list(range(len(LINEAR)))
DAMPING = [i for i, par in enumerate(LINEAR) if par.mode == "value" and par.field in ("ge", "global_ge",
                                                                                   "rayleigh_alpha")]


def same(a, b) -> float:
    """Largest |a − b| relative to the largest entry of the two (sparse or None)."""
    if a is None and b is None:
        return 0.0
    a = sp.csr_matrix(b.shape) if a is None else a
    b = sp.csr_matrix(a.shape) if b is None else b
    return abs(a - b).max() / max(abs(a).max(), abs(b).max(), 1e-300)


@settings(max_examples=15, deadline=None)
@given(st.lists(st.lists(st.floats(0.5, 2.0), min_size=len(MOVING), max_size=len(MOVING)), min_size=2, max_size=4))
def test_cached_derivatives_equal_the_assembled_ones(points):
    for factors in points:
        p = PM.p0 * np.asarray(factors)
        p[DAMPING] += 0.01
        got, want = derivatives(PM, p), PM.derivatives(p)
        assert mc._DERIV_CACHE[PM].ok and mc._DERIV_CACHE[PM].damping is not None   # the affine forms answered
        for par, g, w in zip(LINEAR, got, want):
            for k in ("dK", "dM", "dC", "dD"):
                assert same(getattr(g, k), getattr(w, k)) < 1e-9, (par.name, k)


@settings(max_examples=5, deadline=None)
@given(st.lists(st.floats(0.95, 1.05), min_size=len(OVERLAP), max_size=len(OVERLAP)))
def test_a_model_with_a_non_linear_parameter_is_assembled_directly(factors):
    """A section dimension (here the plate's thickness, I ∝ t³) moves at every step of a fit, and the affine forms
    depend on it: the derivatives are the direct assembly's, to the bit, and no form is built (it cost 2 + n_a
    evaluations of every derivative per step: 5 500 evaluations for 583 calls in the quick demo's diagnosis)."""
    p = PM_OVERLAP.p0 * np.asarray(factors)
    got, want = derivatives(PM_OVERLAP, p), PM_OVERLAP.derivatives(p)
    assert PM_OVERLAP not in mc._DERIV_CACHE
    for par, g, w in zip(OVERLAP, got, want):
        for k in ("dK", "dM", "dC", "dD"):
            a, b = getattr(g, k), getattr(w, k)
            assert (a is None) == (b is None), (par.name, k)
            if a is not None:
                assert np.array_equal(a.toarray(), b.toarray()), (par.name, k)


def test_a_moved_overlapping_factor_changes_the_other_ones_derivative():
    """E of material 1 and E of the property "plate" multiply on the plate's elements: ∂K/∂E_mat1 there scales
    with E_plate, so the two are not cached as constants (they were, before: the first value stayed)."""
    p = PM_OVERLAP.p0.copy()
    derivatives(PM_OVERLAP, p)
    i, j = OVERLAP.index(OVERLAP[-1]), [par.name for par in OVERLAP].index("E_plate")
    p[j] = 1.5
    got, want = derivatives(PM_OVERLAP, p)[i].dK, PM_OVERLAP.derivatives(p)[i].dK
    assert same(got, want) < 1e-9
    assert same(PM_OVERLAP.derivatives(PM_OVERLAP.p0)[i].dK, want) > 0.01


@settings(max_examples=10, deadline=None)
@given(st.lists(st.floats(0.5, 2.0), min_size=len(MOVING), max_size=len(MOVING)),
       st.lists(st.floats(0.5, 2.0), min_size=len(MOVING), max_size=len(MOVING)))
def test_the_derivatives_at_a_point_do_not_depend_on_where_the_model_was_evaluated_before(before, at):
    """Bit for bit: a fit must not depend on the history of its model object (a copy of it in a worker process,
    modalab.core.parallel, starts with an empty cache).  Before, the first call for a key returned the direct
    assembly and later calls the affine form built at the first point, equal only to round-off."""
    pm_used, pm_fresh = (ParametricFEModel(build(Beam3D), LINEAR) for _ in range(2))

    def point(factors):
        p = pm_used.p0 * np.asarray(factors)
        p[DAMPING] += 0.01 * np.asarray(factors)[:len(DAMPING)]
        return p
    derivatives(pm_used, point(before))
    got, want = derivatives(pm_used, point(at)), derivatives(pm_fresh, point(at))
    assert pm_used in mc._DERIV_CACHE and mc._DERIV_CACHE[pm_used].ok
    for par, g, w in zip(LINEAR, got, want):
        for k in ("dK", "dM", "dC", "dD"):
            a, b = getattr(g, k), getattr(w, k)
            assert (a is None) == (b is None), (par.name, k)
            if a is not None:
                assert np.array_equal(sp.csr_matrix(a).toarray(), sp.csr_matrix(b).toarray()), (par.name, k)


def _timoshenko(shear_modulus=None):
    """The frame of shear-deformable beams, steel for material 1, with the E of two properties and a loss factor."""
    m = build(Timoshenko3D)
    m.materials[1] = dataclasses.replace(m.materials[1], E=2.1e11, nu=0.3, G=shear_modulus)
    pars = [Parameter("E_general", "E", properties=["general"]), Parameter("E_plate", "E", properties=["plate"]),
            Parameter("ge_general", "ge", properties=["general"], mode="value")]
    return ParametricFEModel(m, pars)


@settings(max_examples=10, deadline=None)
@given(st.lists(st.floats(0.8, 1.25), min_size=2, max_size=2), st.floats(0.0, 0.05))
def test_a_shear_deformable_beams_E_leaves_its_mass_alone_where_G_follows_from_nu(factors, ge):
    """G = E/(2(1+ν)): the shear parameter φ = 12 E I/(κ G A L²) does not depend on E, so ∂M/∂E is zero and the
    derivatives are cached.  Before, φ was computed from the complex-step E and G, whose ratio carries E's round-off
    in its imaginary part: a ∂M/∂E of relative size 1e-16 (at (1, 1) and most other points) that failed the cache's
    affine check, and every derivative of every fit on a frame of such beams was assembled anew at every step (a
    third of a space frame's diagnosis)."""
    pm = _timoshenko()
    p = np.array([*factors, ge])
    assert [d.dM for d in pm.derivatives(p)[:2]] == [None, None]
    derivatives(pm, p)
    form = mc._DERIV_CACHE[pm]
    assert form.ok and form.damping is not None        # the affine forms are kept
    got, want = derivatives(pm, p * 1.1), pm.derivatives(p * 1.1)  # and hold elsewhere (the loss factor's too)
    for g, w in zip(got, want):
        for k in ("dK", "dM", "dC", "dD"):
            assert same(getattr(g, k), getattr(w, k)) < 1e-9, k


def test_an_explicit_G_makes_a_shear_deformable_beams_mass_depend_on_E():
    """With G given, E/G moves with E: φ and so M change (a genuine, non-linear dependence, assembled directly)."""
    pm = _timoshenko(shear_modulus=80e9)
    d = pm.derivatives(pm.p0)[0]
    M = pm.model_at(pm.p0).assemble().M
    assert d.dM is not None and abs(d.dM).max() > 1e-6 * abs(M).max()


@settings(max_examples=10, deadline=None)
@given(st.floats(0.8, 1.25), st.floats(0.001, 0.3), st.sampled_from([0.0, 0.01, 0.05]))
def test_a_sections_loss_factor_in_all_keeps_the_cached_form(factor, g, eta):
    """A section's loss factor given in all beside PARAM G (the diagnosis' ``eta_<group>``: GE = η − G) makes
    ∂D/∂E of that section η·K_e; at η = 0 it is zero in the affine form and round-off (G·K − G·K summed in
    another order) in the assembly.  That round-off, compared on its own scale, refused the form, and every fit
    of such a model assembled every derivative at every step (tuning case 2160: 184 of 578 calls).  D is
    compared on K's scale."""
    pars = [Parameter("E_1", "E", properties=[1]), Parameter("G", "global_ge", mode="value"),
            _GroupLossFactorTotal("eta_1", "ge", properties=[1], mode="value")]
    pm = ParametricFEModel(build(Beam3D), pars)
    p = np.array([factor, g, eta])
    got, want = derivatives(pm, p), pm.derivatives(p)
    assert mc._DERIV_CACHE[pm].ok
    for g_, w in zip(got, want):
        k_scale = max(abs(d).max() for d in (g_.dK, w.dK, g_.dD, w.dD) if d is not None)
        for k in ("dK", "dM", "dC", "dD"):
            a, b = getattr(g_, k), getattr(w, k)
            a = sp.csr_matrix(pm.structure(p).K.shape) if a is None else a
            b = sp.csr_matrix(a.shape) if b is None else b
            assert abs(a - b).max() <= 1e-9 * (k_scale if k in ("dK", "dD") else max(abs(a).max(), 1e-300)), k
