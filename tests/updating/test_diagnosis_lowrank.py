"""The candidate library's low-rank storage (issue 16 #8): each candidate's unit matrix as indices and a small
block (:class:`~updating.diagnosis.library.LocalMatrix`), equal to the explicit n × n matrices it replaced, and
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
