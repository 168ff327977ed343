"""Damping models beyond element viscous dampers and element ``ge``.

* :class:`ModalDampingTable` — damping as a function of natural frequency,
  like Nastran TABDMP1 (``kind`` 'CRIT' ζ, 'G' structural g = 2ζ, 'Q' quality
  factor Q = 1/(2ζ)), linearly interpolated, held constant outside the table.
* :func:`rayleigh_coefficients` / :func:`rayleigh` — proportional damping
  C = αM + βK with ζ(ω) = α/(2ω) + βω/2 through two (frequency, ζ) points.
* :func:`modal_damping_matrix` — the viscous matrix that gives chosen modal
  damping ratios to a set of mass-normalised modes,
  C = M Φ diag(2 ζ_r ω_r) Φᵀ M (exact on the modes in Φ, zero on the rest).
* :func:`own_loss_exempt` — a model whose PARAM G damps the structure but not the scalar springs that
  declare a loss factor of their own (mounts), for fitting G without moving theirs.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from modalab.core.errors import ModalabValueError

from updating.fe.elements.spring import Spring

__all__ = ["ModalDampingTable", "rayleigh_coefficients", "rayleigh", "modal_damping_matrix", "own_loss_exempt"]


@dataclass(frozen=True)
class ModalDampingTable:
    """ζ(f) table (TABDMP1).  ``freq_hz`` ascending; ``values`` in the unit of ``kind``."""

    freq_hz: tuple
    values: tuple
    kind: str = "CRIT"

    def __post_init__(self):
        f = np.asarray(self.freq_hz, float)
        v = np.asarray(self.values, float)
        if f.ndim != 1 or f.shape != v.shape or f.size == 0:
            raise ModalabValueError(f"modal damping table: {f.size} frequencies and {v.size} values; give equal, "
                                    "non-empty lists")
        if np.any(np.diff(f) < 0):
            raise ModalabValueError("modal damping table frequencies must ascend (as TABDMP1 requires)")
        if self.kind.upper() not in ("CRIT", "G", "Q"):
            raise ModalabValueError(f"modal damping kind {self.kind!r}; expected 'CRIT', 'G' or 'Q'")
        object.__setattr__(self, "kind", self.kind.upper())

    def zeta(self, freq_hz) -> np.ndarray:
        """Viscous damping ratio ζ at the given natural frequencies (Hz)."""
        v = np.interp(np.asarray(freq_hz, float), np.asarray(self.freq_hz, float), np.asarray(self.values, float))
        if self.kind == "G":
            return v / 2.0
        if self.kind == "Q":
            with np.errstate(divide="ignore"):
                return np.where(v > 0, 1.0 / (2.0 * v), 0.0)
        return v


def rayleigh_coefficients(f1_hz: float, zeta1: float, f2_hz: float, zeta2: float) -> tuple[float, float]:
    """(α, β) such that C = αM + βK gives ζ1 at f1 and ζ2 at f2."""
    w1, w2 = 2 * np.pi * f1_hz, 2 * np.pi * f2_hz
    if not (w1 > 0 and w2 > 0 and w1 != w2):
        raise ModalabValueError(f"Rayleigh damping needs two distinct positive frequencies; got {f1_hz}, {f2_hz} Hz")
    A = np.array([[1 / (2 * w1), w1 / 2], [1 / (2 * w2), w2 / 2]])
    a, b = np.linalg.solve(A, [zeta1, zeta2])
    return float(a), float(b)


def rayleigh(M, K, alpha: float, beta: float):
    """C = αM + βK (sparse)."""
    return sp.csr_matrix(alpha * M + beta * K)


def modal_damping_matrix(M, phi, omega, zeta):
    """C = M Φ diag(2 ζ ω) Φᵀ M for mass-normalised Φ (dense n×n; small models)."""
    phi = np.asarray(phi, float)
    w = np.asarray(omega, float)
    z = np.broadcast_to(np.asarray(zeta, float), w.shape)
    MP = M @ phi
    return (MP * (2 * z * w)[None, :]) @ MP.T


def own_loss_exempt(model):
    """A copy of ``model`` whose model-wide loss factor G (``global_ge``, PARAM G) damps the structure but not
    the scalar springs that declare a loss factor of their own (CELAS GE ≠ 0: elastomer mounts, isolators).
    Each such spring keeps the loss factor the deck gives it in all (its GE + the deck's PARAM G) whatever G
    becomes; it is listed in ``global_ge_exempt`` and assembled with ``D = ge·K`` alone.  At the deck's own G
    the matrices are the deck's.  Springs without a GE of their own, and springs added later (candidate
    physics), are damped by G as before.

    For a fit of G as the structure's background loss factor: a mount's GE is the mount's, not the frame
    material's.  With G added to it, a G fitted to the frame's modes moves the damping of the modes on the
    mounts too, and the fit trades one against the other (tuning case 1704 of the discovery benchmark, a
    frame on mounts of GE 0.08: G came out 0.0003 for the rail's 0.0066, and a local damping term on four
    elements made up the difference: a finding on physics the truth does not have)."""
    g0 = float(model.global_ge or 0.0)
    out = model.copy()
    exempt = set(model.global_ge_exempt)
    for eid, el in model.elements.items():
        if isinstance(el, Spring) and el.ge and eid not in exempt:
            out.elements[eid] = dataclasses.replace(el, ge=float(el.ge) + g0)
            exempt.add(eid)
    out.global_ge_exempt = frozenset(exempt)
    return out
