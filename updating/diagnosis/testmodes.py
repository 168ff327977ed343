"""Test modes for the fit blocks: peaks of the measured FRFs (:func:`peak_modes`), the suspension band of a
free model's test article (:func:`suspension_band`), and the pairing of test and model modes with
rigid-body and suspension modes excluded on purpose (:func:`pair_test_modes`).  Split out of
:mod:`~updating.diagnosis.workflow`."""
from __future__ import annotations

import logging

import numpy as np
from scipy.signal import find_peaks

from modalab.core.errors import ModalabValueError
from modalab.core.modes import ModeSet
from modalab.core.frf import FRF

from updating.correlation.metrics import analysis_modes, correlate

log = logging.getLogger(__name__)


def peak_modes(measured: FRF, *, band_hz=None, max_modes: int = 12, prominence: float = 0.05) -> ModeSet:
    """Test modes by quadrature peak picking on the measured FRFs (used when no identified modes are given).

    Peaks are found on the summed receptance power (``scipy.signal.find_peaks`` with a prominence of
    ``prominence`` × the largest peak in log scale); each natural frequency is then refined between the lines
    by a local single-pole fit of every FRF around the peak (:func:`refine_pole`, at the complex frequencies
    ``s = iω + β`` of an exponential window), so it is not snapped to the line grid; each shape is the
    imaginary part of the receptance column of the reference that responds most at the peak.  Adequate for
    well-separated, lightly damped modes, which is what the frequency and MAC columns of the fit blocks need.
    """
    f = measured if band_hz is None else measured.band(*band_hz)
    f = f.band(max(float(f.freq_hz[0]), 1e-9), None) if f.freq_hz[0] <= 0 else f
    rec = f.to("receptance")
    ok = np.all(np.isfinite(rec.H), axis=(0, 1))            # lines without a value (as frf_data leaves them out)
    if not ok.all():
        if np.count_nonzero(ok) < 4:
            raise ModalabValueError("fewer than 4 lines of the measured FRFs have finite values; no peaks to pick")
        rec = rec.lines(ok)
    P = np.sum(np.abs(rec.H) ** 2, axis=(0, 1))
    lg = np.log10(P + 1e-300)
    pk, props = find_peaks(lg, prominence=prominence * max(float(np.ptp(lg)), 1e-12))
    if pk.size == 0:
        raise ModalabValueError("no resonance peaks in the measured FRFs; give identified test modes instead")
    pk = pk[np.argsort(-props["prominences"])[:max_modes]]
    pk.sort()
    s = rec.s
    shapes, freqs, zetas = [], [], []
    for k, i in enumerate(pk):
        lo = int(pk[k - 1]) if k > 0 else 0                     # the window stops at the neighbouring peaks
        hi = int(pk[k + 1]) if k + 1 < pk.size else P.size - 1
        lam = refine_pole(s, rec.H, P, int(i), lo, hi)
        freqs.append(abs(lam) / (2 * np.pi) if lam is not None else float(rec.freq_hz[i]))
        zetas.append(-lam.real / abs(lam) if lam is not None else np.nan)
        col = int(np.argmax(np.sum(np.abs(rec.H[:, :, i]) ** 2, axis=0)))
        shapes.append(rec.H[:, col, i].imag)
    n_on_grid = int(sum(1 for x in zetas if not np.isfinite(x)))
    if n_on_grid:
        log.info("peak picking: %d of %d peak frequencies left on the line grid (no single-pole fit around them)",
                 n_on_grid, pk.size)
    return ModeSet(freq_hz=np.array(freqs), shapes=np.array(shapes).T, dofs=list(rec.responses),
                   metadata={"source": "quadrature peak picking, frequencies refined by a local single-pole fit"})


#: lines each side of a peak used by :func:`refine_pole` at least, and at most (the half-power half-width between)
POLE_FIT_MIN_HALF, POLE_FIT_MAX_HALF = 3, 40
#: orders of the local rational fit tried in turn
POLE_FIT_ORDERS = (1, 2, 3)
#: a higher order is kept only when it lowers the fit's residual sum of squares below this fraction of the
#: lower order's (a neighbouring mode, not the noise)
POLE_FIT_GAIN = 0.25


def refine_pole(s: np.ndarray, H: np.ndarray, P: np.ndarray, i: int, lo: int, hi: int):
    """The pole λ (rad/s, ``Re λ < 0``) of the mode whose summed power ``P`` peaks at line ``i``, or None.

    Every FRF ``H[m, r]`` on the lines around the peak is fitted by ``q`` poles common to all FRFs and a local
    residual, ``H(s) = Σ_k A_mr,k/(s − λ_k) + a_mr + C_mr s``: written with a common denominator
    ``d(s) H = n_mr(s)`` this is linear in the denominator's coefficients once each FRF's numerator is
    projected out (the least-squares complex frequency-domain form of a local modal fit); the residues
    follow by linear least squares.  The data's complex frequencies ``s = iω + β`` are used, so an exponential
    window's decay β is removed exactly.  Orders :data:`POLE_FIT_ORDERS` are tried; a higher one is kept only
    when it lowers the misfit below :data:`POLE_FIT_GAIN` × the lower one's (an unresolved close neighbour).
    The pole returned is the admissible one (stable, lightly damped, inside the window) contributing most at
    the peak line.  The lines used span the half-power points of ``P`` (at least :data:`POLE_FIT_MIN_HALF`, at
    most :data:`POLE_FIT_MAX_HALF` each side) and never reach the neighbouring peaks ``lo``/``hi``.  None (the
    caller keeps the line) when too few lines remain or no admissible pole is found."""
    n = P.size
    half = P[i] / 2
    a = i
    while a > lo and P[a] > half:
        a -= 1
    b = i
    while b < hi and P[b] > half:
        b += 1
    w = int(np.clip(max(i - a, b - i), POLE_FIT_MIN_HALF, POLE_FIT_MAX_HALF))
    j0, j1 = max(i - w, lo + 1 if lo < i else 0, 0), min(i + w, hi - 1 if hi > i else n - 1, n - 1)
    sl = slice(j0, j1 + 1)
    if j1 - j0 + 1 < 4:
        return None
    sv = s[sl]
    Hw = H[:, :, sl].reshape(-1, sv.size)
    w0 = abs(s[i])
    z = sv / w0                                                # scaled: a well-conditioned basis
    best, rss_best = None, np.inf
    for q in POLE_FIT_ORDERS:
        if sv.size < 2 * q + 3:
            continue
        # common denominator a(z) = z^q + Σ a_k z^k and numerators b_mr(z) of degree q + 1 (the q modes and a
        # local residual a + C s): H a = b is linear in the a_k once each FRF's numerator is projected out
        Bm = np.column_stack([z ** k for k in range(q + 2)])
        Q, _ = np.linalg.qr(Bm)
        proj = lambda X: X - (X @ Q.conj()) @ Q.T             # noqa: E731 - remove the numerator's span per row
        A = np.column_stack([proj(Hw * z[None, :] ** k).ravel() for k in range(q)])
        rhs = -proj(Hw * z[None, :] ** q).ravel()
        coef = np.linalg.lstsq(A, rhs, rcond=None)[0]          # complex: only the window's poles, no mirror
        roots = np.roots(np.concatenate([[1.0], coef[::-1]])) * w0
        # the poles' residues and the local residual by linear least squares, and the misfit of the whole
        G = np.column_stack([1.0 / (sv - r) for r in roots] + [np.ones_like(sv), sv])
        R = np.linalg.lstsq(G, Hw.T, rcond=None)[0]            # (q + 2, n_frf)
        rss = float(np.sum(np.abs(G @ R - Hw.T) ** 2))
        # a higher order must explain markedly more (a neighbouring mode), not fit the noise
        if best is not None and not rss < POLE_FIT_GAIN * rss_best:
            continue
        # the pole that makes the peak: the largest contribution at the peak line, among lightly damped poles
        # inside the window
        contrib = [float(np.sum(np.abs(R[k] / (s[i] - r)) ** 2)) for k, r in enumerate(roots)]
        ok = [k for k, r in enumerate(roots) if r.real < 0 and -r.real < 0.5 * abs(r)
              and sv[0].imag <= abs(r) <= sv[-1].imag]
        if ok:
            best, rss_best = roots[max(ok, key=lambda k: contrib[k])], rss
    if best is None:
        return None
    lam = complex(best.real, abs(best.imag))
    return lam


#: pairing in the fit blocks: smallest MAC and largest relative frequency difference of an accepted pair
PAIR_MAC_MIN = 0.6


PAIR_MAX_FREQ_ERROR = 0.25


#: modes below this fraction of the model's first elastic frequency are rigid-body or suspension modes
SUSPENSION_RATIO = 0.5


#: a free-free test article hangs on a suspension whose modes lie below this fraction of its first elastic
#: frequency (the usual design rule of a free-free test: suspension modes at most 10 % of the first elastic one)
SUSPENSION_PEAK_RATIO = 0.1


def suspension_band(structure, measured: FRF, band_hz=None) -> float | None:
    """The frequency below which the lines are left out of the fits because the test article hung on a
    suspension the free model leaves out, or None.

    A free-free model is only an idealisation of a test article on soft cords: "free-free boundary conditions
    are subject to suspension effects, yielding rigid body modes having eigenvalues not equal to zero"
    (thesis, ch. 1; the thesis's test-bed hung with rigid-body modes at about 1 Hz, §5).  When the nominal model
    has rigid-body modes and the measured FRFs resonate below :data:`SUSPENSION_PEAK_RATIO` × its first elastic
    frequency f₁ (peaks of the summed receptance power, as :func:`peak_modes`, or of the summed accelerance
    power), those lines and the transition above them (up to :data:`SUSPENSION_RATIO` × f₁, where the pairing
    already leaves suspension modes out) describe the suspension, not the structure: left in, their misfit
    dominates the error measure and every screening (a 1/ω² mass line against a resonance).  A spring to ground
    that the model should carry (a support at a tenth of f₁ or above) is not a suspension and keeps its lines.

    The accelerance shows a suspension the line spacing does not resolve: a free article's accelerance there is
    its mass line, flat and rising towards the first elastic mode without a peak, while a resonance between two
    lines raises the one above it
    over its neighbours, or the first line over those after it (the first line then counts as a peak); the
    receptance, falling as 1/ω⁴ in power, has its maximum at the first line, where no peak is found (held-out
    3173, seen after its score: cords at 0.51-2.2 Hz measured at 0.365 Hz spacing, the suspension lines left
    in, χ²/N 119 after updating and a 0.1 kg mass not found)."""
    n = min(structure.n_dof, 24)
    ana = analysis_modes(structure, n)
    fa = np.asarray(ana.freq_hz, float)
    rigid = _rigid_fraction(structure, np.asarray(ana.shapes)) > 0.9
    elastic = fa[~rigid]
    # free: rigid-body modes at zero frequency (not a support's or mounts' rigid-body modes, which it models)
    if not elastic.size or not np.any(rigid & (fa < 1e-3 * float(elastic[0]))):
        return None
    f1 = float(elastic[0])
    rec = measured if band_hz is None else measured.band(*band_hz)
    sel = (rec.freq_hz > 0) & (rec.freq_hz <= SUSPENSION_PEAK_RATIO * f1)
    if np.count_nonzero(sel) < 5:
        return None
    pk = np.union1d(_power_peaks(rec.to("receptance").H[:, :, sel]),
                    _power_peaks(rec.to("accelerance").H[:, :, sel], first=True))
    if pk.size == 0:
        return None
    log.info("the measured FRFs resonate at %s Hz, below %.0f %% of the free model's first elastic frequency "
             "(%.4g Hz): a suspension", ", ".join(f"{x:.3g}" for x in rec.freq_hz[sel][pk]),
             100 * SUSPENSION_PEAK_RATIO, f1)
    return SUSPENSION_RATIO * f1


def _power_peaks(H: np.ndarray, first: bool = False) -> np.ndarray:
    """Indices of the lines where the summed power of ``H`` (n_out, n_in, n_lines) peaks on a log scale, with a
    prominence of at least 5 % of its range and a factor of 2.  ``first``: the first line counts as a peak when
    it stands that far above the lines after it (an accelerance, flat on a free article's mass line, is highest
    at the first line when a suspension mode lies just above it)."""
    lg = np.log10(np.sum(np.abs(H) ** 2, axis=(0, 1)) + 1e-300)
    prom = max(0.05 * float(np.ptp(lg)), 0.3)
    if not first:
        return find_peaks(lg, prominence=prom)[0]
    return find_peaks(np.concatenate([[lg.min() - 1.0], lg]), prominence=prom)[0] - 1


def _rigid_fraction(structure, phi: np.ndarray) -> np.ndarray:
    """Share of each mode's kinetic energy (mass-weighted) in the span of the six rigid-body motions of the
    model's nodes (translations and small rotations about the centroid, from the node coordinates)."""
    coords = getattr(structure, "coords", None) or {}
    if not coords:
        return np.zeros(phi.shape[1])
    x0 = np.mean(np.array(list(coords.values()), float), axis=0)
    R = np.zeros((structure.n_dof, 6))
    for i, d in enumerate(structure.dofs):
        xyz = coords.get(d.node)
        if xyz is None:
            continue
        r = np.asarray(xyz, float) - x0
        a = d.axis - 1
        if a < 3:
            R[i, a] = 1.0                                  # translation along the axis
            # rotation θ about axis b moves the node by θ e_b × r; component a of it
            for b in range(3):
                e = np.zeros(3)
                e[b] = 1.0
                R[i, 3 + b] = np.cross(e, r)[a]
        else:
            R[i, a] = 1.0
        R[i] *= d.sign
    M = structure.M
    MR = M @ R
    G = R.T @ MR
    keep = np.flatnonzero(np.diag(G) > 1e-12 * max(np.diag(G).max(), 1e-300))
    if keep.size == 0:
        return np.zeros(phi.shape[1])
    Rk, Gk = R[:, keep], G[np.ix_(keep, keep)]
    c = np.linalg.lstsq(Gk, MR[:, keep].T @ phi, rcond=None)[0]       # M-orthogonal projection coefficients
    proj = Rk @ c
    num = np.einsum("ij,ij->j", proj, M @ proj)
    den = np.einsum("ij,ij->j", phi, M @ phi)
    return np.clip(num / np.maximum(den, 1e-300), 0.0, 1.0)


def pair_test_modes(structure, test_modes: ModeSet) -> dict:
    """THE pairing of the diagnosis (every fit block and frequency table goes through here).

    Rigid-body and suspension modes are excluded on purpose, and only on a model with free directions: a model
    mode whose kinetic energy lies for more than 90 % in the rigid-body motions and whose frequency is below
    :data:`SUSPENSION_PEAK_RATIO` × the first elastic model frequency (a free direction), and a test mode below
    :data:`SUSPENSION_RATIO` × the lowest model mode kept (the suspension the free model leaves out).  A model
    on modelled supports keeps every mode and every test mode: its rigid-like modes on the supports are modes
    of the structure.  The rest are paired by MAC (optimal
    assignment, :func:`updating.correlation.metrics.correlate`) with at least :data:`PAIR_MAC_MIN` and a relative
    frequency difference of at most :data:`PAIR_MAX_FREQ_ERROR`; a mode without such a partner is unpaired.

    Returns ``pairs`` [(model freq, test index)], ``freq_error_pct``, ``mac``, ``excluded_test_hz``,
    ``excluded_model_hz``, ``unpaired_test_hz``, ``unpaired_reason`` {test index: why it has no partner},
    ``cutoff_hz``.  Nothing is logged: a caller says the unpaired modes once (:func:`say_unpaired`), not once
    for each model it pairs.
    """
    n = min(structure.n_dof, 2 * test_modes.n_modes + 12)
    ana = analysis_modes(structure, n)
    top = (1 + PAIR_MAX_FREQ_ERROR) * float(np.max(test_modes.freq_hz, initial=0.0))
    while n < structure.n_dof and ana.freq_hz[-1] < top:          # every model mode a test mode could pair with
        n = min(structure.n_dof, 2 * n)
        ana = analysis_modes(structure, n)
    rigid = _rigid_fraction(structure, np.asarray(ana.shapes)) > 0.9
    fa = np.asarray(ana.freq_hz, float)
    elastic = fa[~rigid]
    # a rigid-like mode is a free direction of the model only when it lies far below the elastic modes (a free
    # model's rigid-body modes sit at ~0 Hz, up to round-off); a modelled support's mode (a mass on springs,
    # a frame on mounts) is a mode of the structure and is paired like any other
    free = rigid & (fa < SUSPENSION_PEAK_RATIO * float(elastic[0])) if elastic.size else rigid
    kept = fa[~free]
    cutoff = SUSPENSION_RATIO * float(kept[0]) if free.any() and kept.size else 0.0
    drop_a = free
    fx = np.asarray(test_modes.freq_hz, float)
    keep_x = np.flatnonzero(fx >= cutoff)
    keep_a = np.flatnonzero(~drop_a)
    out = {"pairs": [], "freq_error_pct": [], "mac": [], "cutoff_hz": cutoff,
           "excluded_test_hz": [float(f) for f in fx[fx < cutoff]],
           "excluded_model_hz": [float(f) for f in fa[drop_a]]}
    why: dict = {}
    if keep_x.size and keep_a.size:
        c = correlate(ana.select_modes(keep_a), test_modes.select_modes(keep_x), mac_min=PAIR_MAC_MIN,
                      max_freq_error=PAIR_MAX_FREQ_ERROR, log_unpaired=False)
        for (a, t), e in zip(c.pairs, c.freq_error_pct):
            out["pairs"].append((float(fa[keep_a[a]]), int(keep_x[t])))
            out["freq_error_pct"].append(float(e))
            out["mac"].append(float(c.mac[a, t]))
        why = {int(keep_x[t]): r for t, r in c.pairing.unpaired_reason.items()}
    paired = {t for _, t in out["pairs"]}
    out["unpaired_test_hz"] = [float(fx[t]) for t in keep_x if t not in paired]
    out["unpaired_reason"] = {int(t): why.get(int(t), "no model mode left to pair with")
                              for t in keep_x if t not in paired}
    return out


def say_unpaired(pairings: dict, test_modes: ModeSet) -> None:
    """Log the test modes without a model partner once for the fit blocks (``pairings``: block name ->
    :func:`pair_test_modes` result) that leave out the same modes, with the reasons of the last of those blocks
    (the model the diagnosis ends with); one line per group only when the blocks leave out different modes."""
    groups: dict = {}
    for name, pr in pairings.items():
        groups.setdefault(tuple(sorted(pr["unpaired_reason"])), []).append(name)
    for modes, names in groups.items():
        if not modes:
            continue
        why = pairings[names[-1]]["unpaired_reason"]
        blocks = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
        log.info("test modes without a model partner in the fit block%s %s: %s", "s" * (len(names) > 1), blocks,
                 "; ".join(f"{j + 1} ({test_modes.freq_hz[j]:.4g} Hz): {why[j]}" for j in modes))


def _paired_frequencies(structure, test_modes, n_modes: int, band) -> list:
    """Model frequencies (Hz) aligned with the test modes by :func:`pair_test_modes` (None where unpaired);
    without test modes, the model's frequencies inside the band (rigid-body and mechanism modes left out)."""
    if test_modes is not None:
        out = [None] * test_modes.n_modes
        for f, t in pair_test_modes(structure, test_modes)["pairs"]:
            out[t] = f
        return out
    w, _ = structure.normal_modes(min(n_modes + 12, structure.n_dof))
    fx = np.atleast_1d(w) / (2 * np.pi)
    return [float(x) for x in fx if 0.5 * band[0] < x <= 1.1 * band[1]][:n_modes]


def _mode_metrics(structure, test_modes) -> dict:
    """``freq_error_max_pct`` and ``mac_min`` over the test modes paired by :func:`pair_test_modes`, with
    the counts of pairs, unpaired test modes and the rigid-body/suspension modes left out on purpose."""
    return _pairing_metrics(None if test_modes is None else pair_test_modes(structure, test_modes))


def _pairing_metrics(p) -> dict:
    """:func:`_mode_metrics` from a :func:`pair_test_modes` result (None: no test modes)."""
    if p is None:
        return {"freq_error_max_pct": None, "mac_min": None}
    out = {"freq_error_max_pct": float(np.max(np.abs(p["freq_error_pct"]))) if p["pairs"] else None,
           "mac_min": float(np.min(p["mac"])) if p["pairs"] else None, "n_pairs": len(p["pairs"]),
           "n_unpaired_test": len(p["unpaired_test_hz"]),
           "suspension_cutoff_hz": p["cutoff_hz"],
           "n_excluded_test": len(p["excluded_test_hz"]), "n_excluded_model": len(p["excluded_model_hz"])}
    return out
