"""Writing bulk data (round trips in three formats) and exporting updated FE models."""
from pathlib import Path

import numpy as np
import pytest

from modalab.core.errors import BulkDataError
from updating.fe.bulk import build_model, read_bdf, to_bulk, write_bdf
from updating.fe.bulk import cards as C
from updating.fe import Beam2D, BeamProperty, Damper, LumpedMass, Parameter, ParametricFEModel, Spring
from updating.fe.models.garteur import garteur_model

DATA = Path(__file__).parent / "data"
DECKS = [DATA / n for n in ("frame_small.bdf", "frame_large_femap.bdf", "frame_free.bdf", "frame_pynastran.bdf")]
DECKS.append(Path(__file__).resolve().parents[2] / "updating" / "fe" / "models" / "garteur.bdf")
FORMATS = ["small", "large", "free"]


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("deck", DECKS, ids=lambda p: p.name)
def test_round_trip_identity(deck, fmt):
    a = read_bdf(deck)
    text = write_bdf(a, format=fmt)
    b = read_bdf(text)
    assert b == a
    assert b.case_control.commands == a.case_control.commands and b.case_control.sol == a.case_control.sol
    assert write_bdf(b, format=fmt) == text          # writing is deterministic and idempotent


def test_unsupported_cards_are_written_back(recwarn):
    deck = "GRID    1\nGRID    2\nGRID    3\nCTRIA6  5       1       1       2       3       .5\nPSOLID  1       1\n"
    a = read_bdf(deck)
    for fmt in FORMATS:
        b = read_bdf(write_bdf(a, format=fmt))
        assert b == a and [r.name for r in b.unsupported] == ["CTRIA6", "PSOLID"]


def test_exact_promotes_to_large_field(tmp_path):
    third = 1.0 / 3.0
    deck = f"GRID,1,,{third!r},0.,0.\nGRID,2,,1.,0.,0.\n"
    a = read_bdf(deck)
    text = write_bdf(a, tmp_path / "out.bdf", format="small")
    assert text.count("GRID*") == 1                        # only the card that needs it
    assert read_bdf(tmp_path / "out.bdf").grids[1].xyz[0] == pytest.approx(third, rel=1e-10)
    strict = read_bdf(write_bdf(a, format="small", exact=False))
    assert strict.grids[1].xyz[0] == pytest.approx(third, rel=1e-6) and strict.grids[1].xyz[0] != third


def test_bad_format():
    with pytest.raises(BulkDataError, match="format"):
        write_bdf(read_bdf("GRID    1\n"), format="wide")


# ----------------------------------------------------------------- export
@pytest.fixture(scope="module")
def frame():
    bulk = read_bdf(DATA / "frame_small.bdf")
    return bulk, build_model(bulk)


def _same_matrices(m1, m2, rtol=1e-9):
    a, b = m1.assemble(), m2.assemble()
    assert a.dofs == b.dofs
    for k in ("K", "M", "C", "D"):
        A, B = getattr(a, k), getattr(b, k)
        if B is None:
            assert A is None
            continue
        assert abs(A - B).max() <= rtol * abs(B).max(), k


def test_export_unchanged_model_keeps_cards(frame):
    bulk, model = frame
    out = to_bulk(model, template=bulk)
    assert out.grids == bulk.grids and out.properties == bulk.properties and out.materials == bulk.materials
    assert out.elements == bulk.elements and out.rigid == bulk.rigid and out.tables == bulk.tables
    assert out.case_control.sol == "103"
    _same_matrices(build_model(read_bdf(write_bdf(out))), model, rtol=0)


def test_export_updated_parameters(frame):
    bulk, model = frame
    pars = [Parameter("E1", "E", materials=(1,)), Parameter("t", "h", properties=(1,)),
            Parameter("kel", "k", elements=(12,), mode="value"), Parameter("m15", "mass", elements=(15,)),
            Parameter("rho_tube", "rho", properties=(4,))]
    pm = ParametricFEModel(model, pars)
    p = np.array([1.2345678901, 0.87654321, 3.3e4, 1.5, 0.9])
    updated = pm.model_at(p)
    out = to_bulk(updated, template=bulk)
    for fmt in FORMATS:
        back = build_model(read_bdf(write_bdf(out, format=fmt)))
        _same_matrices(back, updated)
        np.testing.assert_allclose(back.modes(8).freq_hz, updated.modes(8).freq_hz, rtol=1e-9)
    assert out.materials[1].E == pytest.approx(7e10 * 1.2345678901)
    assert out.properties[1].dims == pytest.approx((0.02 * 0.87654321, 0.01))   # DIM1 is h (along z)
    assert isinstance(out.properties[1], C.Pbarl) and out.properties[1].comment == bulk.properties[1].comment
    assert isinstance(out.elements[12], C.Celas2) and out.elements[12].k == 3.3e4
    assert out.elements[15].m == pytest.approx(0.75)
    tube = out.properties[4]                      # property-level density clones material 2
    assert tube.mid != 2 and out.materials[tube.mid].rho == pytest.approx(7850 * 0.9)
    assert out.grids == bulk.grids and out.elements[11] == bulk.elements[11]


def test_export_added_elements_and_split_grid(frame):
    bulk, model = frame
    m = model.copy()
    m.add_node(50, (1.1, 0.0, -0.2))             # split CBAR 9 (grids 8-9) at a new grid
    old = m.elements[9]
    m.elements[9] = type(old)(9, old.n1, 50, old.pid, orientation=old.orientation)
    m.add_element(type(old)(90, 50, old.n2, old.pid, orientation=old.orientation))
    m.add_element(Spring(91, (50, 3), None, 1.5e3, ge=0.04, group="new spring"))
    m.add_element(LumpedMass(92, 50, 0.05, inertia=(1e-4, 2e-4, 3e-4), group="sensor"))
    m.add_element(Damper(93, (50, 1), (9, 1), 3.0))
    out = to_bulk(m, template=bulk)
    assert out.grids[50].xyz == (1.1, 0.0, -0.2) and out.elements[9].gb == 50
    assert isinstance(out.elements[91], C.Celas2) and out.elements[91].ge == 0.04
    assert isinstance(out.elements[92], C.Conm2) and out.elements[92].inertia[5] == 3e-4
    assert isinstance(out.elements[93], C.Cdamp2)
    text = write_bdf(out, format="large")
    _same_matrices(build_model(read_bdf(text)), m)


def test_export_python_model_without_template():
    m = garteur_model(mesh=2, suspension=True, torsion_springs=True)
    back = build_model(read_bdf(write_bdf(m)))
    _same_matrices(back, m)
    assert back.prop(2).name == "wing" and back.elements[970].group == "wing_torsion"


def test_export_timoshenko_model_as_cbeam_pbeaml():
    from updating.fe import Timoshenko3D
    m = garteur_model(mesh=2, element=Timoshenko3D)
    out = to_bulk(m)
    assert isinstance(out.elements[200], C.Cbeam) and isinstance(out.properties[2], C.Pbeaml)
    for fmt in FORMATS:
        back = build_model(read_bdf(write_bdf(out, format=fmt)))
        assert type(back.elements[200]) is Timoshenko3D
        _same_matrices(back, m)


def test_export_rejects_elements_without_card(frame):
    _, model = frame
    m = model.copy()
    m.add_property(BeamProperty(77, 1, model.prop(1).section))
    m.add_element(Beam2D(77, 1, 2, 77))
    with pytest.raises(BulkDataError, match="Beam2D"):
        to_bulk(m)
