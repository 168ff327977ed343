"""The leakage bound of the diagnosis' lines (``fit.decay_leakage``): a mode that has not died out at the end of
the record leaves a relative error ``e^{−(σ + β) T}`` at the lines it dominates (issue 14: without the
exponential window the exact model's χ²/N was 6.4 on the bar chain, from the lightly damped low modes)."""
from __future__ import annotations

import numpy as np
import pytest

from modalab.core.frf import FRF
from updating.diagnosis.fit import decay_leakage

DF = 0.25
T = 1 / DF


def _sdof(beta, estimator="H1"):
    f = np.arange(1, 400) * DF
    s = 1j * 2 * np.pi * f + beta
    lam = complex(-0.3, 2 * np.pi * 12.0)                 # σ = 0.3 1/s: e^{−σT} = 0.30 in a 4 s record
    H = 1.0 / (s - lam) - 1.0 / (s - np.conj(lam))
    frf = FRF(freq_hz=f, H=H[None, None, :], responses=["1+Z"], references=["1+Z"], quantity="receptance",
              window_beta_per_s=beta, metadata={"estimator": estimator} if estimator else {})
    return frf, s, lam


@pytest.mark.parametrize("beta", [0.0, np.log(100) / T])
def test_bound_at_a_mode_is_its_decay_over_the_record(beta):
    frf, s, lam = _sdof(beta)
    b = decay_leakage(frf, s)
    at = np.argmin(np.abs(s.imag - lam.imag))
    assert b[at] == pytest.approx(np.exp(-(0.3 + beta) * T), rel=0.05)
    assert np.all(b <= np.exp(-(0.3 + beta) * T) * 1.0001)


def test_synthesised_frfs_get_no_bound():
    frf, s, _ = _sdof(0.0, estimator=None)
    assert not decay_leakage(frf, s).any()


def test_lines_without_a_finite_value_are_left_out_not_a_crash():
    frf, s, lam = _sdof(0.0)
    H = frf.H.copy()
    H[..., np.argmin(np.abs(s.imag - lam.imag)) + 1] = np.nan       # inside the peak's window
    bad = FRF(freq_hz=frf.freq_hz, H=H, responses=frf.responses, references=frf.references, quantity="receptance",
              metadata={"estimator": "H1"})
    b = decay_leakage(bad, s)
    assert b[np.argmin(np.abs(s.imag - lam.imag))] == pytest.approx(np.exp(-0.3 * T), rel=0.05)
