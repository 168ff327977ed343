"""The one pairing rule of modalab (correlate, every updating method, diagnosis): :func:`pair_modes`
(cost 1 - MAC + relative frequency distance, Hungarian assignment, unobservable and rigid-body modes
left out, test modes that merge close FE modes detected) and its result :class:`Pairing`, with
:func:`observability`, :func:`shape_noise`, :func:`span_mac` and the pairing defaults.

Split out of :mod:`updating.correlation.metrics` (which re-exports these names: import them from there).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
import numpy as np
from scipy.optimize import linear_sum_assignment
from modalab.core.errors import ModalabValueError, ShapeError
from updating.correlation.shape_criteria import _TINY, mac

log = logging.getLogger(__name__)


# ----------------------------------------------------------------------- pairing
#: defaults of the one pairing rule (correlate, every updating method, the diagnosis fit block)
MAC_MIN = 0.5
FREQ_WINDOW = 0.35
FREQ_WEIGHT = 1.0
MIN_OBSERVABILITY = 1e-6
#: analysis modes closer than this (relative frequency) to a test mode's partner can merge with it in a test
CLOSE_MODES = 0.03
#: a test shape explained better by this much MAC by its partner and the partner's close neighbours together
#: than by its partner alone is a merge of those modes (when the test has fewer modes there): not paired
MERGE_GAIN = 0.1


@dataclass
class Pairing:
    """Result of :func:`pair_modes` (0-based indices).

    pairs : (analysis, test) index pairs of elastic modes, sorted by test mode — the only pairs an objective uses.
    mac : MAC value of each pair (NaN when paired without shapes).
    unpaired_test, unpaired_analysis : modes without a partner (excluded analysis modes included).
    out_of_order : pairs whose order differs between the models (crossing another pair).
    rigid_pairs : (analysis, test) pairs of rigid-body modes (``rigid='pair'``): shown, never in an objective.
    excluded_analysis : {analysis index: reason} for modes kept out of the pairing on purpose
        (rigid-body, not observable by the sensors).
    unpaired_reason : {test index: why it has no partner}.
    method : one sentence saying how the pairs were made (printed with the table).
    """

    pairs: list
    mac: np.ndarray
    unpaired_test: list
    unpaired_analysis: list
    out_of_order: list = field(default_factory=list)
    rigid_pairs: list = field(default_factory=list)
    excluded_analysis: dict = field(default_factory=dict)
    unpaired_reason: dict = field(default_factory=dict)
    method: str = ""

    @property
    def analysis_index(self) -> np.ndarray:
        return np.array([a for a, _ in self.pairs], int)

    @property
    def test_index(self) -> np.ndarray:
        return np.array([x for _, x in self.pairs], int)

    def to_dict(self) -> dict:
        """JSON-ready, 1-based mode numbers."""
        return {"method": self.method,
                "pairs": [[int(a) + 1, int(x) + 1] for a, x in self.pairs],
                "rigid_pairs": [[int(a) + 1, int(x) + 1] for a, x in self.rigid_pairs],
                "unpaired_test_modes": [j + 1 for j in self.unpaired_test],
                "unpaired_analysis_modes": [i + 1 for i in self.unpaired_analysis],
                "excluded_analysis_modes": {str(i + 1): r for i, r in sorted(self.excluded_analysis.items())},
                "unpaired_reason": {str(j + 1): r for j, r in sorted(self.unpaired_reason.items())}}


def observability(observed, full, full_dofs=None) -> np.ndarray:
    """How much of each analysis mode the sensors see: ``max|C φ| / max|φ|`` per mode, in [0, 1]-ish.

    ``observed`` is (n_test_dof, n_modes) — the modes at the test DOFs — and ``full`` the
    same modes on the model DOFs; with ``full_dofs`` only translational DOFs (axes 1–3) form the
    denominator when the model has any, so rotations (other units) do not dilute the ratio.
    A mode whose ratio is at round-off level (e.g. 1e-13: a lateral mode seen by vertical
    sensors only) gives a MAC made of noise and must not be paired.
    """
    O = np.abs(np.asarray(observed))
    F = np.abs(np.asarray(full))
    if full_dofs is not None:
        tr = np.array([1 <= abs(getattr(d, "axis", 0)) <= 3 for d in full_dofs], bool)
        if tr.any() and tr.size == F.shape[0]:
            F = F[tr]
    num = O.max(axis=0, initial=0.0)
    den = F.max(axis=0, initial=0.0)
    return np.where(den > _TINY, num / np.where(den > _TINY, den, 1.0), 0.0)


def _relative_distance(fa, fx):
    den = np.maximum(np.abs(fx)[None, :], 1e-12 * max(np.abs(fx).max(initial=0), np.abs(fa).max(initial=0), 1))
    return np.abs(fa[:, None] - fx[None, :]) / den


def _order_pairs(rel, allowed):
    """Order-preserving matching (no crossing pairs) with the most pairs, then the smallest total distance.

    Dynamic programming over the two frequency-sorted lists (indices must already be in frequency order).
    """
    na, nx = rel.shape
    # best[i][j] = (pairs, -cost) for the first i analysis and j test modes
    best = np.zeros((na + 1, nx + 1))
    cost = np.zeros((na + 1, nx + 1))
    move = np.zeros((na + 1, nx + 1), int)          # 0 skip analysis, 1 skip test, 2 pair
    for i in range(na + 1):
        for j in range(nx + 1):
            if i == 0 and j == 0:
                continue
            cands = []
            if i > 0:
                cands.append((best[i - 1, j], -cost[i - 1, j], 0))
            if j > 0:
                cands.append((best[i, j - 1], -cost[i, j - 1], 1))
            if i > 0 and j > 0 and allowed[i - 1, j - 1]:
                cands.append((best[i - 1, j - 1] + 1, -(cost[i - 1, j - 1] + rel[i - 1, j - 1]), 2))
            b = max(cands, key=lambda t: (t[0], t[1], t[2]))
            best[i, j], cost[i, j], move[i, j] = b[0], -b[1], b[2]
    out, i, j = [], na, nx
    while i > 0 or j > 0:
        m = move[i, j]
        if m == 2:
            out.append((i - 1, j - 1))
            i, j = i - 1, j - 1
        elif m == 0:
            i -= 1
        else:
            j -= 1
    return out[::-1]


def pair_modes(mac_matrix=None, freq_a_hz=None, freq_x_hz=None, *, mac_min: float = MAC_MIN,
               freq_weight: float | None = None, max_freq_error: float | None = FREQ_WINDOW,
               observability=None, min_observability: float = MIN_OBSERVABILITY, rigid_hz: float | None = None,
               rigid: str = "exclude", mode_shapes=None, close_modes: float = CLOSE_MODES,
               merge_gain: float = MERGE_GAIN, log_unpaired: bool = True) -> Pairing:
    """Pair analysis modes (rows) with test modes (columns): the one pairing rule of modalab.

    ``correlate``, every updating method and the diagnosis fit use this function, so
    the same data always give the same pairs (the assignment is deterministic: no
    random start, no set or dict order).

    **With shapes** (a MAC matrix, eq. 2.63): the Hungarian algorithm
    (:func:`scipy.optimize.linear_sum_assignment`) minimises the total cost
    ``Σ (1 − MAC) + freq_weight · |f_a − f_x| / f_x`` over one-to-one pairings, with the
    option of leaving a mode unpaired at the cost of the worst acceptable pair, so swapped
    modes are paired by shape and a mode without a counterpart stays unpaired instead of
    forcing a bad pair.  A candidate must have ``MAC ≥ mac_min`` and a relative frequency
    distance ``≤ max_freq_error`` (the frequency window); ``freq_weight`` defaults to 1 when
    frequencies are given (0: MAC only).  Without frequencies the pairing is by MAC alone.

    **Without shapes** (``mac_matrix=None``, frequency-only mode sets): pairing by order —
    the order-preserving matching of the two frequency lists with the most pairs inside the
    window, then the smallest total relative distance.

    **Excluded analysis modes**: modes whose ``observability`` (see :func:`observability`)
    is below ``min_observability`` (the sensors cannot see them; their MAC is round-off), and
    rigid-body modes (``f_a ≤ rigid_hz``, default 1e-3 × the lowest test frequency: independent of how many
    analysis modes were computed).  With
    ``rigid='pair'`` rigid-body modes are paired by MAC alone with test modes below half the
    lowest elastic analysis frequency and reported in ``rigid_pairs`` — never as an
    objective pair.  Every exclusion and every unpaired test mode carries its reason.

    **Merged and ambiguous test modes** (``mode_shapes=(analysis at the test DOFs, test shapes)``, the arrays the
    MAC matrix was computed from): a test mode whose shape is explained by its partner ``i`` together with the
    unpaired elastic analysis modes within ``close_modes`` of ``f_i`` (at most three, the nearest) better, by
    ``merge_gain`` or more in MAC, than by ``i`` alone, where the test has fewer modes within ``close_modes`` of
    its frequency than that group, is two or more close modes identified as one (a merge, whose frequency and
    damping belong to none of them): it is left unpaired, with that reason, and the assignment is redone
    without it.  A close group with as many test modes as analysis modes is a rotation of the group between
    the models (the shapes mix differently): those modes stay paired by the assignment.  A test mode
    paired with MAC 0.53 at 37.5 Hz whose shape the FE modes at 37.30, 37.42 and 37.63 Hz explain with
    MAC 1.00 together is such a merge (issue 14).

    The unpaired test modes and their reasons are logged (INFO); ``log_unpaired=False`` leaves that to a caller
    that pairs the same modes many times and says it once (the reasons are in the result either way).
    """
    Mc, fa, fx, rel, has_f, freq_weight, window = _checked_inputs(mac_matrix, freq_a_hz, freq_x_hz, mac_min,
                                                                  freq_weight, max_freq_error, rigid)
    na, nx = Mc.shape
    excluded, rigid_a, elastic = _excluded_modes(fa, fx, na, has_f, rigid_hz, rigid, observability,
                                                 min_observability)
    shapes = mac_matrix is not None
    allowed = np.ones((na, nx), bool)          # the candidates: MAC, frequency window, elastic analysis modes
    if shapes:
        allowed &= Mc >= mac_min
    if window is not None:
        allowed &= rel <= window
    allowed &= elastic[:, None]
    Sa, Sx = _checked_shapes(mode_shapes, na, nx) if shapes and has_f else (None, None)
    pairs, merged = _assign_without_merges(Mc, rel, fa, fx, allowed, shapes, freq_weight, mac_min, window, Sa, Sx,
                                           elastic, close_modes, merge_gain)
    rigid_pairs = (_rigid_pairs(Mc, fa, fx, pairs, rigid_a, elastic, has_f, mac_min, nx)
                   if rigid == "pair" and shapes and rigid_a.any() and nx else [])

    used_a = {a for a, _ in pairs} | {a for a, _ in rigid_pairs}
    used_x = {x for _, x in pairs} | {x for _, x in rigid_pairs}
    reasons = {j: merged[j] if j in merged else _unpaired_reason(j, Mc, rel, fa, fx, elastic, excluded,
                                                                 dict(pairs), mac_min, window, shapes)
               for j in range(nx) if j not in used_x}
    ooo = [p for p in pairs if any((q[1] - p[1]) * (q[0] - p[0]) < 0 for q in pairs)]
    how = _method_text(shapes, freq_weight, mac_min, window, excluded, rigid_a, rigid)
    res = Pairing(pairs=pairs, mac=np.asarray([Mc[i, j] for i, j in pairs], float),
                  unpaired_test=[j for j in range(nx) if j not in used_x],
                  unpaired_analysis=[i for i in range(na) if i not in used_a], out_of_order=ooo,
                  rigid_pairs=rigid_pairs, excluded_analysis=excluded, unpaired_reason=reasons, method=how)
    if res.unpaired_test and log_unpaired:
        log.info("test modes without an analysis partner: %s",
                 "; ".join(f"{j + 1}: {reasons[j]}" for j in res.unpaired_test))
    return res


def _checked_shapes(mode_shapes, na, nx):
    """The analysis and test shapes at the test DOFs of :func:`pair_modes` (``(None, None)`` when not given)."""
    if mode_shapes is None:
        return None, None
    Sa, Sx = (np.asarray(v) for v in mode_shapes)
    if Sa.ndim != 2 or Sx.ndim != 2 or Sa.shape[1] != na or Sx.shape[1] != nx or Sa.shape[0] != Sx.shape[0]:
        raise ShapeError(f"mode_shapes are {Sa.shape} and {Sx.shape}; expected (n_dof, {na}) and (n_dof, {nx}) "
                         "on the same DOFs as the MAC matrix")
    return Sa, Sx


def _assign_without_merges(Mc, rel, fa, fx, allowed, shapes, freq_weight, mac_min, window, Sa, Sx, elastic,
                           close_modes, merge_gain):
    """The assignment, redone without the test modes found to be merges of close analysis modes (with shapes
    ``Sa``, ``Sx``) until none is left: the pairs in test-mode order and the merged test modes with their
    reasons.  Clears the merged columns of ``allowed``."""
    na, nx = Mc.shape
    merged: dict[int, str] = {}
    while True:
        pairs = _assign(Mc, rel, fa, fx, allowed, shapes, freq_weight, mac_min, window) if na and nx else []
        if Sa is None:
            break
        new = _merged_tests(pairs, Mc, Sa, Sx, fa, fx, elastic, close_modes, merge_gain)
        if not new:
            break
        merged.update(new)
        for j in new:
            allowed[:, j] = False
    pairs.sort(key=lambda p: p[1])
    return pairs, merged


def _checked_inputs(mac_matrix, freq_a_hz, freq_x_hz, mac_min, freq_weight, max_freq_error, rigid):
    """:func:`pair_modes`' inputs checked (one-line errors) and as arrays: the MAC matrix (NaN without shapes),
    the frequencies, their relative distances, whether frequencies are given, the frequency weight and window."""
    if rigid not in ("exclude", "pair"):
        raise ModalabValueError(f"rigid={rigid!r}; expected 'exclude' or 'pair'")
    if not 0.0 <= mac_min <= 1.0:
        raise ModalabValueError(f"mac_min {mac_min}; expected a value in [0, 1] such as 0.5")
    if freq_weight is not None and freq_weight < 0:
        raise ModalabValueError(f"freq_weight {freq_weight}; expected >= 0")
    if max_freq_error is not None and not max_freq_error > 0:
        raise ModalabValueError(f"max_freq_error {max_freq_error}; expected > 0 (0.35 = ±35 %) or None")
    has_f = freq_a_hz is not None and freq_x_hz is not None
    if mac_matrix is None:
        if not has_f:
            raise ModalabValueError("pairing without shapes needs freq_a_hz and freq_x_hz")
        fa, fx = np.asarray(freq_a_hz, float).ravel(), np.asarray(freq_x_hz, float).ravel()
        Mc = np.full((fa.size, fx.size), np.nan)
    else:
        Mc = np.asarray(mac_matrix, dtype=float)
        if Mc.ndim != 2:
            raise ShapeError(f"MAC matrix has shape {Mc.shape}; expected (n_analysis, n_test)")
        if not np.all(np.isfinite(Mc)):
            raise ModalabValueError("the MAC matrix contains NaN or inf; check the mode shapes")
    na, nx = Mc.shape
    if freq_weight is None:
        freq_weight = FREQ_WEIGHT if has_f else 0.0
    if (freq_weight > 0) and not has_f:
        raise ModalabValueError("freq_weight > 0 needs freq_a_hz and freq_x_hz")
    if has_f:
        fa, fx = np.asarray(freq_a_hz, float).ravel(), np.asarray(freq_x_hz, float).ravel()
        if fa.shape != (na,) or fx.shape != (nx,):
            raise ShapeError(f"frequencies have {fa.size} and {fx.size} values; the MAC matrix is {na} x {nx}")
        if not (np.all(np.isfinite(fa)) and np.all(np.isfinite(fx))):
            raise ModalabValueError("mode frequencies contain NaN or inf")
        rel = _relative_distance(fa, fx)
    else:
        fa = fx = None
        rel = np.zeros_like(Mc)
    window = max_freq_error if has_f else None
    return Mc, fa, fx, rel, has_f, freq_weight, window


def _excluded_modes(fa, fx, na, has_f, rigid_hz, rigid, observability, min_observability):
    """Analysis modes kept out of the pairing on purpose (rigid-body, unobservable) with their reasons; the
    rigid-body mask; the mask of the elastic (pairable) analysis modes."""
    excluded: dict[int, str] = {}
    rigid_a = np.zeros(na, bool)
    if has_f and na:
        pos = np.abs(fx)[np.abs(fx) > 0]
        thr = (float(rigid_hz) if rigid_hz is not None else
               1e-3 * float(pos.min()) if pos.size else 1e-4 * float(np.abs(fa).max(initial=0)))
        rigid_a = np.abs(fa) <= thr
        for i in np.flatnonzero(rigid_a):
            excluded[int(i)] = (f"rigid-body mode ({fa[i]:.3g} Hz <= {thr:.3g} Hz): "
                                + ("paired by MAC only, kept out of objectives" if rigid == "pair"
                                   else "excluded from pairing"))
    if observability is not None:
        ob = np.asarray(observability, float).ravel()
        if ob.shape != (na,):
            raise ShapeError(f"observability has {ob.size} values; expected one per analysis mode ({na})")
        for i in np.flatnonzero(ob < min_observability):
            if int(i) not in excluded:
                excluded[int(i)] = (f"not observable by the sensors (observed/full amplitude {ob[i]:.2g} "
                                    f"< {min_observability:g}): excluded")
    elastic = np.array([i not in excluded for i in range(na)], bool)
    return excluded, rigid_a, elastic


def _rigid_pairs(Mc, fa, fx, pairs, rigid_a, elastic, has_f, mac_min, nx) -> list:
    """``rigid='pair'``: rigid-body analysis modes paired by MAC alone with unpaired test modes below half the
    lowest elastic analysis frequency."""
    rigid_pairs: list = []
    lowest = fa[elastic].min(initial=np.inf) if has_f else np.inf
    used_x = {x for _, x in pairs}
    rx = [j for j in range(nx) if j not in used_x and fx[j] < 0.5 * lowest]
    ra = list(np.flatnonzero(rigid_a))
    if rx and ra:
        sub = Mc[np.ix_(ra, rx)]
        r, c = linear_sum_assignment(1.0 - sub)
        rigid_pairs = sorted([(int(ra[i]), int(rx[j])) for i, j in zip(r, c) if sub[i, j] >= mac_min],
                             key=lambda p: p[1])
    return rigid_pairs


def _method_text(shapes, freq_weight, mac_min, window, excluded, rigid_a, rigid) -> str:
    """The one-line description of how the pairing was made (``Pairing.method``)."""
    if shapes:
        how = "Hungarian assignment on (1 - MAC)"
        how += f" + {freq_weight:g} x relative frequency distance" if freq_weight > 0 else " (MAC only)"
        how += f", MAC >= {mac_min:g}"
    else:
        how = "no shapes: pairing by frequency order"
    how += f", frequency window ±{100 * window:g} %" if window is not None else ", no frequency window"
    if excluded:
        n_r = int(rigid_a.sum())
        n_o = len(excluded) - n_r
        bits = ([f"{n_r} rigid-body analysis mode(s) {'paired by MAC only' if rigid == 'pair' else 'excluded'}"]
                if n_r else []) + ([f"{n_o} unobservable analysis mode(s) excluded"] if n_o else [])
        how += "; " + ", ".join(bits)
    return how


def _assign(Mc, rel, fa, fx, allowed, shapes, freq_weight, mac_min, window) -> list:
    """The pairs of :func:`pair_modes` for the candidates ``allowed``: Hungarian with the option of no partner
    (shapes), or the order-preserving matching (frequencies only)."""
    na, nx = Mc.shape
    if shapes:
        cost = (1.0 - Mc) + freq_weight * np.minimum(rel, 1e6)
        u = (1.0 - mac_min) + (freq_weight * window if window is not None else
                               freq_weight * float(np.minimum(rel, 1e6)[allowed].max(initial=0.0)))
        big = 1e6 * (1.0 + u + float(np.abs(cost[allowed]).max(initial=0.0)))
        n = na + nx
        C = np.full((n, n), big)
        C[:na, :nx] = np.where(allowed, cost, big)
        C[:na, nx:][np.diag_indices(na)] = 0.5 * u
        C[na:, :nx][np.diag_indices(nx)] = 0.5 * u
        C[na:, nx:] = 0.0
        r, c = linear_sum_assignment(C)
        return [(int(i), int(j)) for i, j in zip(r, c) if i < na and j < nx and allowed[i, j]]
    oa = np.argsort(fa, kind="stable")
    ox = np.argsort(fx, kind="stable")
    sub = _order_pairs(rel[np.ix_(oa, ox)], allowed[np.ix_(oa, ox)])
    return [(int(oa[i]), int(ox[j])) for i, j in sub]


def shape_noise(shapes) -> np.ndarray:
    """Relative noise level of each identified shape, read from its complexity: ``√2 ‖Im ψ'‖ / ‖Re ψ'‖``.

    ``ψ'`` is the shape rotated so that its imaginary part is least-squares minimal (the rotation of
    :func:`~modalab.core.modes.real_mode_approximation`).  A normal mode of a lightly, proportionally damped
    structure is real up to a common phase, so what remains out of phase is noise (or a neighbour's leakage,
    or non-proportional damping: all of which a real FE mode cannot reproduce); noise is equally likely in
    phase and out of phase, hence the √2.  A real shape gives 0.  Per mode, relative to the RMS amplitude
    of a component, like ``shape_sigma`` of the eigensensitivity updater: a weakly excited mode
    identified with MPC 0.64 gives about 0.45, a clean one (MPC 0.999) about 0.02.
    """
    phi = np.atleast_2d(np.asarray(shapes))
    if not np.iscomplexobj(phi):
        return np.zeros(phi.shape[1])
    theta = 0.5 * np.angle(np.sum(phi * phi, axis=0))
    rot = phi * np.exp(-1j * theta)[None, :]
    re = np.linalg.norm(rot.real, axis=0)
    return np.sqrt(2.0) * np.linalg.norm(rot.imag, axis=0) / np.maximum(re, _TINY)


def span_mac(x, basis) -> float:
    """MAC of the shape ``x`` with the subspace spanned by the columns of ``basis`` (least squares):
    ``‖B c‖² / ‖x‖²`` with ``c`` minimising ``‖x − B c‖``; equals :func:`mac` for one column."""
    x = np.asarray(x).ravel()
    B = np.asarray(basis).reshape(x.size, -1)
    nx2 = float(np.vdot(x, x).real)
    if nx2 <= _TINY or not B.size:
        return 0.0
    c, *_ = np.linalg.lstsq(B.astype(complex), x.astype(complex), rcond=None)
    return float(min(1.0, np.linalg.norm(B @ c) ** 2 / nx2))


def _merged_tests(pairs, Mc, Sa, Sx, fa, fx, elastic, close_modes, merge_gain) -> dict:
    """``{test index: reason}`` for paired test modes whose shape is a merge of their partner and its close,
    unpaired analysis neighbours (:func:`pair_modes`, 'Merged and ambiguous test modes')."""
    paired_a = {a for a, _ in pairs}
    out = {}
    for i, j in pairs:
        near = [k for k in np.flatnonzero(elastic) if k != i and k not in paired_a
                and abs(fa[k] - fa[i]) <= close_modes * abs(fa[i])]
        if not near:
            continue
        near = sorted(near, key=lambda k: (abs(fa[k] - fa[i]), k))[:3]
        group = sorted([i] + [int(k) for k in near])
        if np.sum(np.abs(fx - fx[j]) <= close_modes * abs(fx[j])) >= len(group):
            continue            # as many test modes as FE modes there: a close group rotated, not a merge
        m_span = span_mac(Sx[:, j], Sa[:, group])
        if m_span - Mc[i, j] >= merge_gain:
            fe = ", ".join(f"{k + 1} ({fa[k]:.4g} Hz)" for k in group)
            out[j] = (f"merged or ambiguous: its shape is a mix of the close FE modes {fe} (MAC {Mc[i, j]:.3f} "
                      f"with FE {i + 1} alone, {m_span:.3f} with them together): not paired")
    return out


def _unpaired_reason(j, Mc, rel, fa, fx, elastic, excluded, partner_of_a, mac_min, window, shapes) -> str:
    na = Mc.shape[0]
    cand = [i for i in range(na) if elastic[i]]
    if not cand:
        return "no analysis mode available" + (f" ({len(excluded)} excluded)" if excluded else "")
    if shapes:
        i = max(cand, key=lambda k: (Mc[k, j], -rel[k, j], -k))
        df = f", df {100 * (fa[i] - fx[j]) / fx[j]:+.1f} %" if fa is not None and fx[j] != 0 else ""
        what = f"best MAC {Mc[i, j]:.3f} with FE {i + 1}{df}"
        if Mc[i, j] < mac_min:
            return f"{what} < MAC floor {mac_min:g}"
        if window is not None and rel[i, j] > window:
            inwin = [k for k in cand if rel[k, j] <= window]
            extra = ""
            if inwin:
                k = max(inwin, key=lambda q: (Mc[q, j], -q))
                extra = f"; within the window best MAC {Mc[k, j]:.3f} with FE {k + 1}"
            return f"{what} is outside the ±{100 * window:g} % frequency window{extra}"
        if i in partner_of_a:
            return f"{what}, but FE {i + 1} is paired with test {partner_of_a[i] + 1}"
        return f"{what}; leaving both unpaired costs less than this pair"
    i = min(cand, key=lambda k: (rel[k, j], k))
    df = 100 * (fa[i] - fx[j]) / fx[j] if fx[j] != 0 else np.inf
    if window is not None and rel[i, j] > window:
        return f"nearest FE {i + 1} ({fa[i]:.4g} Hz, {df:+.1f} %) is outside the ±{100 * window:g} % window"
    if i in partner_of_a:
        return f"nearest FE {i + 1} ({df:+.1f} %) is paired with test {partner_of_a[i] + 1} (frequency order)"
    return f"nearest FE {i + 1} ({df:+.1f} %) would cross another pair (frequency order)"
