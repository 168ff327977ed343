"""How the diagnosis maps measured DOFs onto a model: displacement systems (CD) and rigid links."""
from __future__ import annotations

import numpy as np
import pytest

from modalab.core.errors import ModalabValueError
from updating.diagnosis.terms import promote_measured
from updating.fe.models.garteur import garteur_model


def _rotx(deg):
    a = np.radians(deg)
    return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])


def test_a_measured_grid_with_its_own_displacement_system_is_put_in_basic():
    plain = garteur_model(suspension=True)
    tilted = garteur_model(suspension=True)
    tilted.nodes[110] = type(tilted.nodes[110])(110, tilted.nodes[110].xyz, _rotx(150.0))
    tilted._changed()
    f = np.linspace(5.0, 60.0, 12)
    want = plain.frf(f, ["110+Z", "110+Y"], ["218+Z"], quantity="receptance").H
    # in its own system the grid's "Z" is another direction: the measured (basic) Z must not be read from it
    raw = tilted.frf(f, ["110+Z", "110+Y"], ["218+Z"], quantity="receptance").H
    assert np.max(np.abs(raw - want)) > 0.1 * np.max(np.abs(want))
    fixed = promote_measured(tilted, ["110+Z", "110+Y", "218+Z"])
    assert fixed is not tilted and fixed.nodes[110].cd is None and tilted.nodes[110].cd is not None
    got = fixed.frf(f, ["110+Z", "110+Y"], ["218+Z"], quantity="receptance").H
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12 * np.max(np.abs(want)))


def test_a_constrained_grid_with_its_own_system_is_refused_with_advice():
    m = garteur_model(suspension=True)
    m.nodes[110] = type(m.nodes[110])(110, m.nodes[110].xyz, _rotx(30.0))
    m.add_spc(110, "1")
    m._changed()
    with pytest.raises(ModalabValueError, match="grid 110.*displacement system"):
        promote_measured(m, ["110+Z"])


def test_nothing_to_change_returns_the_model_itself():
    m = garteur_model(suspension=True)
    assert promote_measured(m, ["110+Z", "218+Z"]) is m
