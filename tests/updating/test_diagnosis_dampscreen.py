"""Local damping screened with the parameters re-fitted (updating.diagnosis.dampscreen).

The data are exact receptances of the thesis beam (free-free tube, PARAM G 0.01) with a structural loss factor
added on one element, computed by the direct solve of the augmented model (the library's element matrix, not
the modal form under test).  The screen starts from a global loss factor fitted without the local term (raised
to absorb it), the situation in which the exact screening with the parameters held ranks the element far down."""
import numpy as np
import pytest

from modalab.core.frf import FRF
from modalab.core.structure import Structure
from updating.diagnosis.dampscreen import damping_screen
from updating.diagnosis.fit import frf_data
from updating.diagnosis.library import build_library
from updating.diagnosis.terms import _augment
from updating.fe import Parameter, ParametricFEModel
from updating.fe.models.beams import thesis_beam


def _case(element: int | None, eta: float):
    nominal = thesis_beam()
    nominal.global_ge = 0.01
    nominal._changed()
    lib = build_library(nominal, kinds=("local_damping",))
    truth = nominal
    if element is not None:
        c = next(c for c in lib if c.matrix == "D" and c.elements == (element,))
        m_aug, cpar, scales = _augment(nominal, [c])
        truth = ParametricFEModel(m_aug, cpar).model_at([eta / scales[-1]])
    labels = [str(d) for d in nominal.structure().dofs if d.axis == 3]
    f = np.linspace(5.0, 900.0, 600)
    H = truth.frf(f, labels, [labels[2], labels[7]], quantity="receptance")
    meas = FRF(freq_hz=f, H=H.H, responses=H.responses, references=H.references, coherence=np.ones(H.H.shape),
               quantity="receptance")
    pm = ParametricFEModel(nominal, [Parameter("eta", "global_ge", mode="value")])
    return pm, lib, frf_data(meas, max_lines=300)


@pytest.mark.parametrize("element", [2, 5, 8])
def test_the_damped_element_ranks_first_with_its_loss_factor(element):
    pm, lib, data = _case(element, 0.2)
    # the global loss factor as a fit without the local term leaves it: raised to take part of it
    ranked = damping_screen(pm, [0.013], lib, data)
    c, value, gain = ranked[0]
    assert element in c.elements, [(o.label, round(g, 3)) for o, _, g in ranked[:4]]
    if c.elements == (element,):
        assert value == pytest.approx(0.2, rel=0.15)
    assert gain > 0.5


def test_the_screening_on_two_processes_is_the_serial_one_bit_for_bit():
    """The candidates' fits run on forked processes (fork_map): the same ranking, values and gains, in the same
    order, as the serial loop, the top FITTED continued from their own two-step points."""
    pm, lib, data = _case(5, 0.2)
    serial = damping_screen(pm, [0.013], lib, data, jobs=1)
    forked = damping_screen(pm, [0.013], lib, data, jobs=2)
    assert len(serial) > 3
    assert [(c.key, v, g) for c, v, g in forked] == [(c.key, v, g) for c, v, g in serial]
    assert all(a is b for (a, _, _), (b, _, _) in zip(forked, serial))        # the caller's own candidates


def test_an_exact_model_gains_nothing():
    pm, lib, data = _case(None, 0.0)
    ranked = damping_screen(pm, [0.01], lib, data)
    assert all(g < 1e-3 for _, _, g in ranked), ranked[:3]


@pytest.mark.parametrize("path", ["eigensolution", "line by line", "viscous"])
def test_the_factored_terms_give_the_residual_and_jacobian_of_the_full_arrays(path, monkeypatch):
    """The modal change keeps each term as two m x m parts, ``A(s) = A0 + s² A2``, never the (lines x m x m)
    array (one per candidate and parameter, kept for a fit, made the demo's diagnosis peak at 20 GB).  On the
    beam, with a local loss factor and a mass-and-stiffness parameter at once, its residual and Jacobian are
    those of the full arrays (the formula of the module docstring, inverted line by line here), and the
    Jacobian is the residual's derivative (central differences) — both from one eigensolution of the changed
    reduced model (the free beam's six rigid-body modes a cluster of equal eigenvalues) and, when that is
    refused (a backward error allowed of 0) or does not apply (a viscous term, ``Z`` quadratic in ``s``), from
    the LU of every line."""
    from updating.diagnosis import dampscreen
    from updating.diagnosis.dampscreen import _ModalChange, _projected
    if path == "line by line":
        monkeypatch.setattr(dampscreen, "BACKWARD_ERROR", 0.0)
    tol = 1e-9 if path == "eigensolution" else 1e-12
    pm, lib, data = _case(5, 0.2)
    st = pm.structure([0.013])
    if path == "viscous":                            # proportional viscous damping beside the structural
        st = Structure(M=st.M, K=st.K, C=1e-6 * st.K, D=st.D, dofs=st.dofs)
    mc = _ModalChange(st, data)
    c = next(c for c in lib if c.matrix == "D" and c.elements == (5,))
    K, M = st.K.tocsr(), st.M.tocsr()
    terms = [(None, None, c.G), (0.3 * K, -0.2 * M, 0.01 * K)]          # (K, M, D) of each term
    E = mc.stack([mc.term(dK, dM, dD) for dK, dM, dD in terms])
    x = np.array([0.15, 0.02])
    s2 = data.s ** 2
    full = np.stack([(_projected(dK, mc.phi) + 1j * _projected(dD, mc.phi))[None]
                     + s2[:, None, None] * _projected(dM, mc.phi)[None] for dK, dM, dD in terms])   # (n_x, n_s, m, m)
    Zi = np.linalg.inv(mc.Z0 + np.einsum("j,jfab->fab", x.astype(complex), full))
    H = mc.pm[None] @ Zi @ mc.pr.T[None]
    r_full = (mc.r0 + (H - mc.H00) * mc.scale).ravel()
    J_full = np.stack([(-(mc.pm[None] @ Zi @ full[j] @ Zi @ mc.pr.T[None]) * mc.scale).ravel()
                       for j in range(x.size)])
    r, J = mc.residual(x, E), mc.jacobian(x, E)
    assert (mc._modes(x, E) is not None) == (path == "eigensolution")
    assert np.abs(r - r_full).max() <= tol * np.abs(r_full).max()
    assert np.abs(J - J_full).max() <= tol * np.abs(J_full).max()
    for j in range(x.size):
        h = 1e-6 * np.eye(x.size)[j]
        fd = (mc.residual(x + h, E) - mc.residual(x - h, E)) / 2e-6
        assert np.abs(fd - J[j]).max() <= 1e-5 * np.abs(J[j]).max()
    assert abs(np.linalg.norm(r) - np.linalg.norm(mc.r0)) > 1e-3 * np.linalg.norm(mc.r0)   # the change shows
