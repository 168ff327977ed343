"""Guyan, IRS and SEREP reduction (thesis 2.1.1) against closed-form and full-model results."""
import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

from modalab.core.errors import ConvergenceError, DofError, ModalabValueError
from modalab.core.structure import Structure
from updating.correlation.reduction import guyan, irs, master_indices, reduce, serep


def chain(n=10, seed=0, fixed=True, sparse=False):
    """Fixed-free (or free-free) spring-mass chain with random springs and masses."""
    rng = np.random.default_rng(seed)
    k = rng.uniform(1.0, 2.0, n) * 1e4
    m = rng.uniform(1.0, 2.0, n)
    K = np.zeros((n, n))
    if fixed:
        K[0, 0] += k[0]
    for i in range(1, n):
        K[i - 1, i - 1] += k[i]
        K[i, i] += k[i]
        K[i - 1, i] -= k[i]
        K[i, i - 1] -= k[i]
    M = np.diag(m)
    if sparse:
        K, M = sp.csr_matrix(K), sp.csr_matrix(M)
    return K, M, [f"{i + 1}+Z" for i in range(n)]


MASTERS = ["3+Z", "6+Z", "10+Z"]


class TestMasterIndices:
    def test_labels_and_indices_agree(self):
        _, _, dofs = chain()
        i1, s1, l1 = master_indices(MASTERS, 10, dofs)
        i2, s2, l2 = master_indices([2, 5, 9], 10, dofs)
        assert list(i1) == list(i2) == [2, 5, 9]
        assert [str(d) for d in l1] == [str(d) for d in l2] == MASTERS

    def test_negative_label_flips_sign(self):
        _, _, dofs = chain()
        _, s, _ = master_indices(["3-Z", "6+Z"], 10, dofs)
        assert list(s) == [-1, 1]

    def test_unknown_label_is_named(self):
        _, _, dofs = chain()
        with pytest.raises(DofError, match="99"):
            master_indices(["99+Z"], 10, dofs)

    def test_labels_without_dofs(self):
        with pytest.raises(DofError, match="dofs"):
            master_indices(["3+Z"], 10)

    def test_duplicates_and_all_masters_rejected(self):
        with pytest.raises(DofError):
            master_indices([1, 1], 10)
        with pytest.raises(ModalabValueError):
            master_indices(list(range(10)), 10)


class TestGuyan:
    def test_exact_for_static_loads_on_masters(self):
        K, M, dofs = chain()
        red = guyan(K, M, MASTERS, dofs=dofs)
        F = np.zeros(10)
        F[[2, 5, 9]] = [100.0, -50.0, 30.0]
        x = np.linalg.solve(K, F)
        xm = np.linalg.solve(red.K, F[[2, 5, 9]])                # eq. 2.16 with ω = 0
        np.testing.assert_allclose(xm, x[[2, 5, 9]], rtol=1e-12)
        np.testing.assert_allclose(red.expand(xm), x, rtol=1e-11)  # eq. 2.7

    def test_exact_when_masters_carry_all_mass(self):
        K, M, dofs = chain()
        midx = [2, 5, 9]
        M = np.diag(np.where(np.isin(np.arange(10), midx), np.diag(M), 0.0))
        red = guyan(K, M, midx)
        lam_red = sla.eigvalsh(red.K, red.M)
        # finite eigenvalues of the singular pencil: reciprocals of the non-zero eigenvalues of (M, K)
        mu = sla.eigvalsh(M, K)
        lam_full = np.sort(1.0 / mu[mu > 1e-12])
        np.testing.assert_allclose(lam_red, lam_full, rtol=1e-10)

    def test_transformation_structure(self):
        K, M, dofs = chain()
        red = guyan(K, M, MASTERS, dofs=dofs)
        np.testing.assert_allclose(red.T[[2, 5, 9]], np.eye(3), atol=1e-15)   # identity rows, eq. 2.9
        np.testing.assert_allclose(red.K, red.T.T @ K @ red.T, rtol=1e-12)  # eq. 2.14
        np.testing.assert_allclose(red.M, red.T.T @ M @ red.T, rtol=1e-12)  # eq. 2.15

    def test_upper_bound_on_frequencies(self):
        K, M, dofs = chain()
        red = guyan(K, M, MASTERS, dofs=dofs)
        lam = sla.eigvalsh(red.K, red.M)
        full = sla.eigvalsh(K, M)[:3]
        assert np.all(lam >= full * (1 - 1e-12))                  # Rayleigh–Ritz: never below
        assert lam[2] > full[2] * 1.01                            # and visibly above for this set

    def test_sparse_equals_dense(self):
        K, M, dofs = chain()
        Ks, Ms, _ = chain(sparse=True)
        a, b = guyan(K, M, MASTERS, dofs=dofs), guyan(Ks, Ms, MASTERS, dofs=dofs)
        np.testing.assert_allclose(a.K, b.K, rtol=1e-12)
        np.testing.assert_allclose(a.T, b.T, rtol=1e-12, atol=1e-15)

    def test_negative_master_flips_coordinate(self):
        K, M, dofs = chain()
        a = guyan(K, M, MASTERS, dofs=dofs)
        b = guyan(K, M, ["3-Z", "6+Z", "10+Z"], dofs=dofs)
        np.testing.assert_allclose(b.T[:, 0], -a.T[:, 0], atol=1e-15)
        np.testing.assert_allclose(sla.eigvalsh(a.K, a.M), sla.eigvalsh(b.K, b.M), rtol=1e-12)

    def test_singular_slave_stiffness_is_explained(self):
        K, M, dofs = chain(fixed=False)          # free-free chain: restrained through the single master
        guyan(K, M, ["10+Z"], dofs=dofs)
        # DOF 5 disconnected from everything: K_ss singular
        K2 = K.copy()
        K2[4, :] = 0
        K2[:, 4] = 0
        with pytest.raises(ModalabValueError, match="singular"):
            guyan(K2, M, ["10+Z"], dofs=dofs)


class TestIRS:
    def test_single_step_better_than_guyan(self):
        K, M, dofs = chain()
        full = sla.eigvalsh(K, M)[:3]
        g = sla.eigvalsh(*(lambda r: (r.K, r.M))(guyan(K, M, MASTERS, dofs=dofs)))
        r1 = irs(K, M, MASTERS, dofs=dofs, iterate=False)
        i1 = sla.eigvalsh(r1.K, r1.M)
        assert r1.iterations == 1
        assert np.all(np.abs(i1 - full) / full < np.abs(g - full) / full)

    def test_iterated_converges_to_exact_lowest_eigenvalues(self):
        K, M, dofs = chain()
        r = irs(K, M, MASTERS, dofs=dofs, tol=1e-12)
        assert r.converged and r.iterations > 1
        np.testing.assert_allclose(sla.eigvalsh(r.K, r.M), sla.eigvalsh(K, M)[:3], rtol=1e-9)
        # the history of eigenvalue changes decreases towards the tolerance
        assert r.history[-1] < 1e-12 and r.history[0] > r.history[-1]

    def test_iterated_equals_serep_of_lowest_modes(self):
        # the converged IRS transformation spans the lowest modes: same reduced model as SEREP
        K, M, dofs = chain()
        r = irs(K, M, MASTERS, dofs=dofs, tol=1e-13)
        s = serep(K, M, MASTERS, dofs=dofs)
        np.testing.assert_allclose(r.T, s.T, rtol=1e-6, atol=1e-8 * np.abs(s.T).max())

    def test_sparse_equals_dense(self):
        K, M, dofs = chain()
        Ks, Ms, _ = chain(sparse=True)
        a, b = irs(K, M, MASTERS, dofs=dofs), irs(Ks, Ms, MASTERS, dofs=dofs)
        np.testing.assert_allclose(a.K, b.K, rtol=1e-10)

    def test_non_convergence(self):
        K, M, dofs = chain()
        with pytest.raises(ConvergenceError, match="max_iter"):
            irs(K, M, MASTERS, dofs=dofs, max_iter=2, tol=1e-15)
        r = irs(K, M, MASTERS, dofs=dofs, max_iter=2, tol=1e-15, on_no_convergence="warn")
        assert not r.converged and r.iterations == 2


class TestSEREP:
    def test_reproduces_lowest_modes(self):
        K, M, dofs = chain()
        red = serep(K, M, MASTERS, dofs=dofs)
        w2, phi = sla.eigh(K, M)
        lam, u = sla.eigh(red.K, red.M)
        np.testing.assert_allclose(lam, w2[:3], rtol=1e-11)
        # master shapes equal the full shapes at the masters (up to sign), eq. 2.39
        for r in range(3):
            a, b = u[:, r], phi[[2, 5, 9], r]
            assert abs(abs(a @ b) - np.linalg.norm(a) * np.linalg.norm(b)) < 1e-9 * np.linalg.norm(b) ** 2
            np.testing.assert_allclose(np.abs(red.T @ u[:, r]), np.abs(phi[:, r]), rtol=1e-8, atol=1e-12)

    def test_reproduces_chosen_modes(self):
        K, M, dofs = chain()
        w2, phi = sla.eigh(K, M)
        red = serep(K, M, MASTERS, dofs=dofs, modes=phi[:, [0, 3, 5]] * [2.0, -1.0, 7.0])
        np.testing.assert_allclose(sla.eigvalsh(red.K, red.M), w2[[0, 3, 5]], rtol=1e-11)

    def test_sparse_large_model(self):
        n = 1600                                   # above the dense threshold: shift-invert Lanczos path
        K, M, dofs = chain(n=n, sparse=True)
        masters = [f"{i}+Z" for i in (400, 800, 1200, 1600)]
        red = serep(K, M, masters, dofs=dofs)
        lam = sla.eigvalsh(red.K, red.M)
        import scipy.sparse.linalg as spla
        ref = np.sort(spla.eigsh(K.tocsc(), k=4, M=M.tocsc(), sigma=-1.0, which="LM")[0])
        np.testing.assert_allclose(lam, ref, rtol=1e-8)

    def test_dependent_modes_at_masters(self):
        K, M, dofs = chain()
        _, phi = sla.eigh(K, M)
        modes = phi[:, :2].copy()
        modes[:, 1] = modes[:, 0]
        with pytest.raises(ModalabValueError, match="linearly dependent"):
            serep(K, M, MASTERS[:2], dofs=dofs, modes=modes)


class TestReduceStructure:
    def test_structure_with_damping(self):
        K, M, dofs = chain()
        C = 1e-3 * K + 0.1 * M
        st = Structure(M=M, K=sp.csr_matrix(K), C=C, dofs=dofs)
        red = reduce(st, MASTERS, method="guyan")
        np.testing.assert_allclose(red.C, 1e-3 * red.K + 0.1 * red.M, rtol=1e-10, atol=1e-12)
        rs = red.structure()
        assert [str(d) for d in rs.dofs] == MASTERS
        ms = red.modes()
        assert ms.n_modes == 3 and ms.scaling == "unit_modal_mass"
        full = red.modes(full=True)
        assert full.n_dof == 10

    def test_unknown_method(self):
        K, M, dofs = chain()
        with pytest.raises(ModalabValueError, match="guyan"):
            reduce(Structure(M=M, K=K, dofs=dofs), MASTERS, method="craig")

    def test_masters_as_test_labels_through_a_map(self):
        from updating.correlation.dofmap import DofMap
        from updating.correlation.metrics import mixed_orthogonality
        K, M, dofs = chain()
        st = Structure(M=M, K=K, dofs=dofs)
        dm = DofMap(dofs={"103+Z": "3-Z", "106+Z": "6+Z", "110+Z": "10+Z"})
        red = reduce(st, ["103+Z", "106+Z", "110+Z"], method="serep", dofmap=dm)
        assert [str(d) for d in red.masters] == ["103+Z", "106+Z", "110+Z"]
        w2, phi = sla.eigh(K, M)
        test_shapes = phi[[2, 5, 9], :3] * np.array([-1.0, 1.0, 1.0])[:, None]   # what the sensors read
        np.testing.assert_allclose(mixed_orthogonality(test_shapes, red.M), np.eye(3), atol=1e-10)
        np.testing.assert_allclose(red.expand(test_shapes), phi[:, :3], atol=1e-10)
