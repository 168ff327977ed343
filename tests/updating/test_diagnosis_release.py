"""Joint and support flexibility as exact low-rank releases (updating.diagnosis.release), screened everywhere."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from modalab.core.errors import ModalabValueError
from modalab.core.frf import FRF
from updating.diagnosis.fit import frf_data, frf_error, model_frf
from updating.diagnosis.library import _member_ends, _plausible_inertia, build_library
from updating.diagnosis.release import release_screen, released_receptance
from updating.diagnosis.workflow import _augment
from updating.fe import Beam3D, BeamProperty, FEModel, Material, ParametricFEModel, TubeSection


def _t_frame(clamp: bool = False, ge: float = 0.01) -> FEModel:
    """A T of two tubes in the x-y plane: a rail 1-2-3-4-5 along x and a post 3-6-7-8 along y ending on it
    at node 3 (3-D beams); the rail's end 1 clamped when ``clamp``."""
    m = FEModel("T frame", global_ge=ge)
    for i in range(5):
        m.add_node(i + 1, (0.15 * i, 0.0, 0.0))
    for j, y in enumerate((0.15, 0.3, 0.45)):
        m.add_node(6 + j, (0.3, y, 0.0))
    m.add_material(Material(1, E=70e9, rho=2700.0))
    m.add_property(BeamProperty(1, 1, TubeSection(0.02, 0.017), name="rail"))
    m.add_property(BeamProperty(2, 1, TubeSection(0.016, 0.013), name="post"))
    for i in range(4):
        m.add_element(Beam3D(i + 1, i + 1, i + 2, 1, orientation=(0.0, 0.0, 1.0)))
    for k, (a, b) in enumerate(((3, 6), (6, 7), (7, 8))):
        m.add_element(Beam3D(5 + k, a, b, 2, orientation=(0.0, 0.0, 1.0)))
    if clamp:
        m.add_spc(1, "123456")
    return m


def _data(structure, resp, refs, f, *, noise=0.0, seed=0):
    H = structure.frf(f, resp, refs, quantity="receptance")
    Hn = H.H
    if noise:
        rng = np.random.default_rng(seed)
        Hn = Hn * (1 + noise * (rng.standard_normal(Hn.shape) + 1j * rng.standard_normal(Hn.shape)))
    meas = FRF(freq_hz=f, H=Hn, responses=H.responses, references=H.references, coherence=np.ones(Hn.shape),
               quantity="receptance")
    return frf_data(meas, max_lines=len(f))


RESP = ["2+Z", "4+Z", "5+Z", "6+Z", "7+Z", "8+Z", "5+Y", "2+Y", "6+X", "8+X"]


def test_member_ends_are_the_joints_of_the_frame():
    m = _t_frame()
    ends = _member_ends(m)
    # node 3: the rail runs through (elements 2, 3), the post ends there (element 5): one side, the post's end
    assert ends == [(3, (5,))]
    lib = build_library(m, kinds=["joint_flexibility"])
    assert sorted(c.dofs[0] for c in lib) == ["3+RX", "3+RY", "3+RZ"]
    assert all(c.release == ("joint", 3, (int(c.dofs[0][-1] == "X") * 4 + int(c.dofs[0][-1] == "Y") * 5 +
                                         int(c.dofs[0][-1] == "Z") * 6,), (5,)) for c in lib)


@pytest.mark.parametrize("kind, pick", [("joint_flexibility", "3+RZ"), ("joint_flexibility", "3+RX"),
                                        ("boundary_flexibility", "1+RY"),
                                        ("boundary_flexibility", "rotations")])
def test_released_receptance_equals_the_built_model(kind, pick):
    """The Woodbury form on the nominal receptance is exactly the receptance of the model the candidate builds
    (node split with a rigid link and a spring, or the SPC edited into springs), at any spring value."""
    m = _t_frame(clamp=True, ge=0.02)
    st0 = m.structure()
    f = np.linspace(5.0, 400.0, 40)
    data = _data(st0, RESP, ["2+Z", "6+X"], f)
    lib = build_library(m, kinds=[kind])
    c = next(c for c in lib if (pick in c.label if pick == "rotations" else c.dofs == (pick,)))
    for k in (30.0, 3e3, 3e5):
        m_aug, pars, sc = _augment(m, [c])
        st_aug = ParametricFEModel(m_aug, pars).structure([k / sc[0]])
        H_built = model_frf(st_aug, data)
        H_rel = released_receptance(st0, m, c, k, data, loss_factor=m.global_ge)
        np.testing.assert_allclose(H_rel, H_built, rtol=1e-7, atol=1e-9 * np.abs(H_built).max())
        if k == 30.0:      # a soft release changes the receptance (the test would pass for a no-op otherwise)
            assert np.abs(H_built - model_frf(st0, data)).max() > 1e-3 * np.abs(H_built).max()


@settings(max_examples=4, deadline=None)
@given(axis=st.sampled_from(["RX", "RZ"]), logk=st.floats(min_value=1.5, max_value=2.5))
def test_release_screen_names_a_concealed_joint_and_its_axis(axis, logk):
    """Data from the frame whose post end at the T-joint turns about ``axis`` (perpendicular to the post, as a
    welded joint yields) on a spring: the exact screening
    ranks that joint and axis first among every joint and support release, with the spring's value."""
    m = _t_frame(clamp=True)
    lib = build_library(m, kinds=["joint_flexibility", "boundary_flexibility"])
    true = next(c for c in lib if c.physics == "joint_flexibility" and c.dofs == (f"3+{axis}",))
    k_loc = 4 * 70e9 * np.pi * (0.016 ** 4 - 0.013 ** 4) / 4 / 0.15          # the post end's own 4EI/L
    k = 10 ** logk / 100 * k_loc
    m_aug, pars, sc = _augment(m, [true])
    st_true = ParametricFEModel(m_aug, pars).structure([k / sc[0]])
    f = np.linspace(5.0, 600.0, 120)
    data = _data(st_true, RESP + ["3+X", "3+Y"], ["2+Z", "6+X", "7+Y"], f, noise=0.002)
    ranked = release_screen(m.structure(), m, lib, data, loss_factor=m.global_ge)
    best, kb, gain = ranked[0]
    assert best.key == true.key
    # what is left is the noise: the error of the true model itself
    e0 = frf_error(model_frf(m.structure(), data), data)
    e_true = frf_error(model_frf(st_true, data), data)
    assert e_true < 0.5 * e0
    assert (1 - gain) * e0 <= 1.05 * e_true
    assert kb == pytest.approx(k, rel=0.1)


def test_release_screen_of_an_exact_model_gains_nothing():
    m = _t_frame(clamp=True)
    st0 = m.structure()
    data = _data(st0, RESP, ["2+Z", "6+X"], np.linspace(5.0, 500.0, 80))
    lib = build_library(m, kinds=["joint_flexibility", "boundary_flexibility"])
    assert frf_error(model_frf(st0, data), data) < 1e-6
    ranked = release_screen(st0, m, lib, data, loss_factor=m.global_ge)
    assert all(g < 1e-3 for _, _, g in ranked)


def test_release_screen_cost_is_linear_in_candidates():
    """Screening twice the candidates costs about twice as much: counted, not timed, by the receptance columns
    it solves (the support DOFs of the candidates) and the candidates it evaluates."""
    m = _t_frame(clamp=True)
    st0 = m.structure()
    data = _data(st0, RESP, ["2+Z"], np.linspace(5.0, 500.0, 30))
    lib = build_library(m, kinds=["joint_flexibility", "boundary_flexibility"])
    from updating.diagnosis import release as rel
    seen = []
    orig = rel._columns

    def counting(structure, s, cols, keep):
        seen.append(len(cols))
        return orig(structure, s, cols, keep)
    rel._columns = counting
    try:
        release_screen(st0, m, lib[:1], data)
        release_screen(st0, m, lib, data)
    finally:
        rel._columns = orig
    n_sup = seen[1] - 1                     # columns beyond the one reference
    assert seen[0] <= 1 + 12 and n_sup <= 12 * len(lib)


def test_release_screen_refuses_a_structure_of_another_model():
    m = _t_frame(clamp=True)
    other = _t_frame(clamp=False).structure()
    data = _data(other, RESP, ["2+Z"], np.linspace(5.0, 300.0, 20))
    with pytest.raises(ModalabValueError, match="constrained DOFs"):
        release_screen(other, m, build_library(m, kinds=["joint_flexibility"]), data)


def test_plausible_inertia_fails_with_a_message_on_a_non_finite_mass():
    m = _t_frame()
    m.materials[1] = Material(1, E=70e9, rho=float("nan"))
    m._changed()
    with pytest.raises(ModalabValueError, match="translational mass"):
        _plausible_inertia(m)
