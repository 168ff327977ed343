"""Synthetic FRFs with known modes, for tests, benchmarks and demonstrations.

:func:`modal_system` builds a proportionally damped :class:`modalab.ModalModel`
by modal superposition from chosen natural frequencies, damping ratios and
(mass-normalised) mode shapes; :func:`noisy_frf` samples its FRFs and adds
complex Gaussian noise scaled to the RMS of each FRF.
"""
from __future__ import annotations

import numpy as np

from modalab.core.dof import parse_dofs
from modalab.core.errors import ModalabValueError
from modalab.core.frf import FRF
from modalab.core.structure import ModalModel

__all__ = ["modal_system", "noisy_frf", "TEN_MODES_HZ", "TEN_MODES_DAMPING"]

#: the 10-mode reference case of the identification tests (close pair 240/247 Hz)
TEN_MODES_HZ = np.array([42.0, 95.0, 151.0, 240.0, 247.0, 333.0, 418.0, 560.0, 702.0, 861.0])
TEN_MODES_DAMPING = np.array([0.010, 0.008, 0.012, 0.006, 0.012, 0.009, 0.011, 0.007, 0.010, 0.008])


def modal_system(freq_hz, damping, n_dof: int = 30, *, shapes=None, rng=None, window_beta: float = 0.0):
    """Pole–residue model with viscous modal damping; returns ``(ModalModel, shapes)``.

    ``shapes`` (n_dof, n_modes) are mass-normalised; random N(0, 0.3²) by
    default.  With ``window_beta`` every pole is moved by ``−β`` (the effect of
    an exponential window ``e^{−βt}`` on the impulse response), residues unchanged.
    """
    fn = np.atleast_1d(np.asarray(freq_hz, float))
    z = np.broadcast_to(np.asarray(damping, float), fn.shape)
    if np.any(fn <= 0) or np.any((z < 0) | (z >= 1)):
        raise ModalabValueError("modal_system needs positive frequencies and damping ratios in [0, 1)")
    rng = np.random.default_rng(rng)
    phi = rng.normal(scale=0.3, size=(n_dof, fn.size)) if shapes is None else np.asarray(shapes, float)
    w = 2 * np.pi * fn
    s1 = -z * w + 1j * w * np.sqrt(1 - z ** 2)
    gap = s1 - s1.conj()
    poles = np.concatenate([s1, s1.conj()]) - float(window_beta)
    right = np.concatenate([phi / gap, -phi / gap], axis=1).astype(complex)
    left = np.concatenate([phi.T, phi.T], axis=0).astype(complex)
    dofs = parse_dofs([f"{k + 1}+Z" for k in range(phi.shape[0])])
    return ModalModel(poles=poles, right=right, left=left, rigid=np.zeros((phi.shape[0], 0)), dofs=dofs), phi


def noisy_frf(model: ModalModel, freq_hz, references, *, noise: float = 0.015, quantity: str = "accelerance",
              rng=None, responses=None) -> FRF:
    """FRFs of ``model`` plus complex noise of standard deviation ``noise × RMS`` of each FRF."""
    F = model.frf(np.asarray(freq_hz, float), responses=responses, references=references, quantity=quantity)
    rng = np.random.default_rng(rng)
    rms = np.sqrt(np.mean(np.abs(F.H) ** 2, axis=-1, keepdims=True))
    e = (rng.normal(size=F.H.shape) + 1j * rng.normal(size=F.H.shape)) / np.sqrt(2)
    return F._replace(H=F.H + noise * rms * e, metadata={"estimator": "synthetic", "noise": noise})
