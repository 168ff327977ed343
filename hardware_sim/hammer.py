"""The impact hammer: pulse shape from the tip stiffness, scatter, double hits.

A hammer of mass ``m`` striking through a tip of contact stiffness ``k`` behaves,
during contact, like a mass on a spring: the force is a half-sine lasting half
a period, ``T = π √(m/k)``.  Harder tips give shorter pulses and a wider
force spectrum (its first zero lies at ``1.5/T``).  Typical values for a
0.16 kg modal hammer (PCB 086C03 class):

======  ===================  ==================  ===================
tip     stiffness (N/m)      contact time        first spectral zero
======  ===================  ==================  ===================
hard    4.0e7 (steel)        0.20 ms             7.5 kHz
medium  2.5e6 (plastic)      0.79 ms             1.9 kHz
soft    1.6e5 (rubber)       3.1 ms              0.48 kHz
======  ===================  ==================  ===================

A manual hit scatters in peak force (log-normal, ``force_scatter`` relative),
in width (``width_scatter``) and in placement (``placement_scatter_m``), and
rebounds into a second, weaker hit with ``double_hit_probability``.  An
automatic hammer (``automatic=True``) fires a requested force with
``automatic_force_scatter`` and never double-hits (its rebound catcher).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from modalab.core.errors import ModalabValueError

__all__ = ["Hammer", "Pulse", "TIP_STIFFNESS_N_PER_M", "contact_time_s"]

#: contact stiffness of the standard tips, N/m
TIP_STIFFNESS_N_PER_M = {"hard": 4.0e7, "medium": 2.5e6, "soft": 1.6e5}


def contact_time_s(mass_kg: float, stiffness_n_per_m: float) -> float:
    """Half-sine contact time ``T = π √(m/k)`` in s."""
    if not (mass_kg > 0 and stiffness_n_per_m > 0):
        raise ModalabValueError(f"hammer mass {mass_kg!r} kg and tip stiffness {stiffness_n_per_m!r} N/m "
                                "must both be positive")
    return math.pi * math.sqrt(mass_kg / stiffness_n_per_m)


@dataclass(frozen=True)
class Pulse:
    """One half-sine of a hit: start ``delay_s`` after the first pulse, peak ``amplitude_n``, ``width_s``."""

    delay_s: float
    amplitude_n: float
    width_s: float


@dataclass(frozen=True)
class Hammer:
    """A modal impact hammer (manual or automatic).

    mass_kg : moving mass of the hammer head.
    tip : 'hard', 'medium' or 'soft' (see the module table).
    tip_stiffness_n_per_m : overrides ``tip`` with an explicit contact stiffness.
    force_n : nominal peak force of a manual hit (N).
    force_scatter : relative (log-normal) scatter of the peak force of manual hits.
    width_scatter : relative scatter of the contact time.
    placement_scatter_m : rms distance by which a manual hit misses the point.
    double_hit_probability : chance that a manual hit rebounds into a second hit.
    double_hit_delay_s : (min, max) delay of the second hit after the first.
    double_hit_ratio : (min, max) peak of the second hit relative to the first.
    automatic : an automatic (solenoid) hammer that fires on command.
    automatic_force_scatter : relative force scatter of the automatic hammer.
    """

    mass_kg: float = 0.16
    tip: str = "medium"
    tip_stiffness_n_per_m: float | None = None
    force_n: float = 200.0
    force_scatter: float = 0.15
    width_scatter: float = 0.03
    placement_scatter_m: float = 0.003
    double_hit_probability: float = 0.0
    double_hit_delay_s: tuple = (0.004, 0.02)
    double_hit_ratio: tuple = (0.1, 0.5)
    automatic: bool = False
    automatic_force_scatter: float = 0.01

    def __post_init__(self):
        if self.tip_stiffness_n_per_m is None and self.tip not in TIP_STIFFNESS_N_PER_M:
            raise ModalabValueError(f"hammer tip {self.tip!r} unknown; expected one of "
                                    f"{', '.join(TIP_STIFFNESS_N_PER_M)} or give tip_stiffness_n_per_m")
        contact_time_s(self.mass_kg, self.stiffness_n_per_m)
        if not self.force_n > 0:
            raise ModalabValueError(f"hammer force_n={self.force_n!r} N must be positive")
        for name in ("force_scatter", "width_scatter", "placement_scatter_m", "automatic_force_scatter"):
            if getattr(self, name) < 0:
                raise ModalabValueError(f"hammer {name}={getattr(self, name)!r} must be >= 0")
        if not 0 <= self.double_hit_probability <= 1:
            raise ModalabValueError(f"double_hit_probability={self.double_hit_probability!r} must lie in [0, 1]")
        lo, hi = self.double_hit_delay_s
        if not 0 < lo <= hi:
            raise ModalabValueError(f"double_hit_delay_s={self.double_hit_delay_s!r} must be (min, max) with "
                                    "0 < min <= max, in s")
        lo, hi = self.double_hit_ratio
        if not 0 < lo <= hi:
            raise ModalabValueError(f"double_hit_ratio={self.double_hit_ratio!r} must be (min, max) "
                                    "with 0 < min <= max")

    @property
    def stiffness_n_per_m(self) -> float:
        """Contact stiffness of the tip in N/m."""
        if self.tip_stiffness_n_per_m is not None:
            return float(self.tip_stiffness_n_per_m)
        return TIP_STIFFNESS_N_PER_M[self.tip]

    @property
    def contact_time_s(self) -> float:
        """Nominal pulse width ``π √(m/k)`` in s."""
        return contact_time_s(self.mass_kg, self.stiffness_n_per_m)

    @property
    def max_width_s(self) -> float:
        """A width no pulse exceeds (5 sigma of the width scatter)."""
        return self.contact_time_s * math.exp(5 * self.width_scatter)

    def draw_pulses(self, rng: np.random.Generator, force_n: float | None = None,
                    force_double: bool = False) -> tuple[Pulse, ...]:
        """Pulses of one hit.  Always draws the same number of random numbers (determinism).

        ``force_n`` overrides the nominal force; ``force_double`` forces a double
        hit (fault injection) whatever ``double_hit_probability`` says.
        """
        nominal = self.force_n if force_n is None else float(force_n)
        if not nominal > 0:
            raise ModalabValueError(f"force {force_n!r} N must be positive")
        z = rng.standard_normal(2)
        u = rng.random(3)
        if self.automatic:
            amp = nominal * math.exp(self.automatic_force_scatter * z[0])
            width = self.contact_time_s * math.exp(min(self.width_scatter, 0.01) * z[1])
            double = force_double
        else:
            amp = nominal * math.exp(self.force_scatter * z[0] - 0.5 * self.force_scatter ** 2)
            width = self.contact_time_s * math.exp(self.width_scatter * z[1])
            double = force_double or bool(u[0] < self.double_hit_probability)
        pulses = [Pulse(0.0, amp, width)]
        if double:
            lo, hi = self.double_hit_delay_s
            delay = max(lo + (hi - lo) * u[1], 1.5 * width)
            rlo, rhi = self.double_hit_ratio
            ratio = rlo + (rhi - rlo) * u[2]
            # the second contact is softer in speed, hence a little longer (Hertz: T ∝ v^-1/5)
            pulses.append(Pulse(delay, amp * ratio, width * ratio ** -0.2))
        return tuple(pulses)

    def draw_placement(self, rng: np.random.Generator) -> tuple[float, float]:
        """Miss distance (m, ≥ 0) and a uniform number for choosing its direction."""
        z = rng.standard_normal()
        u = rng.random()
        sigma = 0.0 if self.automatic else self.placement_scatter_m
        return abs(sigma * z), u
