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
from updating.diagnosis.terms import _augment
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
    k_loc = 4 * 70e9 * np.pi * (0.016 ** 4 - 0.013 ** 4) / 64 / 0.15         # the post end's own 4EI/L
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
    """Counted, not timed: the receptance columns solved are the references and the candidates' support DOFs
    (at most 12 per single-node release), and what is kept per candidate is its own support block, so work and
    memory grow linearly with the number of candidates (never with its square)."""
    from updating.diagnosis import release as rel
    m = _t_frame(clamp=True)
    st0 = m.structure()
    data = _data(st0, RESP, ["2+Z"], np.linspace(5.0, 500.0, 30))
    lib = build_library(m, kinds=["joint_flexibility", "boundary_flexibility"])
    rvs = [rel.release_vectors(m, c) for c in lib]
    B = rel._Blocks(st0, data, [rv.rows for rv in rvs])
    assert all(rv.rows.size <= 12 for rv in rvs)
    assert B.H_blk.shape[0] == sum(rv.rows.size ** 2 for rv in rvs)
    assert B.H_uio.shape[0] == np.unique(np.concatenate([rv.rows for rv in rvs])).size
    assert B.n_cols <= len(RESP) + 1 + sum(rv.rows.size for rv in rvs)
    # the blocks are the receptance's: H[m, S] by symmetry from the support rows, H[S, S] gathered
    H = rel._Blocks(st0, data, [np.arange(st0.n_dof)])
    for k, rv in enumerate(rvs):
        Hms, Hsr, Hss = B.candidate(k, rv.rows)
        _, _, Hall = H.candidate(0, np.arange(st0.n_dof))
        np.testing.assert_allclose(Hss, Hall[np.ix_(rv.rows, rv.rows)], rtol=1e-10, atol=1e-16)
        np.testing.assert_allclose(Hms, Hall[np.ix_(B.mi, rv.rows)], rtol=1e-8, atol=1e-14)
        np.testing.assert_allclose(Hsr, Hall[np.ix_(rv.rows, B.ri)], rtol=1e-8, atol=1e-14)


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


def _truth_t_frame(k_joint: float | None, axis: int = 2, *, spring: tuple | None = None,
                   clamp: tuple | None = None, damped: tuple | None = None, clamp_eta: float = 0.0):
    """The T frame of :func:`_t_frame` (rail end 1 clamped) in the benchmark's independent truth simulator
    (benchmarks/discovery/truthsim.py: Timoshenko beams three times finer, hysteretic loss factor 0.01): the
    post's end at node 3 on a twin node that turns about global ``axis`` (0, 1, 2) on a spring ``k_joint``
    (None: welded rigidly).  ``spring = (node, component 1-6, k, eta)``: a spring to ground with its own
    hysteretic loss.  ``clamp = (k_translation, k_rotation)``: node 1 held by springs in all six components
    instead of fixed, each with hysteretic loss factor ``clamp_eta``.  ``damped = (element, eta)``: that element of the nominal with loss factor ``eta``."""
    import sys
    from pathlib import Path
    root = str(Path(__file__).resolve().parents[2])
    if root not in sys.path:
        sys.path.insert(0, root)
    from benchmarks.discovery.truthsim import TruthModel, tube
    t = TruthModel()
    nom = _t_frame()
    for nid, nd in sorted(nom.nodes.items()):
        t.add_node(nid, nd.xyz)
    if k_joint is not None:
        t.twin(3, 5003, axis)
    E, rho, G = 70e9, 2700.0, 70e9 / (2 * 1.33)
    secs = {1: tube(0.01, 0.0085), 2: tube(0.008, 0.0065)}          # radii (the model's are diameters)
    nxt = 100
    for e in sorted(nom.elements.values(), key=lambda e: e.eid):
        a, b = e.n1, e.n2
        if e.pid == 2 and a == 3 and k_joint is not None:
            a = 5003
        xa, xb = np.asarray(nom.nodes[e.n1].xyz), np.asarray(nom.nodes[e.n2].xyz)
        chain = [a]
        for k in (1, 2):
            t.add_node(nxt, xa + (xb - xa) * k / 3)
            chain.append(nxt)
            nxt += 1
        chain.append(b)
        for p, q in zip(chain, chain[1:]):
            eta = damped[1] if damped is not None and e.eid == damped[0] else 0.01
            t.beam(p, q, np.array([0.0, 0.0, 1.0]), secs[e.pid], E, G, rho, eta)
    if k_joint is not None:
        t.spring(t.dof(3, 4 + axis), t.dof(5003, 4 + axis), k_joint)
    if spring is not None:
        node, comp, k, eta = spring
        t.spring(t.dof(node, comp), None, k, eta)
    if clamp is None:
        t.fix(1)
    else:
        for comp in range(1, 7):
            t.spring(t.dof(1, comp), None, clamp[0] if comp <= 3 else clamp[1], clamp_eta)
    return t


def _truth_accelerance(t, f_max: float = 600.0, noise: float = 0.003) -> FRF:
    """Accelerance of a truth model at 14 responses and 3 references, 300 lines from 5 Hz, with relative
    complex noise (seeded)."""
    f = np.linspace(5.0, f_max, 300)
    resp = [(2, 3), (4, 3), (5, 3), (6, 3), (7, 3), (8, 3), (5, 2), (2, 2), (6, 1), (8, 1), (3, 1), (3, 2),
            (7, 1), (4, 2)]
    refs = [(2, 2), (6, 1), (8, 2)]
    A = -(2 * np.pi * f) ** 2 * t.receptance(f, resp, refs)
    rng = np.random.default_rng(1)
    A = A * (1 + noise * (rng.standard_normal(A.shape) + 1j * rng.standard_normal(A.shape)))
    lbl = lambda n, c: f"{n}+{'XYZ'[c - 1]}"                                  # noqa: E731
    return FRF(freq_hz=f, H=A, responses=[lbl(*d) for d in resp], references=[lbl(*d) for d in refs],
               coherence=np.full(A.shape, 0.99), quantity="accelerance")


def test_a_spring_to_ground_and_its_own_loss_are_one_finding():
    """A lossy spring to ground (hysteretic loss factor 0.06, as a rubber mount) at the post's tip 8+X of the
    clamped T in the independent truth simulator, 0.07 % noise: the diagnosis names one ground spring at 8+X
    within 20 %.  A dashpot at the same DOF selected after it (as on frames where the mount's loss is visible)
    is reported as a part of that finding, the mount's own loss, not as a second piece of missing physics:
    checked by adding the library's dashpot at 8+X to the accepted terms of this diagnosis."""
    from dataclasses import replace
    from updating.diagnosis import Diagnoser, DiagnoserConfig
    k = 4e3
    meas = _truth_accelerance(_truth_t_frame(None, spring=(8, 1, k, 0.06)), noise=0.0007)
    d = Diagnoser(DiagnoserConfig()).fit(_t_frame(clamp=True, ge=0.0), meas)
    assert [(f.candidate.physics, f.candidate.dofs) for f in d.findings_] == [("ground_spring", ("8+X",))]
    assert d.findings_[0].value == pytest.approx(k, rel=0.2)
    dashpot = next(c for c in build_library(_t_frame(clamp=True), kinds=["local_damping"]) if c.dofs == ("8+X",)
                   and c.matrix == "C")
    d.current = [*d.current, dashpot]
    m_aug, cpar, d.best_scales = _augment(d.model0, d.current)
    d.best_pm = ParametricFEModel(m_aug, d.params + cpar)
    d.best_fit = replace(d.best_fit, p=np.append(d.best_fit.p, 7.0 / d.best_scales[-1]),
                         std=np.append(d.best_fit.std, 0.5))
    (f,) = d._findings()
    assert [(o.physics, o.dofs) for o, *_ in f.parts] == [("local_damping", ("8+X",))]
    assert f.parts[0][1] == pytest.approx(7.0)
    assert "spring to ground at 8+X" in f.label and "with dashpot to ground at 8+X of 7 N·s/m" in f.label


def test_a_released_support_s_own_loss_is_one_loss_factor_on_its_springs():
    """A clamp's rotations released into springs of one stiffness (2e3 N·m/rad) carry, as a candidate, one loss
    factor η on those springs (their CELAS GE): its unit matrix is exactly the change of the structural damping
    matrix per unit η, it is that support's own loss (:func:`loss_of`) and no other term's, and the nominal
    (nothing released) has none."""
    from updating.diagnosis.library import loss_of, spring_loss_candidates
    from updating.fe import ParametricFEModel
    from updating.fe.assembly import assemble
    m = _t_frame(clamp=True, ge=0.0)
    assert spring_loss_candidates(m) == []
    lib = build_library(m, kinds=["boundary_flexibility"])
    rot = next(c for c in lib if c.release[2] == (4, 5, 6))
    tra = next(c for c in lib if c.release[2] == (1, 2, 3))
    m_aug, pars, scales = _augment(m, [rot])
    m_k = ParametricFEModel(m_aug, pars).model_at(np.array([2e3 / scales[0]]))
    (loss,) = spring_loss_candidates(m_k)
    assert loss.dofs == rot.dofs == ("1+RX", "1+RY", "1+RZ")
    assert loss_of(loss, rot) and not loss_of(loss, tra)
    m_l, lpar, _ = _augment(m_k, [loss])
    pm = ParametricFEModel(m_l, lpar)
    red = m_k.reduction()
    assert assemble(pm.model_at(np.array([0.0]))).D is None              # no loss anywhere at η = 0 (ge = 0)
    D = (red.T.T @ assemble(pm.model_at(np.array([0.03]))).D @ red.T).toarray()
    np.testing.assert_allclose(0.03 * loss.G.toarray(), D, rtol=1e-12, atol=1e-12 * 2e3)
    assert np.abs(loss.G.toarray()).max() == pytest.approx(2e3)


def test_diagnoser_names_a_joint_from_independent_truth_data():
    """Accelerance from the independent truth simulator (finer Timoshenko mesh, hysteretic damping, a twin node
    turning about z on a spring at the T-joint) with 0.3 % noise: the diagnosis names joint flexibility at
    node 3 about z, not an inertia or a spring to ground, and its stiffness within 30 %."""
    from updating.diagnosis import Diagnoser, DiagnoserConfig
    k = 2e3
    meas = _truth_accelerance(_truth_t_frame(k, axis=2))
    d = Diagnoser(DiagnoserConfig()).fit(_t_frame(clamp=True, ge=0.0), meas)
    # the first (strongest) finding; whether a later, small term of model-form error (the finer Timoshenko mesh)
    # is kept is the selection step's business, not the screening's
    c = d.findings_[0].candidate
    assert c.physics == "joint_flexibility" and c.dofs == ("3+RZ",)
    assert d.findings_[0].value == pytest.approx(k, rel=0.3)
    assert not any(f.candidate.physics == "joint_flexibility" for f in d.findings_[1:])


def test_release_visibility_separates_what_in_plane_sensors_cannot_see():
    """The T frame lies in the x-y plane (tubes: in- and out-of-plane motion decouple).  Hit and measured only
    in x and y, a released post end about x or y (out-of-plane bending) changes nothing the data hold: its
    χ² is round-off; about z (in-plane bending) it is far above the noise.  With out-of-plane sensors and
    hits the bending axes are visible; the post's own torsion (about y, its axis: a free tube turning about its
    axis moves no translation on it) stays invisible to translational sensors."""
    from updating.diagnosis.release import release_visibility
    m = _t_frame(clamp=True)
    st0 = m.structure()
    f = np.linspace(5.0, 600.0, 60)
    lib = build_library(m, kinds=["joint_flexibility", "boundary_flexibility"])
    in_plane = _data(st0, ["2+X", "2+Y", "4+Y", "5+X", "6+X", "7+X", "8+Y"], ["2+Y", "7+X"], f)
    vis = {c.dofs[0] if c.physics == "joint_flexibility" else c.label: x
           for c, x in release_visibility(st0, m, lib, in_plane, loss_factor=m.global_ge)}
    need = 10 * np.log(in_plane.H.size)
    assert vis["3+RX"] < 1e-12 * need and vis["3+RY"] < 1e-12 * need
    assert vis["3+RZ"] > 1e3 * need
    everywhere = _data(st0, RESP, ["2+Z", "6+X"], f)
    vis3 = {c.dofs[0]: x for c, x in release_visibility(st0, m, lib, everywhere, loss_factor=m.global_ge)
            if c.physics == "joint_flexibility"}
    assert min(vis3["3+RX"], vis3["3+RZ"]) > 1e3 * need
    assert vis3["3+RY"] < need


def test_unobservable_releases_are_listed_and_stated_not_screened():
    """A diagnosis from in-plane data lists the out-of-plane joint releases as unobservable (diagnosis.json
    and the statement), and never screens or names them."""
    from updating.diagnosis import Diagnoser, DiagnoserConfig
    from updating.diagnosis.findings import statement
    m = _t_frame(clamp=True)
    f = np.linspace(5.0, 600.0, 120)
    resp, refs = ["2+X", "2+Y", "4+Y", "5+X", "6+X", "7+X", "8+Y", "4+X"], ["2+Y", "7+X"]
    X = m.structure().frf(f, resp, refs, quantity="receptance")
    meas = FRF(freq_hz=f, H=X.H, responses=X.responses, references=X.references, coherence=np.ones(X.H.shape),
               quantity="receptance")
    d = Diagnoser(DiagnoserConfig(kinds=["joint_flexibility", "boundary_flexibility"]))
    d._t0, d.timings = 0.0, {}
    d.baseline(m, meas)
    d.localise()
    hidden = sorted(u["dofs"][0] for u in d.unobservable if u["physics"] == "joint_flexibility")
    assert hidden == ["3+RX", "3+RY"]
    assert all("3+R" not in c.dofs[0] or c.dofs[0] == "3+RZ" for c, _ in d._options(0)
               if c.physics == "joint_flexibility")
    text = statement([], {k: {"frf_error_held_out": 0.01} for k in ("nominal", "parameters_only", "with_physics")},
                     "rows", (), d.unobservable)
    assert "Not observable with these sensors and hits: " in text and "this conclusion does not cover it" in text
    assert "joint flexibility about RX at node 3;" in text and "joint flexibility about RY at node 3" in text
    assert "about RZ at node 3" not in text


def _portal(ge: float = 0.01) -> FEModel:
    """A portal symmetric about x = 0.3: posts 1-2-3 and 9-8-7 (feet 1 and 9 clamped), a beam 3-4-5-6-7."""
    m = FEModel("portal", global_ge=ge)
    xy = {1: (0, 0), 2: (0, 0.2), 3: (0, 0.4), 4: (0.15, 0.4), 5: (0.3, 0.4), 6: (0.45, 0.4), 7: (0.6, 0.4),
          8: (0.6, 0.2), 9: (0.6, 0.0)}
    for n, (x, y) in xy.items():
        m.add_node(n, (float(x), float(y), 0.0))
    m.add_material(Material(1, E=70e9, rho=2700.0))
    m.add_property(BeamProperty(1, 1, TubeSection(0.02, 0.017), name="post"))
    m.add_property(BeamProperty(2, 1, TubeSection(0.016, 0.013), name="beam"))
    for i, (a, b, p) in enumerate(((1, 2, 1), (2, 3, 1), (3, 4, 2), (4, 5, 2), (5, 6, 2), (6, 7, 2), (7, 8, 1),
                                   (8, 9, 1))):
        m.add_element(Beam3D(i + 1, a, b, p, orientation=(0.0, 0.0, 1.0)))
    m.add_spc(1, "123456")
    m.add_spc(9, "123456")
    return m


def test_a_release_and_its_mirror_image_are_fitted_alternatives():
    """Data taken only on the portal's plane of symmetry (mid-span, vertical and out-of-plane) cannot tell a
    flexible left corner from a flexible right one: the mirror-image models have the same FRFs there.  Fitted
    with the parameters, the mirror-image release is an alternative of the concealed one, with its value;
    a spring to ground, which fits worse, is not."""
    from updating.diagnosis import Diagnoser, DiagnoserConfig
    m = _portal()
    lib = build_library(m, kinds=["joint_flexibility"])
    left = next(c for c in lib if c.dofs == ("3+RZ",))
    k = 0.05 * 4 * 70e9 * np.pi * (0.016 ** 4 - 0.013 ** 4) / 64 / 0.15
    m_aug, pars, sc = _augment(m, [left])
    st_true = ParametricFEModel(m_aug, pars).structure([k / sc[0]])
    f = np.linspace(5.0, 900.0, 160)
    X = st_true.frf(f, ["5+Y", "5+Z"], ["5+Y", "5+Z"], quantity="receptance")
    rng = np.random.default_rng(3)
    Hn = X.H * (1 + 0.005 * (rng.standard_normal(X.H.shape) + 1j * rng.standard_normal(X.H.shape)))
    meas = FRF(freq_hz=f, H=Hn, responses=X.responses, references=X.references, coherence=np.ones(Hn.shape),
               quantity="receptance")
    d = Diagnoser(DiagnoserConfig(kinds=["joint_flexibility", "ground_spring"]))
    d._t0, d.timings = 0.0, {}
    d.baseline(m, meas)
    d.localise()
    d._options(0)
    n = len(d.params)
    m_a, cpar, scales = _augment(d.model0, [left])
    pm_a = ParametricFEModel(m_a, d.params + cpar)
    clo, chi = np.r_[d.lo, 0.0], np.r_[d.hi, np.inf]
    fr = d._fit(pm_a, d.train, np.clip(np.r_[d.p_nomd[:n], k / scales[-1]], clo, chi), lower=clo, upper=chi,
                max_nfev=30)
    alts, comps = d._fitted_alternatives(left, fr, 0, [], [], pm_a.model_at(fr.p), d.train.H.size * 2,
                                         d._margin(pm_a, fr))
    assert [o.dofs for o, _ in alts] == [("7+RZ",)]
    assert ("7+RZ",) in [t[1].dofs for t in comps]         # the competitors fitted, as the picks are kept
    assert alts[0][1] == pytest.approx(k, rel=0.1)


@pytest.mark.parametrize("kt", [5e6, 1e7])
def test_an_elastic_clamp_is_one_finding_with_its_rotational_and_translational_stiffness(kt):
    """The rail's end 1 of the T held, in the independent truth simulator, by springs in all six components
    (``kt`` N/m, 2e3 N·m/rad) instead of a clamp.  5e6 N/m: the screening releases the clamp's rotation
    first; the translations, whose frequency effect alone is small, are then fitted as a part of the same
    support.  1e7 N/m: the rotation alone leaves a residual above the noise and is rejected as a lone term, so
    it is judged once more with the translations (:mod:`updating.diagnosis.refine`; before, nothing was
    found).  One finding at node 1 with both stiffnesses near the truth, and the held-out FRF error well
    below parameter updating's.  At 1e7 N/m the translations shift the frequencies by 0.7 % and their
    cross-validation sits at its threshold: on an AMD EPYC's OpenBLAS the rotation alone passed first and the
    translations, judged on top of it, failed the cross-validation on one fold of four (its fit moved the
    stiffness to 4.5e6); there the finding is the rotation alone, and the test asks the translation only where
    it is part of the finding."""
    from updating.diagnosis import Diagnoser, DiagnoserConfig
    kr = 2e3
    meas = _truth_accelerance(_truth_t_frame(None, clamp=(kt, kr)), noise=0.0007)
    d = Diagnoser(DiagnoserConfig()).fit(_t_frame(clamp=True, ge=0.0), meas)
    assert len(d.findings_) == 1, [f.label for f in d.findings_]
    f = d.findings_[0]
    terms = [(f.candidate, f.value)] + [(o, v) for o, v, _ in f.parts]
    assert all(c.physics == "boundary_flexibility" and c.nodes == (1,) for c, _ in terms)
    rot = [v for c, v in terms if min(c.release[2]) >= 4]
    tra = [v for c, v in terms if max(c.release[2]) <= 3]
    assert len(rot) == 1 and rot[0] == pytest.approx(kr, rel=0.15)
    assert len(tra) == 1 if kt < 1e7 else len(tra) <= 1
    assert all(v == pytest.approx(kt, rel=0.25) for v in tra)
    assert d.fit_["with_physics"]["frf_error_held_out"] < d.fit_["parameters_only"]["frf_error_held_out"] / 5


def test_local_damping_the_mci_over_estimates_is_refitted_on_the_frfs():
    """Loss factor 0.1 on rail element 2 (0.01 elsewhere) in the independent truth simulator.  The MCI ranks
    the damping on element 2 first, but its MCI-optimal loss factor makes the training FRFs worse (χ²/N 7.97 ->
    11.2), and no screening pick was that damping: nothing was found.  The MCI's best is now fitted on the
    FRFs too, from its exact screening's value, and competes with the picks (error 0.046 against 0.055 for
    the best pick, a spring to ground at 8+X, which is then no alternative either)."""
    from updating.diagnosis import Diagnoser, DiagnoserConfig
    meas = _truth_accelerance(_truth_t_frame(None, damped=(2, 0.1)), noise=0.0007)
    d = Diagnoser(DiagnoserConfig()).fit(_t_frame(clamp=True, ge=0.01), meas)
    assert len(d.findings_) == 1, [f.label for f in d.findings_]
    f = d.findings_[0]
    assert f.candidate.physics == "local_damping" and f.candidate.elements == (2,), f.label
    assert "8+X" not in f.label
    # held-out FRF error 0.051 with the parameters alone, 0.030 with the damping
    assert d.fit_["with_physics"]["frf_error_held_out"] < 0.7 * d.fit_["parameters_only"]["frf_error_held_out"]


def test_two_member_ends_released_about_one_axis_at_one_node_are_two_terms():
    """Three members end at node 5 (the rail, a post up and a brace down): two of their ends released about
    the same axis are two terms with two parameters.  Both parameters were named kj_5_6, and the diagnosis of
    a planar frame (a fresh benchmark case, seed 603) stopped with 'duplicate parameter names' after its first
    finding."""
    from updating.diagnosis.terms import _augment

    m = _t_frame(clamp=True)
    m.add_node(9, (0.6, 0.15, 0.0))
    m.add_node(10, (0.6, -0.15, 0.0))
    m.add_element(Beam3D(8, 5, 9, 2, orientation=(0.0, 0.0, 1.0)))
    m.add_element(Beam3D(9, 5, 10, 1, orientation=(0.0, 0.0, 1.0)))
    lib = [c for c in build_library(m, kinds=["joint_flexibility"]) if c.dofs == ("5+RZ",)]
    assert len(lib) >= 2, [c.label for c in lib]
    m_aug, params, _ = _augment(m, lib[:2])
    assert len({p.name for p in params}) == 2, [p.name for p in params]
    pm = ParametricFEModel(m_aug, params)
    assert len(pm.structure([1e4, 2e4]).dofs) > len(m.structure().dofs)
