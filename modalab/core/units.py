"""Units and FRF quantities.

Inside modalab everything is SI: metres, seconds, newtons, kilograms, radians.
Frequencies in names ending ``_hz`` are in Hz, ``omega`` is in rad/s.

FRF quantities and their conversion factors (for a translational response per
unit force): receptance X/F [m/N], mobility V/F [m/s/N] = iω·X/F, accelerance
A/F [m/s²/N] = -ω²·X/F.
"""
from __future__ import annotations

import numpy as np

from .errors import ModalabValueError

__all__ = ["QUANTITIES", "QUANTITY_UNITS", "check_quantity", "quantity_factor", "G", "to_si"]

G = 9.80665  # standard gravity, m/s^2

QUANTITIES = ("receptance", "mobility", "accelerance")
#: derivative order of each quantity relative to displacement
_ORDER = {"receptance": 0, "mobility": 1, "accelerance": 2}
QUANTITY_UNITS = {"receptance": "m/N", "mobility": "m/s/N", "accelerance": "m/s^2/N"}

_ALIASES = {"compliance": "receptance", "displacement": "receptance", "dynamic compliance": "receptance",
            "admittance": "receptance", "velocity": "mobility", "acceleration": "accelerance",
            "inertance": "accelerance"}

# unit name -> factor to SI
_UNIT_FACTORS = {
    "m": 1.0, "mm": 1e-3, "um": 1e-6, "in": 0.0254,
    "m/s": 1.0, "mm/s": 1e-3, "in/s": 0.0254,
    "m/s^2": 1.0, "m/s2": 1.0, "m/s**2": 1.0, "mm/s^2": 1e-3, "g": G, "in/s^2": 0.0254,
    "N": 1.0, "kN": 1e3, "lbf": 4.4482216152605,
    "V": 1.0, "mV": 1e-3,
}


def check_quantity(quantity: str) -> str:
    """Normalise a quantity name; raise a clear error for an unknown one."""
    q = str(quantity).strip().lower()
    q = _ALIASES.get(q, q)
    if q not in QUANTITIES:
        raise ModalabValueError(
            f"unknown FRF quantity {quantity!r}; expected one of {', '.join(QUANTITIES)}. "
            "Use 'accelerance' for acceleration per force (m/s^2/N)")
    return q


def quantity_factor(src: str, dst: str, omega) -> np.ndarray:
    """Factor ``(i·omega)**(order(dst) - order(src))`` converting src FRFs to dst.

    Where the factor divides by zero (omega = 0) the result is NaN: the
    quantity is undefined there.
    """
    n = _ORDER[check_quantity(dst)] - _ORDER[check_quantity(src)]
    s = 1j * np.asarray(omega, dtype=float)
    if n >= 0:
        return s ** n
    with np.errstate(divide="ignore", invalid="ignore"):
        f = 1.0 / s ** (-n)
    f[~np.isfinite(f)] = np.nan
    return f


def to_si(value, unit: str):
    """Scale ``value`` given in ``unit`` to SI (``'g'`` → m/s², ``'mm'`` → m...)."""
    u = unit.strip()
    if u not in _UNIT_FACTORS:
        raise ModalabValueError(
            f"unknown unit {unit!r}; expected one of {', '.join(sorted(_UNIT_FACTORS))}. "
            "Convert the data to SI before loading it")
    return np.asarray(value) * _UNIT_FACTORS[u]
