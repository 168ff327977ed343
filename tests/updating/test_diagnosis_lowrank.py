"""The candidate library's low-rank storage (issue 16 #8): each candidate's unit matrix as indices and a small
block (:class:`~updating.diagnosis.local_matrix.LocalMatrix`), equal to the explicit n × n matrices it replaced, and
the modes-only screening giving the same numbers from either."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from updating.diagnosis.frfscreen import _low_rank
from updating.diagnosis.library import LocalMatrix, build_library
from updating.fe import Beam3D, BeamProperty, FEModel, LumpedMass, Material, RectangularSection


def _frame():
    """A free-free 3-D frame with a rigid link (dependent DOFs: a candidate there acts through the link), a
    clamp and a lumped mass."""
    m = FEModel("frame")
    m.add_material(Material(1, E=70e9, nu=0.3, rho=2700.0))
    m.add_property(BeamProperty(1, 1, RectangularSection(0.05, 0.008), name="bar"))
    m.add_property(BeamProperty(2, 1, RectangularSection(0.03, 0.01), name="post"))
    xs = [(0, 0, 0), (0.2, 0, 0), (0.4, 0, 0), (0.6, 0, 0), (0.4, 0.0, 0.2), (0.4, 0.0, 0.4)]
    for i, x in enumerate(xs):
        m.add_node(i + 1, x)
    for i, (a, b, pid) in enumerate([(1, 2, 1), (2, 3, 1), (3, 4, 1), (3, 5, 2), (5, 6, 2)]):
        m.add_element(Beam3D(i + 1, a, b, pid, (0.0, 1.0, 0.0) if pid == 1 else (1.0, 0.0, 0.0)))
    m.add_node(7, (0.6, 0.05, 0.02))
    m.add_rbe2(20, 4, [7])
    m.add_element(LumpedMass(30, 7, 0.2))
    m.add_spc(1, "123")
    return m


def _explicit(model, cand, red):
    """The unit matrix as the library built it before: ``Tᵀ E Eᵀ T`` (springs, masses) or ``Tᵀ K_e T``."""
    from updating.fe.assembly import assemble
    from modalab.core.dof import parse_dofs
    if cand.physics == "local_damping" and cand.matrix == "D":
        K = sum(assemble(model, elements=[model.elements[i]], include_global=False).K for i in cand.elements)
        return (red.T.T @ K @ red.T).toarray()
    idx = {(d.node, d.axis): i for i, d in enumerate(red.full_dofs)}
    R = red.T[[idx[(d.node, d.axis)] for d in parse_dofs(list(cand.dofs))]]
    return (R.T @ R).toarray()


def test_local_matrices_equal_the_explicit_unit_matrices():
    m = _frame()
    red = m.reduction()
    cands = build_library(m)
    shared = [c for c in cands if c.shared and c.G is not None]
    assert {c.physics for c in shared} == {"ground_spring", "added_mass", "local_damping"}
    for c in shared:
        assert isinstance(c.G, LocalMatrix)
        assert c.G.shape == (red.n_dof, red.n_dof)
        E = _explicit(m, c, red)
        np.testing.assert_allclose(c.G.toarray(), E, rtol=1e-14, atol=1e-14 * np.abs(E).max())
        # the factor the screenings use is the one of the explicit matrix (bit for bit off the rigid link,
        # where the sums have one term)
        rows_a, L_a = c.G.low_rank()
        rows_b, L_b = _low_rank(sp.csr_matrix(E))
        np.testing.assert_array_equal(rows_a, rows_b)
        np.testing.assert_allclose(L_a @ L_a.T, L_b @ L_b.T, rtol=1e-12, atol=1e-12 * np.abs(E).max())
        if 7 not in c.nodes and c.physics != "local_damping":
            np.testing.assert_array_equal(L_a, L_b)
    # a point mass on a node slaved by the rigid link acts on the independent node's six DOFs
    c7 = next(c for c in shared if c.label == "point mass at node 7")
    assert c7.G.rows.size == 6 and np.linalg.matrix_rank(c7.G.block) == 3


def test_local_matrix_storage_does_not_grow_with_the_model():
    G = LocalMatrix.from_factor(sp.csr_matrix(([1.0, 1.0], ([0, 1], [7, 99_998])), shape=(2, 100_000)), 100_000)
    assert G.rows.tolist() == [7, 99_998] and G.block.shape == (2, 2)
    assert G.rows.nbytes + G.block.nbytes < 100
    np.testing.assert_array_equal(G.tocsr()[[7, 99_998]][:, [7, 99_998]].toarray(), np.eye(2))


# ------------------------------------------------------------------ the modes-only screening on the low-rank form
def _gvt_case(tmp_path):
    """A 21-grid lumped-mass CBEAM deck without SPC and the modes of an independent finer beam carrying a
    concealed 0.06 kg mass at grid 18 (the test helpers of test_diagnosis_modes)."""
    from test_diagnosis_modes import _gvt_deck, _gvt_modes
    from updating.diagnosis.modes import ModalResidual, _on_independent_dofs
    model = _gvt_deck(tmp_path / "gvt.bdf")
    st = model.structure()
    lib = _on_independent_dofs(build_library(model, kinds=["ground_spring", "added_mass"]), st)
    return st, lib, ModalResidual(_gvt_modes(masses=[(18, 0.06)]))


def test_screening_numbers_are_the_same_from_low_rank_and_explicit_matrices(tmp_path):
    import dataclasses
    from updating.diagnosis.modes import screen_modes
    st, lib, resid = _gvt_case(tmp_path)
    explicit = [dataclasses.replace(c, G=c.G.tocsr()) for c in lib]
    assert all(isinstance(c.G, sp.csr_matrix) for c in explicit)
    a = screen_modes(st, lib, resid)
    b = screen_modes(st, explicit, resid)
    assert len(a) > 10
    assert [c.key for c, _, _ in a] == [c.key for c, _, _ in b]
    np.testing.assert_array_equal([v for _, v, _ in a], [v for _, v, _ in b])
    np.testing.assert_array_equal([g for _, _, g in a], [g for _, _, g in b])


def test_first_order_sensitivities_match_finite_differences_in_the_subspace(tmp_path):
    # ∂e/∂θ of the pre-screen against central differences of the residual of the subspace eigenproblem
    # Kr + θ bbᵀ (or Mr + θ bbᵀ) at a small value, the pairing fixed: eigenvalues and shapes to first order
    import scipy.linalg as sla
    from updating.diagnosis.modes_screen import _jacobians, _ScreenState
    st, lib, resid = _gvt_case(tmp_path)
    state = _ScreenState(st, resid, None)
    Kr0, Mr0 = state.basis.project(state.K, state.M)
    for label in ("spring to ground at 9+Z", "point mass at node 14", "rotary inertia at 5+RY"):
        c = next(c for c in lib if c.label == label)
        rows, L = c.G.low_rank()
        J = _jacobians(state, c.matrix, rows[None], L[None])[0]
        b = state.basis.rows_of(rows).T @ L
        scale = np.trace(L.T @ (state.K if c.matrix == "K" else state.M)[rows][:, rows].toarray() @ L)
        h = 1e-5 * abs(scale) / max(float(np.sum(b * b)), 1e-300) if c.matrix == "K" else 1e-5 * 0.1

        def e(theta):
            Kr = Kr0 + theta * b @ b.T if c.matrix == "K" else Kr0
            Mr = Mr0 + theta * b @ b.T if c.matrix == "M" else Mr0
            w2, Psi = sla.eigh(Kr, Mr)
            fm = np.sqrt(np.clip(w2[:state.kn], 0, None)) / (2 * np.pi)
            return resid.residual(fm, state.Um @ np.linalg.solve(state.Psi0, Psi[:, :state.kn]))

        fd = (e(h) - e(-h)) / (2 * h)
        assert np.abs(fd).max() > 0, label
        np.testing.assert_allclose(J, fd, rtol=1e-4, atol=1e-4 * np.abs(fd).max(), err_msg=label)


def test_first_order_prescreen_keeps_what_the_full_screening_finds(tmp_path):
    from updating.diagnosis.modes import screen_modes
    st, lib, resid = _gvt_case(tmp_path)
    full = screen_modes(st, lib, resid)
    pre = screen_modes(st, lib, resid, prescreen_above=0, keep=20)          # 20 of ~200 evaluated exactly
    assert len(lib) > 150 and len(pre) <= 20
    # the best candidates of the full screening survive the pre-screen, with the same numbers
    for c, v, g in full[:4]:
        hit = next(x for x in pre if x[0].key == c.key)
        assert hit[1] == v and hit[2] == g


def test_mci_columns_are_the_same_from_low_rank_and_explicit_matrices():
    # the MCI screening's residual columns (updating.methods.mci_condensed._column) from the block alone
    from updating.methods.mci_condensed import _column
    m = _frame()
    cands = [c for c in build_library(m) if c.shared and c.G is not None]
    n = m.reduction().n_dof
    rng = np.random.default_rng(0)
    x = rng.standard_normal((n, 2, 5)) + 1j * rng.standard_normal((n, 2, 5))
    T = rng.standard_normal((n, 3, 5))
    s = 1j * np.linspace(10.0, 60.0, 5)
    w = np.ones((2, 5))
    for c in cands:
        a = _column(T, x, c.G, s ** 2, w)
        b = _column(T, x, c.G.tocsr(), s ** 2, w)
        np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-13 * np.abs(b).max())
