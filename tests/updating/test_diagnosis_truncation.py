"""The tails a record cuts off (``updating.diagnosis.truncation.restore_tails``) and the FRF diagnosis of exact,
unwindowed data (issue 14 #2: without the exponential window the exact model's E and ρ moved by
−0.14..−0.27 %, 3.5-7.6 std, on the demo chain without noise).

The truth of the unit tests is not the formula of the module: the "measured" FRFs are the DFTs of sampled modal
impulse responses cut by a 4 s record that starts 0.0625 s before the impulse, and the truth is the same DFT of
a record 64 times longer, on the same lines."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from modalab.core.frf import FRF
from updating.diagnosis.truncation import restore_tails

FS, N, N0 = 256.0, 1024, 16                              # 4 s record, the impulse 0.0625 s in
#: (Hz, ζ): a bounce mode that keeps 78 % at 4 s, one that keeps 25 %, one 2 %, two that have died out
MODES = [(1.0, 0.01), (5.5, 0.01), (15.7, 0.01), (40.0, 0.01), (71.0, 0.01)]
PHI = np.array([[1.0, 0.6, -0.8, 0.5, 0.3], [0.4, -1.0, 0.7, 0.9, -0.6]])   # 2 responses, modal mass 1


def _record(n: int, beta: float = 0.0) -> np.ndarray:
    """Accelerance of the two responses to an impulse at sample N0 of an n-sample record (window e^{−β(t−t0)}),
    as the spectral estimate forms it: Δt · DFT(response) / DFT(impulse), on the lines of the n-sample record."""
    t = (np.arange(n) - N0) / FS
    acc = np.zeros((2, n))
    for (f, z), phi in zip(MODES, PHI.T):
        lam = -z * 2 * np.pi * f + 1j * 2 * np.pi * f * np.sqrt(1 - z * z)
        A = phi[:, None] * phi[0] / (2j * lam.imag)                # receptance residue, reference = response 0
        acc += np.where(t >= 0, 2 * np.real(A * lam ** 2 * np.exp(lam * np.maximum(t, 0))), 0.0)
    acc *= np.exp(-beta * np.maximum(t, 0))
    k = np.arange(n // 2 + 1)
    return np.fft.rfft(acc, axis=1) / FS / np.exp(-2j * np.pi * k * N0 / n)


def _frf(H, beta=0.0):
    f = np.arange(H.shape[-1]) * FS / N
    return FRF(freq_hz=f[1:], H=H[:, None, 1:], responses=["1+Z", "2+Z"], references=["1+Z"],
               quantity="accelerance", metadata={"estimator": "H1"}, window_beta_per_s=beta)


@pytest.fixture(scope="module")
def cut_and_truth():
    return _frf(_record(N)), _frf(_record(64 * N)[:, ::64])


def _err(H, truth, lo, hi):
    sel = (truth.freq_hz >= lo) & (truth.freq_hz < hi)
    return float(np.linalg.norm(H[..., sel] - truth.H[..., sel]) / np.linalg.norm(truth.H[..., sel]))


def test_the_cut_tails_are_restored_to_the_long_record(cut_and_truth):
    cut, truth = cut_and_truth
    assert _err(cut.H, truth, 4, 10) > 0.1                 # the cut: 25 % of the 5.5 Hz mode
    r = restore_tails(cut)
    assert r.t0 == pytest.approx(N0 / FS, abs=2e-3)
    assert sorted(np.round(r.poles.imag / (2 * np.pi), 1)) == [1.0, 5.5, 15.7]
    # the bounce mode keeps 78 % past the record: its lines (up to halfway to 5.5 Hz) are to be left out
    assert r.cut_hz == pytest.approx((1.0 + 5.5) / 2, abs=0.1)
    # measured: 22 % -> 0.03 % at 1.5-4 Hz, 25.6 % -> 0.005 % at 4-10 Hz, 2.2 % -> 0.01 % at 10-30 Hz
    for lo, hi in ((1.5, 4), (4, 10), (10, 30), (30, 100)):
        assert _err(r.frf.H, truth, lo, hi) < 0.1 * max(_err(cut.H, truth, lo, hi), 0.005), (lo, hi)


def test_a_windowed_record_is_left_alone():
    beta = np.log(100) / (N / FS)                          # the usual window: 1 % left at the record's end
    frf = _frf(_record(N, beta), beta)
    r = restore_tails(frf)
    assert r.poles.size == 0 and r.cut_hz == 0 and r.frf is frf


def test_synthesised_frfs_are_left_alone(cut_and_truth):
    cut, _ = cut_and_truth
    syn = dataclasses.replace(cut, metadata={}) if dataclasses.is_dataclass(cut) else cut._replace(metadata={})
    assert restore_tails(syn).poles.size == 0

