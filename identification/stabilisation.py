"""Stabilisation of poles across model orders.

A pole of order ``n`` is compared with one partner of the *previous evaluated
order* — the row directly below it in the diagram — the pole closest in the sum
of the three normalised differences below, on

* frequency:      ``|f_n − f_{n−1}| / f_{n−1} ≤ freq_tol``,
* damping:        ``|ζ_n − ζ_{n−1}| / ζ_{n−1} ≤ damping_tol``,
* participation:  ``MAC(l_n, l_{n−1}) ≥ mac_min``.

Every row of :class:`StabilisationDiagram` carries the model order it was
computed at (``order``), so a pole drawn at order ``n`` is the pole *of* order
``n``.  (sdypy-EMA stores order ``n`` in column ``n−1`` and compares it with
column ``n−2``; here there is no index arithmetic between rows and orders.)
With a single reference the participation vector is a scalar and the MAC test
is trivially true.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from modalab.core.errors import ModalabValueError, fmt_error

__all__ = ["StabilisationCriteria", "StabilisationDiagram", "stabilise", "mac_vectors", "pole_freq_damping"]


@dataclass(frozen=True)
class StabilisationCriteria:
    """Tolerances of the stabilisation tests (relative frequency, relative damping, participation MAC)."""

    freq_tol: float = 0.01
    damping_tol: float = 0.05
    mac_min: float = 0.98

    def __post_init__(self):
        for name, lo, hi in (("freq_tol", 0.0, 1.0), ("damping_tol", 0.0, 10.0), ("mac_min", 0.0, 1.0)):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and lo < v <= hi):
                raise ModalabValueError(fmt_error(f"StabilisationCriteria.{name}", v, f"a number in ({lo}, {hi}]",
                                                  "Defaults: freq_tol=0.01, damping_tol=0.05, mac_min=0.98"))


def pole_freq_damping(lam):
    """Undamped natural frequency (Hz) and damping ratio of poles ``λ`` (rad/s)."""
    lam = np.asarray(lam, complex)
    wn = np.abs(lam)
    with np.errstate(divide="ignore", invalid="ignore"):
        zeta = np.where(wn > 0, -lam.real / wn, 0.0)
    return wn / (2 * np.pi), zeta


def mac_vectors(A, B):
    """MAC between the columns of ``A`` (n, a) and ``B`` (n, b): ``|aᴴb|² / (aᴴa · bᴴb)``."""
    A = np.asarray(A)
    B = np.asarray(B)
    if A.shape[0] == 1 and B.shape[0] == 1:
        # scalars (one reference): |ab|²/(|a|²|b|²) = 1 unless one of them is zero
        return ((A[0] != 0)[:, None] & (B[0] != 0)[None, :]).astype(float)
    num = np.abs(A.conj().T @ B) ** 2
    den = np.real(np.sum(A.conj() * A, axis=0))[:, None] * np.real(np.sum(B.conj() * B, axis=0))[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0, num / den, 0.0)


@dataclass
class StabilisationDiagram:
    """All poles of all orders, flattened, with their stabilisation flags.

    Attributes (one entry per pole unless noted)
    ----------
    orders : (n_orders,) the evaluated model orders, ascending.
    order : model order the pole was computed at.
    lam : complex pole in rad/s (as estimated, before any window correction).
    freq_hz, damping : undamped natural frequency and damping ratio.
    participation : (n_in, n_poles) unit participation vectors.
    stable_freq, stable_damping, stable_vector : the three tests against the previous order.
    criteria : the :class:`StabilisationCriteria` used.
    """

    orders: np.ndarray
    order: np.ndarray
    lam: np.ndarray
    freq_hz: np.ndarray
    damping: np.ndarray
    participation: np.ndarray
    stable_freq: np.ndarray
    stable_damping: np.ndarray
    stable_vector: np.ndarray
    criteria: StabilisationCriteria = field(default_factory=StabilisationCriteria)

    @property
    def stable(self) -> np.ndarray:
        """Stable in frequency, damping and participation vector."""
        return self.stable_freq & self.stable_damping & self.stable_vector

    @property
    def status(self) -> np.ndarray:
        """One letter per pole: 's' stable, 'v' freq+vector, 'd' freq+damping, 'f' freq only, 'o' new."""
        s = np.full(self.order.shape, "o", dtype="<U1")
        s[self.stable_freq] = "f"
        s[self.stable_freq & self.stable_damping] = "d"
        s[self.stable_freq & self.stable_vector & ~self.stable_damping] = "v"
        s[self.stable] = "s"
        return s

    def at_order(self, n: int) -> np.ndarray:
        """Indices of the poles computed at model order ``n``."""
        if n not in set(self.orders.tolist()):
            raise ModalabValueError(f"order {n} was not evaluated; available {self.orders[0]}..{self.orders[-1]} "
                                    f"step {self.orders[1] - self.orders[0] if self.orders.size > 1 else 1}")
        return np.flatnonzero(self.order == n)

    def to_dict(self) -> dict:
        return {"orders": self.orders.tolist(), "order": self.order.tolist(), "freq_hz": self.freq_hz.tolist(),
                "damping": self.damping.tolist(), "status": self.status.tolist(),
                "criteria": {"freq_tol": self.criteria.freq_tol, "damping_tol": self.criteria.damping_tol,
                             "mac_min": self.criteria.mac_min}}


def stabilise(orders, poles, participation, criteria: StabilisationCriteria | None = None) -> StabilisationDiagram:
    """Flag each pole of ``poles[k]`` (order ``orders[k]``) against the poles of ``orders[k-1]``.

    ``poles`` is a list of complex arrays (rad/s), ``participation`` a list of
    ``(n_in, n_k)`` arrays, both aligned with ``orders``.
    """
    crit = criteria if criteria is not None else StabilisationCriteria()
    orders = np.asarray(orders, dtype=int)
    if len(poles) != orders.size or len(participation) != orders.size:
        raise ModalabValueError(f"{orders.size} orders but {len(poles)} pole sets and {len(participation)} "
                                "participation sets; give one of each per order")
    n_in = participation[0].shape[0] if participation else 1
    cols = {k: [] for k in ("order", "lam", "f", "z", "L", "sf", "sd", "sv")}
    prev = None
    for n, lam, L in zip(orders, poles, participation):
        lam = np.asarray(lam, complex)
        f, z = pole_freq_damping(lam)
        m = lam.size
        sf = np.zeros(m, bool)
        sd = np.zeros(m, bool)
        sv = np.zeros(m, bool)
        if prev is not None and prev[0].size and m:
            fp, zp, Lp = prev
            with np.errstate(divide="ignore", invalid="ignore"):
                rf = np.abs(f[:, None] - fp[None, :]) / (crit.freq_tol * np.abs(fp[None, :]))
                rd = np.abs(z[:, None] - zp[None, :]) / (crit.damping_tol * np.abs(zp[None, :]))
            # scalar, nonzero participations (one reference): MAC = 1, the vector term is zero
            scalar = L.shape[0] == 1 and np.all(L != 0) and np.all(Lp != 0)
            rv = None if scalar else (1.0 - mac_vectors(L, Lp)) / max(1.0 - crit.mac_min, 1e-12)
            rf[np.isnan(rf)] = np.inf                                      # 0/0: never stable
            rd[np.isnan(rd)] = np.inf
            # each pole is tested against ONE partner of the previous order: the pole closest in the
            # combined normalised distance (so dense noise poles cannot pass by picking different
            # partners for different tests, and shadow poles of close modes pair correctly)
            tot = np.minimum(rf, 1e6)
            tot += np.minimum(rd, 1e6)
            if rv is not None:
                tot += np.minimum(rv, 1e6)
            j = np.argmin(tot, axis=1)
            i = np.arange(m)
            sf = rf[i, j] <= 1.0
            sd = sf & (rd[i, j] <= 1.0)
            sv = sf.copy() if rv is None else sf & (rv[i, j] <= 1.0)
        cols["order"].append(np.full(m, n))
        cols["lam"].append(lam)
        cols["f"].append(f)
        cols["z"].append(z)
        cols["L"].append(L)
        cols["sf"].append(sf)
        cols["sd"].append(sd)
        cols["sv"].append(sv)
        prev = (f, z, L)
    cat = lambda k, dt: np.concatenate(cols[k]).astype(dt) if cols[k] else np.zeros(0, dt)  # noqa: E731
    Lall = np.concatenate(cols["L"], axis=1) if cols["L"] else np.zeros((n_in, 0), complex)
    return StabilisationDiagram(orders=orders, order=cat("order", int), lam=cat("lam", complex),
                                freq_hz=cat("f", float), damping=cat("z", float), participation=Lall,
                                stable_freq=cat("sf", bool), stable_damping=cat("sd", bool),
                                stable_vector=cat("sv", bool), criteria=crit)
