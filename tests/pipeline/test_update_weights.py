"""The update stage's weights (issue 14): frequencies weighted by the standard deviations identification stored
with the modes, shapes by the noise their complexity shows; a set without them says so and keeps 1 %."""
import logging

import numpy as np
import pytest

from modalab.app.stages._update import _freq_sigma, _shape_sigma
from modalab.core.modes import ModeSet


def _modes(std=None, complex_part=0.0):
    rng = np.random.default_rng(0)
    phi = rng.normal(size=(6, 3)) + 1j * complex_part * rng.normal(size=(6, 3))
    ind = {} if std is None else {"freq_std_hz": np.asarray(std, float)}
    return ModeSet(freq_hz=[10.0, 20.0, 40.0], damping=[0.01] * 3, shapes=phi,
                   dofs=[f"{k}+Z" for k in range(1, 7)], indicators=ind)


def test_frequency_sigma_comes_from_the_identified_standard_deviations():
    fs = _freq_sigma(None, _modes([0.001, 0.004, np.nan]), "modes.json")
    assert np.allclose(fs, [1e-4, 2e-4, 0.01])            # relative; a mode without one keeps 1 %
    assert _freq_sigma(0.003, _modes([0.001, 0.004, 0.002]), "modes.json") == 0.003   # the option wins


def test_a_set_without_standard_deviations_keeps_one_percent_and_says_so(caplog):
    with caplog.at_level(logging.WARNING):
        assert _freq_sigma(None, _modes(), "modes.uff") is None
    assert "modes.uff" in caplog.text and "--freq-sigma" in caplog.text


@pytest.mark.parametrize("part, low, high", [(0.0, 0.05, 0.05), (0.5, 0.3, 2.0)])
def test_shape_sigma_is_raised_to_the_complexity_noise(part, low, high):
    sig = np.atleast_1d(_shape_sigma(0.05, _modes(complex_part=part)))
    assert np.all(sig >= low) and np.all(sig <= high)


# ----------------------------------------------------------------------------- a UFF 55 and its modes.json
def _write_pair(d, std, json_modes=None):
    """modes.uff as ``modalab identify`` writes it, and a modes.json beside it (the same modes unless given)."""
    from modalab.core import uff

    m = _modes(std)
    uff.write_modes(d / "modes.uff", _modes())          # a UFF 55 carries no frequency uncertainty
    (json_modes or m).to_json(d / "modes.json")
    return d / "modes.uff"


def test_a_uff_takes_the_uncertainties_of_the_modes_json_beside_it(tmp_path):
    from modalab.app.stages._common import load_modes
    from modalab.app.stages._update import _sibling_uncertainty, _weights_text

    path = _write_pair(tmp_path, [0.001, 0.004, 0.002])
    test, src = _sibling_uncertainty(load_modes(path), path)
    assert src == tmp_path / "modes.json"
    fs = _freq_sigma(None, test, path)
    assert np.allclose(fs, [1e-4, 2e-4, 5e-5])
    text = _weights_text(test, fs, None, path, src)
    assert "modes.json beside modes.uff" in text and "assumption" not in text


def test_a_modes_json_of_other_modes_is_not_used_and_the_one_percent_is_called_an_assumption(tmp_path, caplog):
    from modalab.app.stages._common import load_modes
    from modalab.app.stages._update import _sibling_uncertainty, _weights_text

    other = _modes([0.001, 0.004, 0.002])
    other.freq_hz = other.freq_hz * 1.001                 # another identification run
    path = _write_pair(tmp_path, None, json_modes=other)
    with caplog.at_level(logging.WARNING):
        test, src = _sibling_uncertainty(load_modes(path), path)
        fs = _freq_sigma(None, test, path)
    assert src is None and fs is None
    assert "holds other modes" in caplog.text
    text = _weights_text(test, fs, None, path, src)
    assert text.startswith("relative sigma 0.01 for every test mode: an assumption") and "modes.uff" in text
    (tmp_path / "modes.json").unlink()                   # nothing beside it: the same assumption, said so
    test, src = _sibling_uncertainty(load_modes(path), path)
    assert src is None and "assumption" in _weights_text(test, _freq_sigma(None, test, path), None, path, src)
