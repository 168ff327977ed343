"""Poly-reference least-squares complex-frequency estimator (pLSCF, "PolyMAX").

Model
-----
A right matrix-fraction description on the z-domain, all references at once
(Guillaume et al. 2003, "A poly-reference implementation of the least-squares
complex frequency-domain estimator", IMAC XXI; Peeters et al. 2004, "The
PolyMAX frequency-domain method: a new standard for modal parameter
estimation?", Shock and Vibration 11):

    H_o(ω) ≈ N_o(ω) A(ω)⁻¹,   N_o(ω) = Σ_r Ω_r(ω) β_or,   A(ω) = Σ_r Ω_r(ω) α_r,

with ``Ω_r(ω) = z^r``, ``z = exp(iωΔt)``, ``Δt = 1/(2 f_max)``, real
coefficients ``β_or`` (1 × n_in) and ``α_r`` (n_in × n_in), one numerator row
per output and a common denominator matrix.  The linearised weighted error
``E_o(ω_k) = w_o(ω_k) [Ω(ω_k) β_o − H_o(ω_k) ⊗ Ω(ω_k) α]`` leads to the normal
equations with the blocks

    R_o = Re(Γ_oᴴΓ_o),  S_o = Re(Γ_oᴴΥ_o),  T_o = Re(Υ_oᴴΥ_o),

and, after eliminating every numerator, to the *reduced* normal equations
(Peeters 2004, eq. 6)

    M α = 0,    M = 2 Σ_o (T_o − S_oᵀ R_o⁻¹ S_o).

Because ``Ω_r`` are powers of ``z`` on the unit circle, every block is
Toeplitz in the order index: each is built from 2p+1 "lag" sums, one matrix
product over the frequency lines for all outputs at once.  ``M`` is built
once, for the highest order ``p``; the reduced matrix of a lower order ``n`` is
taken as its leading ``(n+1)·n_in`` block (the denominator of order ``n`` with
the numerators kept at order ``p``), so no order rebuilds anything.  The
constraint ``α_n = I`` (PolyMAX) gives ``α_0..α_{n-1}`` from a linear solve —
for all orders from one Cholesky factor of ``M`` (one triangular solve per order) —,
the poles are the eigenvalues of the block companion matrix and each modal
participation vector ``l`` spans the left null space of ``A(z_pole)``.

With one reference the denominator is a scalar polynomial, and from degree 76 on its
roots are tracked from the previous evaluated order instead (:func:`denominator_roots`):
a simultaneous Aberth–Ehrlich iteration started at the previous roots, whose result is
accepted only when disjoint Newton inclusion discs prove that every root was found once
(else the companion eigenvalues are taken).  It costs O(n²) per order instead of the
O(n³) of the eigenvalues, which dominate a sweep to high orders.

Memory holds the lag sums (accumulated over chunks of lines), one chunk of
``S_o`` blocks (bounded to a few tens of MB) and ``M``: it does not grow with the
order beyond the reduced matrix.
"""
from __future__ import annotations

import dataclasses
import logging

import numpy as np

from modalab.core.errors import ModalabValueError, NotFittedError, fmt_error
from modalab.core.frf import FRF
from .stabilisation import mac_vectors
from .stabilisation import StabilisationCriteria, stabilise
from .selection import SelectionOptions, select_poles
from .indicators import mpc
from .lsfd import lsfd, modes_from_poles, pole_uncertainty, refine_poles
from .stabilisation import pole_freq_damping
# the numerics live in two modules (re-exported here: this stays the import path of every name below)
from .polymax_normal import _WEIGHTINGS, frequency_weights, reduced_normal_matrix
from .polymax_roots import (_cholesky, _companion_roots, _denominator, _roots_at_order, _to_poles,  # noqa: F401
                            aberth_roots, denominator_roots, poles_at_order)

log = logging.getLogger(__name__)

__all__ = ["PolyMAX", "frequency_weights", "reduced_normal_matrix", "poles_at_order", "denominator_roots",
           "aberth_roots"]


# --------------------------------------------------------------------------- automatic selection helpers
def duplicate_shapes(freq_hz, psi, cluster_size, distance: float, mac_min: float) -> np.ndarray:
    """True for automatic picks that repeat a nearby pick's shape: within ``distance`` in relative frequency
    and shape MAC >= ``mac_min`` of a pick with a larger cluster (ties: the lower frequency stays)."""

    f = np.asarray(freq_hz, float)
    m = f.size
    dup = np.zeros(m, bool)
    if m < 2:
        return dup
    mac = mac_vectors(psi, psi)
    rank = np.lexsort((f, -np.asarray(cluster_size)))             # larger clusters first, then lower frequency
    for a in rank:
        if dup[a]:
            continue
        near = (np.abs(f - f[a]) < distance * f[a]) & (mac[a] >= mac_min) & ~dup
        near[a] = False
        if near.any():
            log.info("automatic selection: %d pick(s) near %.4g Hz repeat its shape (MAC >= %g): one mode",
                     int(near.sum()), f[a], mac_min)
        dup |= near
    return dup


def combined_std(unc: dict, selected, refined=None) -> dict:
    """Standard deviations of frequency and damping: FRF noise plus the spread of the pole over orders.

    ``σ² = σ_noise² + σ_orders²``.  ``σ_noise`` from :func:`~identification.lsfd.pole_uncertainty`: the
    variance of the FRF across averages (``FRF.variance``, or from coherence) propagated to the refined
    pole.  ``σ_orders`` stands for the model error the noise does not see, from ``s`` the standard
    deviation of the mode's stable poles over the upper third of its orders and ``n`` their number
    (:func:`~identification.selection.order_spread`):

    * a pole reported as the stabilisation diagram gives it (not refined, or the refinement was
      turned down): ``σ_orders = s/√n``, the standard error of the estimate over the model orders;
    * a refined pole: ``σ_orders = min(s/√n, √max(χ², 1)·σ_noise)`` (χ² the ``chi2_ratio`` of its local
      fit).  The refined pole is not the diagram's average over orders: it minimises the misfit on its own
      band, with the neighbours and the band's residual terms in the model, so the diagram's spread bounds
      its model error only loosely.  Where the local fit leaves no misfit beyond the noise (χ² ≈ 1), a
      model error much larger than ``σ_noise`` would show in the residual, hence the cap.  Measured on the
      roving plate (tests/identification/roving_plate.py: analyser H1 and coherence from 5 hits, 14 modes,
      336 (mode, seed) pairs per set): on seeds 101-147 odd (used to choose the cap) ±1σ held 60 % (frequency)
      / 57 % (damping) of the truths with ``σ_noise`` alone, 76 % / 74 % with the uncapped ``s/√n`` (100 % at
      the close pair and the two modes below the band edge, whose diagram poles wander over the orders
      3-40 times more than the noise explains), 69 % / 68 % with the cap; on fresh seeds 201-247 odd,
      measured once after the choice: 65 % / 63 % noise alone, 73.5 % / 71 % with the cap (±2σ: 97 % / 98 %).

    A mode without an order spread (fewer than two poles) keeps the noise term alone.  ``refined``
    (bool per mode) says which poles are refined; ``None``: all are.  The coverage is tested in
    ``tests/identification/test_uncertainty_coverage.py``.

    Returns the indicators ``freq_std_hz``, ``damping_std`` (total), ``freq_std_noise_hz``,
    ``damping_std_noise``, ``freq_std_orders_hz``, ``damping_std_orders`` (the order terms as used) and
    ``chi2_ratio``.
    """
    n = np.maximum(np.asarray(selected.n_spread, float), 1.0)
    fo = np.where(np.isfinite(selected.freq_spread_hz), selected.freq_spread_hz / np.sqrt(n), 0.0)
    zo = np.where(np.isfinite(selected.damping_spread), selected.damping_spread / np.sqrt(n), 0.0)
    fnz, znz = np.asarray(unc["freq_std_hz"], float), np.asarray(unc["damping_std"], float)
    chi2 = np.asarray(unc["chi2_ratio"], float)
    ref = np.ones(fo.size, bool) if refined is None else np.asarray(refined, bool)
    k = np.sqrt(np.maximum(np.where(np.isfinite(chi2), chi2, 1.0), 1.0))
    cap = ref & np.isfinite(fnz) & np.isfinite(znz)
    fo = np.where(cap, np.minimum(fo, k * fnz), fo)
    zo = np.where(cap, np.minimum(zo, k * znz), zo)
    return {"freq_std_hz": np.hypot(fnz, fo), "damping_std": np.hypot(znz, zo),
            "freq_std_noise_hz": fnz, "damping_std_noise": znz,
            "freq_std_orders_hz": fo, "damping_std_orders": zo, "chi2_ratio": chi2}


#: a mode "may be a pair" when its residues fail the rank-one test at this p-value ...
PAIR_P = 1e-6
#: ... and the part beyond rank one holds at least this fraction of the mode's fitted energy
PAIR_FRACTION = 0.05


def may_be_pair(unc: dict) -> np.ndarray:
    """Modes whose residues are not of rank one: a close pair merged into one pole (bool per mode).

    One mode has residues ``A = ψ lᵀ`` of rank one; two modes closer than the pole estimate can separate
    (e.g. 0.015 % apart, 1 % damping) share one pole and give a residue matrix of rank two, which the
    local LSFD problem detects (:meth:`~identification.lsfd_refine._LocalProjection.rank_one_test`).
    Two conditions: the F test rejects rank one (``rank2_p < PAIR_P``) *and* the part beyond rank one
    carries at least ``PAIR_FRACTION`` = 5 % of the mode's energy (a second mode with residues of at least
    ~22 % of the first): a mode fitted slightly imperfectly (leakage, windows, a weak mode near strong
    ones) also fails the F test when the noise is low.  Measured: on the roving plate and roving_lab
    (exact local model) F ≈ 0.7-2.7 and fraction < 4e-5 on every mode including their separated 0.3 %
    pairs; on the demo's FRFs (simulated lab) the merged 36.566/36.572 Hz pair has F ≈ 2.5e4 and fraction
    0.063 (its participations at the three references are 4x apart: (0.014/0.056)² = 0.06), single modes
    F 2-65 with fraction ≤ 4e-4 except the weakly observed 53 Hz mode (0.028).  Needs several
    references (NaN test: False).
    """
    p = np.asarray(unc.get("rank2_p"), float)
    frac = np.asarray(unc.get("rank2_fraction"), float)
    return np.isfinite(p) & (p < PAIR_P) & np.isfinite(frac) & (frac >= PAIR_FRACTION)


# --------------------------------------------------------------------------- estimator
def _keep_consistent_refinement(lam_diagram, lam_refined, max_change: float) -> np.ndarray:
    """The refined poles, except where the local refinement left the stabilisation diagram's estimate: a damping
    ratio changed by more than the factor ``max_change`` (either way) or a frequency moved by more than one
    half-power half-bandwidth (``ζ·f`` of the diagram's pole).  There the diagram's pole, stable over many
    orders, is kept: a local single-pole fit over several close modes merged into one pick converges to a
    compromise (the issue 14 data: 314.35 Hz with ζ 1.07 %, stable over 25 orders, refined to 311.5 Hz with
    ζ 4.4 % where three modes lie at 313.3-314.5 Hz)."""
    lam_d = np.asarray(lam_diagram, complex)
    lam_r = np.array(lam_refined, complex)
    if lam_d.size != lam_r.size or not lam_d.size:
        return lam_r
    fd, zd = pole_freq_damping(lam_d)
    fr, zr = pole_freq_damping(lam_r)
    ratio = zr / np.maximum(zd, 1e-12)
    off = (ratio > max_change) | (ratio < 1.0 / max_change) | (np.abs(fr - fd) > zd * fd)
    for k in np.flatnonzero(off):
        log.info("refinement of %.5g Hz (zeta %.3g %%) to %.5g Hz (zeta %.3g %%) left the stabilisation diagram's "
                 "estimate: the diagram's pole is kept", fd[k], 100 * zd[k], fr[k], 100 * zr[k])
    lam_r[off] = lam_d[off]
    return lam_r


def _poles_per_order(M: np.ndarray, orders, n_in: int, dt: float):
    """Poles (positive frequency, ascending) and participation vectors at every order, the roots of each order
    starting the next; and how many orders were solved by tracking vs eigenvalues."""
    poles, parts = [], []
    methods = {"tracked": 0, "eigvals": 0}
    z = None
    chol = _cholesky(M)
    for n in orders:
        z, L, how = _roots_at_order(M, int(n), n_in, start=z, chol=chol)
        methods[how] += 1
        lam, L = _to_poles(z, L, dt)
        up = lam.imag > 0
        lam, L = lam[up], L[:, up]
        o = np.argsort(lam.imag)
        poles.append(lam[o])
        parts.append(L[:, o])
    return poles, parts, methods


class PolyMAX:
    """Poly-reference LSCF (PolyMAX-style) modal parameter estimator.

    Parameters (stored only; :meth:`fit` does the work)
    ----------
    max_order : int
        Highest polynomial order ``p``; order ``n`` yields ``n·n_in`` poles.
    min_order, order_step : int
        Orders evaluated: ``min_order, min_order+step, ..., max_order``.
    weighting : None, 'coherence' or 'variance'
        Frequency weighting (:func:`frequency_weights`).
    band_hz : (lo, hi) or None
        Frequency band used; the whole FRF by default.
    criteria : :class:`~identification.stabilisation.StabilisationCriteria` or None (defaults).
    select : 'auto', a sequence of frequencies in Hz, or a path to a JSON/TOML selection file.
    selection : :class:`~identification.selection.SelectionOptions` or None (defaults).
    lower_residual, upper_residual : bool
        Residual terms in LSFD.
    refine : bool
        Refine each selected pole by variable-projection least squares on the lines around it
        (:func:`~identification.lsfd.refine_poles`) before the final LSFD.
    refine_max_change : float
        An automatic pick whose refinement changes the damping ratio by more than this factor, or moves the
        frequency by more than a half-power half-bandwidth, keeps the stabilisation diagram's pole (a merge of
        close modes makes the local single-pole fit drift; default 2).
    window_correction : bool
        Remove the exponential window's decay ``frf.window_beta_per_s`` (1/s) from the poles
        (:func:`acquisition.windows.correct_poles`).
    uncertainty : bool
        Standard deviations of the refined frequencies and damping ratios in ``modes_.indicators``:
        ``freq_std_hz``, ``damping_std`` — FRF noise (:func:`~identification.lsfd.pole_uncertainty`,
        first order, one Jacobian per mode) combined with the spread of the pole over the stable orders
        (:func:`combined_std`) —, their parts ``*_noise``/``*_orders`` and ``chi2_ratio``; the noise model
        used is ``modes_.metadata['pole_std_source']``.  NaN with ``refine=False`` (the std describes
        the refined estimate).

    Fitted attributes
    -----------------
    orders_ : (n_orders,) int — the model order of each row of the stabilisation data.
    poles_ : list of (n_k,) complex — upper-half-plane poles (rad/s) of each order, as estimated
        (before window correction).
    participation_ : list of (n_in, n_k) complex — participation vectors of those poles.
    stabilisation_ : :class:`~identification.stabilisation.StabilisationDiagram`.
    selected_ : :class:`~identification.selection.SelectedPoles` (measured poles, linear pLSCF estimates).
    refined_poles_ : (n_modes,) complex — the selected poles after refinement (equal to
        ``selected_.lam`` with ``refine=False``), before window correction.
    lsfd_ : :class:`~identification.lsfd.LSFDResult`.
    modes_ : :class:`modalab.ModeSet` — window-corrected, scaled modes with indicators.
    frf_ : the FRF actually used (band, references), ``dt_`` the z-domain sampling time.
    reduced_matrix_shape_ : shape of the reduced normal matrix (memory diagnostic).
    root_methods_ : dict — how many orders had their roots tracked from the previous order
        (one reference, :func:`denominator_roots`) and how many took companion eigenvalues.

    Example
    -------
    >>> pm = PolyMAX(max_order=40).fit(frf)          # doctest: +SKIP
    >>> pm.modes_.freq_hz, pm.modes_.damping         # doctest: +SKIP
    """

    def __init__(self, max_order: int = 64, *, min_order: int = 1, order_step: int = 1, weighting=None,
                 band_hz=None, criteria=None, select="auto", selection=None, lower_residual: bool = True,
                 upper_residual: bool = True, window_correction: bool = True, refine: bool = True,
                 uncertainty: bool = True, refine_max_change: float = 2.0):
        self.max_order = max_order
        self.min_order = min_order
        self.order_step = order_step
        self.weighting = weighting
        self.band_hz = band_hz
        self.criteria = criteria
        self.select = select
        self.selection = selection
        self.lower_residual = lower_residual
        self.upper_residual = upper_residual
        self.window_correction = window_correction
        self.refine = refine
        self.refine_max_change = refine_max_change
        self.uncertainty = uncertainty

    # ------------------------------------------------------------------ helpers
    def _check_params(self, frf):
        if not isinstance(frf, FRF):
            raise ModalabValueError(fmt_error("frf", type(frf).__name__, "a modalab.FRF",
                                              "Build one with FRF.from_arrays or FRF.from_uff"))
        for name in ("max_order", "min_order", "order_step"):
            v = getattr(self, name)
            if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < 1:
                raise ModalabValueError(fmt_error(name, v, "a positive integer", "e.g. max_order=64"))
        if self.min_order > self.max_order:
            raise ModalabValueError(f"min_order={self.min_order} > max_order={self.max_order}; "
                                    "give min_order <= max_order")
        if self.weighting not in _WEIGHTINGS:
            raise ModalabValueError(fmt_error("weighting", self.weighting, "None, 'coherence' or 'variance'",
                                              "Use None for unit weights"))

    @staticmethod
    def prepare(frf: FRF, band_hz=None) -> FRF:
        """Band-limit and drop lines at 0 Hz or with non-finite data (coherence and variance with them)."""
        f = frf if band_hz is None else frf.band(*band_hz)
        good = (f.freq_hz > 0) & np.all(np.isfinite(f.H), axis=(0, 1))
        if not good.all():
            f = f.lines(good)
        return f

    # ------------------------------------------------------------------ fit
    def fit(self, frf: FRF) -> "PolyMAX":
        """Estimate poles for every order, stabilise, select, and fit shapes by LSFD.

        The steps, in order: :meth:`_estimate_poles` (reduced normal matrix, poles of every order),
        stabilisation and selection, :meth:`_refine_selected` (local refinement; automatic picks that run off
        or leave the diagram's estimate), :meth:`_drop_noise_picks` (low MPC, repeated shapes),
        :meth:`_pole_std` (standard deviations, pair test) and the final LSFD (:func:`modes_from_poles`)."""
        self._check_params(frf)
        data = self.prepare(frf, self.band_hz)
        self._estimate_poles(data)
        crit = self.criteria if self.criteria is not None else StabilisationCriteria()
        self.stabilisation_ = stabilise(self.orders_, self.poles_, self.participation_, crit)
        opts = self.selection if self.selection is not None else SelectionOptions()
        band = (float(data.freq_hz[0]), float(data.freq_hz[-1]))
        self.selected_ = select_poles(self.stabilisation_, self.select, opts, band_hz=band)
        lam_sel = self._refine_selected(data, opts)
        self.refined_poles_ = lam_sel
        beta = float(data.window_beta_per_s) if self.window_correction else 0.0
        lam_sel = self._drop_noise_picks(data, lam_sel, opts)
        extra, std_source, pair_warn = self._pole_std(data, lam_sel, beta)
        self.modes_, self.lsfd_ = modes_from_poles(
            data, lam_sel, self.selected_.participation, lower_residual=self.lower_residual,
            upper_residual=self.upper_residual, window_beta=beta, extra_indicators=extra)
        self.modes_.metadata.update({"method": "pLSCF (PolyMAX-style) + LSFD", "max_order": int(self.max_order),
                                     "band_hz": list(band), "window_beta_per_s": beta,
                                     "weighting": self.weighting or "none"})
        if std_source is not None:
            self.modes_.metadata["pole_std_source"] = std_source
        for k, F, pv, frac in pair_warn:
            log.warning("the mode at %.5g Hz may be two modes (a close pair merged into one pole): its residues "
                        "are not of rank one (F = %.3g, p = %.1e; a second mode would carry about %.0f %% of its "
                        "residue); more references, a higher order or --select can tell",
                        self.modes_.freq_hz[k], F, pv, 100 * np.sqrt(frac))
        n_out, n_in, nf = data.shape
        log.info("PolyMAX: %d outputs x %d references x %d lines, orders %d..%d, %d modes",
                 n_out, n_in, nf, self.orders_[0], self.orders_[-1], self.modes_.n_modes)
        return self

    def _estimate_poles(self, data: FRF) -> None:
        """The reduced normal matrix of the highest order and the poles and participation vectors of every
        order: sets ``frf_``, ``dt_``, ``reduced_matrix_shape_``, ``root_methods_``, ``orders_``, ``poles_``
        and ``participation_``."""
        n_out, n_in, nf = data.shape
        p = int(self.max_order)
        if nf < 2 * p // max(n_in, 1) + 2:
            log.warning("only %d lines for order %d: the problem is barely over-determined", nf, p)
        if nf < p + 2:
            raise ModalabValueError(f"{nf} frequency lines cannot support max_order={p}; "
                                    f"use max_order <= {max(nf - 2, 1)} or a wider band")
        fmax = float(data.freq_hz[-1])
        dt = 1.0 / (2.0 * fmax)
        theta = 2 * np.pi * data.freq_hz * dt
        w = frequency_weights(data, self.weighting)
        M = reduced_normal_matrix(data.H, w, theta, p)
        orders = np.arange(self.min_order, p + 1, self.order_step)
        poles, parts, methods = _poles_per_order(M, orders, n_in, dt)
        self.frf_ = data
        self.dt_ = dt
        self.reduced_matrix_shape_ = M.shape
        self.root_methods_ = methods
        self.orders_ = orders
        self.poles_ = poles
        self.participation_ = parts

    def _refine_selected(self, data: FRF, opts: SelectionOptions) -> np.ndarray:
        """The selected poles refined (:func:`refine_poles`), with the participation re-estimated in
        ``selected_``; of automatic picks, those whose refinement runs off to unphysical damping are dropped and
        those whose refinement left the diagram's estimate keep the diagram's pole and participation."""
        lam_sel = self.selected_.lam
        L_diag = self.selected_.participation
        if self.refine and lam_sel.size:
            # the refinement re-estimates each participation vector with its pole (rank-one fit of the local
            # residues): the diagram's comes from one order's denominator and carries its noise
            lam_sel, L_ref = refine_poles(data, lam_sel, self.selected_.participation,
                                          lower_residual=self.lower_residual, upper_residual=self.upper_residual,
                                          return_participation=True)
            self.selected_ = dataclasses.replace(self.selected_, participation=L_ref)
        if self.refine and lam_sel.size and self.selected_.source == "auto":
            # refinement can expose a spurious pole: it runs off to unphysical damping
            _, z_ref = pole_freq_damping(lam_sel)
            ok = (z_ref > 0) & (z_ref <= opts.max_damping)
            if not ok.all():
                log.info("refinement rejected %d pole(s) with damping outside (0, %g]", int((~ok).sum()),
                         opts.max_damping)
                sp = self.selected_
                self.selected_ = sp.subset(ok)
                lam_sel = lam_sel[ok]
                L_diag = L_diag[:, ok]
            lam_sel = _keep_consistent_refinement(self.selected_.lam, lam_sel, self.refine_max_change)
            back = lam_sel == self.selected_.lam          # the diagram's pole kept: its participation with it
            if back.any():
                P = self.selected_.participation.copy()
                P[:, back] = L_diag[:, back]
                self.selected_ = dataclasses.replace(self.selected_, participation=P)
        return lam_sel

    def _drop_noise_picks(self, data: FRF, lam_sel: np.ndarray, opts: SelectionOptions) -> np.ndarray:
        """Automatic picks without a low MPC and not repeating another pick's shape (``selected_`` and
        ``refined_poles_`` updated when any is dropped)."""
        if self.selected_.source == "auto" and opts.min_mpc > 0 and lam_sel.size:
            # noise modes fitted by LSFD have scattered phases: drop automatic picks with a low MPC
            # (MPC is invariant to the complex scaling of a shape: taken on the raw LSFD shapes ψ)
            psi = lsfd(data, lam_sel, self.selected_.participation, lower_residual=self.lower_residual,
                       upper_residual=self.upper_residual).psi
            ok = ~(mpc(psi) < opts.min_mpc)
            # one mode picked twice (two near clusters kept because they coexist at some orders): their
            # shapes agree; a close pair has distinct shapes (MAC between candidate shapes)
            ok &= ~duplicate_shapes(pole_freq_damping(lam_sel)[0], psi, self.selected_.cluster_size,
                                    opts.distance, opts.same_mode_mac)
            if not ok.all():
                log.info("dropped %d automatic pick(s): MPC < %g (noise) or a repeated shape", int((~ok).sum()),
                         opts.min_mpc)
                sp = self.selected_
                self.selected_ = sp.subset(ok)
                lam_sel = lam_sel[ok]
                self.refined_poles_ = lam_sel
        return lam_sel

    def _pole_std(self, data: FRF, lam_sel: np.ndarray, beta: float):
        """The modes' extra indicators (cluster size, order, standard deviations, pair test), the noise model
        of the standard deviations (None without ``uncertainty``) and the modes that may be a merged pair
        ``(k, F, p, fraction)``."""
        extra = {"cluster_size": self.selected_.cluster_size, "order": self.selected_.order}
        pair_warn = []
        std_source = None
        if self.uncertainty:
            if self.refine:
                unc = pole_uncertainty(data, lam_sel, self.selected_.participation, window_beta=beta)
                std_source = unc["source"]
            else:
                unc = {k: np.full(lam_sel.size, np.nan) for k in ("freq_std_hz", "damping_std", "chi2_ratio")}
                std_source = "not computed (refine=False)"
            extra.update(combined_std(unc, self.selected_,
                                      refined=(lam_sel != self.selected_.lam) if self.refine else None))
            if "rank2_F" in unc:
                pair = may_be_pair(unc)
                extra.update({"rank2_F": unc["rank2_F"], "rank2_fraction": unc["rank2_fraction"],
                              "may_be_pair": pair.astype(float)})
                pair_warn = [(k, unc["rank2_F"][k], unc["rank2_p"][k], unc["rank2_fraction"][k])
                             for k in np.flatnonzero(pair)]
        return extra, std_source, pair_warn

    def __getattr__(self, name):
        if name.endswith("_") and not name.startswith("__"):
            raise NotFittedError(f"PolyMAX.{name} is not available: call fit(frf) first")
        raise AttributeError(name)

    def synthesise(self, freq_hz=None) -> FRF:
        """FRFs synthesised from the fitted modal model (measured poles and residuals)."""
        res = self.lsfd_
        return res.synthesise(self.frf_ if freq_hz is None else np.asarray(freq_hz, float))
