"""A model-wide loss factor that does not damp springs with a loss factor of their own
(updating.fe.damping.own_loss_exempt): the matrices, the deck's own G, and the Nastran deck written from it."""
import numpy as np
import pytest

from updating.fe import Beam3D, BeamProperty, FEModel, Material, RectangularSection, Spring
from updating.fe.assembly import assemble
from updating.fe.bulk import build_model, read_bdf, to_bulk, write_bdf
from updating.fe.damping import own_loss_exempt


def mounted_bar(g=0.0):
    """A bar on two elastomer mounts (GE 0.08) and one plain spring (no GE of its own)."""
    m = FEModel("bar on mounts", global_ge=g)
    m.add_material(Material(1, E=70e9, nu=0.3, rho=2700))
    m.add_property(BeamProperty(1, 1, RectangularSection(0.03, 0.01), name="bar"))
    for i in range(4):
        m.add_node(i + 1, (0.2 * i, 0.0, 0.0))
    for i in range(3):
        m.add_element(Beam3D(i + 1, i + 1, i + 2, 1, (0.0, 0.0, 1.0)))
    m.add_element(Spring(101, (1, 3), None, 5e3, ge=0.08))
    m.add_element(Spring(102, (4, 3), None, 5e3, ge=0.08))
    m.add_element(Spring(103, (2, 2), None, 2e3))
    return m


def parts(m):
    """K of the beams, of the mounts and of the plain spring."""
    def k(eids):
        return assemble(m, elements=[m.elements[e] for e in eids], include_global=False).K.toarray()
    return k([1, 2, 3]), k([101, 102]), k([103])


@pytest.mark.parametrize("g0", [0.0, 0.01])
def test_mounts_keep_their_loss_whatever_g(g0):
    m = own_loss_exempt(mounted_bar(g0))
    kb, km, ks = parts(m)
    # at the deck's own G the matrices are the deck's: mounts (0.08 + G0), beams and plain spring G0
    np.testing.assert_allclose(m.assemble().D.toarray(), mounted_bar(g0).assemble().D.toarray(), atol=1e-9)
    for g in (0.0, 0.003, 0.05):
        m.global_ge = g
        want = g * (kb + ks) + (0.08 + g0) * km        # the mounts' loss alone at g = 0: D is never empty
        np.testing.assert_allclose(m.assemble().D.toarray(), want, atol=1e-9)
    # the deck as Nastran reads it: G damps everything, the mounts GE + G
    d = mounted_bar(0.05)
    np.testing.assert_allclose(d.assemble().D.toarray(), 0.05 * (kb + ks + km) + 0.08 * km, atol=1e-9)


def test_spring_added_later_is_damped_by_g():
    m = own_loss_exempt(mounted_bar())
    assert m.global_ge_exempt == {101, 102}
    m.add_element(Spring(104, (3, 3), None, 1e3, ge=0.02))      # a candidate's spring: G + its own ge
    m.global_ge = 0.01
    k4 = assemble(m, elements=[m.elements[104]]).D.toarray()
    K4 = assemble(m, elements=[m.elements[104]], include_global=False).K.toarray()
    np.testing.assert_allclose(k4, 0.03 * K4, atol=1e-12)


def test_deck_written_with_exempt_mounts_reads_back_the_same_damping(tmp_path):
    m = own_loss_exempt(mounted_bar())
    m.global_ge = 0.006
    path = tmp_path / "diagnosed.bdf"
    write_bdf(to_bulk(m), path)
    back = build_model(read_bdf(path))         # Nastran's reading: PARAM G on every stiffness, GE written 0.074
    assert back.global_ge == pytest.approx(0.006) and not back.global_ge_exempt
    np.testing.assert_allclose(back.assemble().D.toarray(), m.assemble().D.toarray(), rtol=1e-6, atol=1e-6)
