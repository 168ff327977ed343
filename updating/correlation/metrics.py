"""Test–analysis correlation — thesis section 2.2.

Mode-shape criteria (shapes are ``(n_dof, n_modes)`` arrays or
:class:`~modalab.core.modes.ModeSet` objects on the same DOFs):

* :func:`mac` — Modal Assurance Criterion, eq. 2.63 (complex-aware, optional weighting);
  :func:`automac` — MAC of a set with itself; :func:`macx` — the complex MAC (MACX).
* :func:`msf` — Modal Scale Factor, eq. 2.62.
* :func:`comac` — Coordinate MAC, eq. 2.64; :func:`ecomac` — enhanced COMAC.
* :func:`cross_orthogonality`, :func:`mixed_orthogonality` — eqs. 2.65, 2.66.
* :func:`frequency_table` — direct comparison of paired frequencies (section 2.2.1).

Pairing: :func:`pair_modes` — the one pairing rule of modalab (``correlate``, every
updating method and the diagnosis fit call it): Hungarian assignment on
``(1 − MAC) + relative frequency distance`` inside a frequency window (default
±35 %) with a MAC floor (0.5), the option of leaving a mode unpaired, analysis
modes the sensors cannot observe and rigid-body modes kept out and said so, a
reason for every unpaired test mode, and pairing by frequency order for
frequency-only sets.  It reports pairs whose order differs between the models
(the thesis' scaled aircraft, Table 10, had test modes 3–5 paired with FE modes
5, 3, 4 and 9–10 with 10, 9 — the latter at +22.7 %, inside the window).
Deterministic: no random start, no set or dict order.

FRF criteria: :func:`frac` (FRF assurance criterion per FRF over frequency),
:func:`csac` and :func:`csf` (cross-signature assurance and scale factor per
frequency line), :func:`frf_correlation` for labelled FRFs or a Structure.

High level: :func:`correlate` maps the analysis modes onto the test DOFs,
computes the MAC matrix, pairs the modes and returns a :class:`CorrelationResult`
with frequency errors, MSF, COMAC and ECOMAC, ``to_dict()`` for JSON and
``table()`` for text; the analysis may be a Structure (:func:`analysis_modes`
computes its normal modes).  Mode numbers in ``to_dict()`` and ``table()`` are 1-based;
indices in Python attributes are 0-based.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.optimize import linear_sum_assignment

from modalab.core.errors import ModalabValueError, ShapeError
from modalab.core.frf import FRF
from modalab.core.modes import ModeSet
from modalab.core.structure import Structure

from updating.correlation.dofmap import as_dofmap

__all__ = ["mac", "automac", "macx", "msf", "comac", "ecomac", "cross_orthogonality", "mixed_orthogonality",
           "frequency_table", "Pairing", "pair_modes", "span_mac", "shape_noise", "CLOSE_MODES", "MERGE_GAIN",
           "observability", "MAC_MIN", "FREQ_WINDOW",
           "FREQ_WEIGHT", "MIN_OBSERVABILITY", "frac", "csac", "csf", "FrfCorrelation",
           "frf_correlation", "CorrelationResult", "correlate", "analysis_modes"]

log = logging.getLogger(__name__)

_TINY = 1e-300


# ------------------------------------------------------------------------ inputs
def _shapes(x, name: str) -> np.ndarray:
    if isinstance(x, ModeSet):
        return np.asarray(x.shapes)
    try:
        a = np.asarray(x)
    except (TypeError, ValueError):
        raise ModalabValueError(f"{name}: got {type(x).__name__}; expected an (n_dof, n_modes) array or a ModeSet") \
            from None
    if a.dtype == object or not np.issubdtype(a.dtype, np.number):
        raise ModalabValueError(f"{name}: got an array of {a.dtype}; expected numbers, shape (n_dof, n_modes)")
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2:
        raise ShapeError(f"{name} has shape {a.shape}; expected (n_dof, n_modes)")
    if not np.all(np.isfinite(a)):
        raise ModalabValueError(f"{name} contains NaN or inf; remove or fill the missing shape values first")
    return a


def _pair_shapes(a, x, na="analysis shapes", nx="test shapes", same_modes=False):
    A, X = _shapes(a, na), _shapes(x, nx)
    if A.shape[0] != X.shape[0]:
        raise ShapeError(f"{na} have {A.shape[0]} DOFs but {nx} have {X.shape[0]}; map both onto the same DOFs "
                         "first (updating.correlation.dofmap.DofMap.apply or correlate(..., dofmap=...))")
    if same_modes and A.shape[1] != X.shape[1]:
        raise ShapeError(f"{na} have {A.shape[1]} modes but {nx} have {X.shape[1]}; pass paired modes column by "
                         "column (e.g. from pair_modes)")
    if isinstance(a, ModeSet) and isinstance(x, ModeSet):
        if [(d.node, d.axis) for d in a.dofs] != [(d.node, d.axis) for d in x.dofs]:
            raise ShapeError("the two mode sets are on different DOF labels; select common DOFs first "
                             "(ModeSet.select_dofs) or use correlate(..., dofmap=...)")
        sg = np.array([da.sign * dx.sign for da, dx in zip(a.dofs, x.dofs)], float)
        X = X * sg[:, None]
    return A, X


def _rescale(P):
    """Divide every column by its largest modulus (for criteria invariant to column scaling; avoids underflow)."""
    m = np.abs(P).max(axis=0, initial=0.0)
    return P / np.where((m > 0) & np.isfinite(m), m, 1.0)[None, :]


def _weight(W, n):
    if W is None:
        return None
    if sp.issparse(W):
        W = sp.csr_matrix(W)
    else:
        W = np.asarray(W)
    if W.shape != (n, n):
        raise ShapeError(f"weighting matrix has shape {W.shape}; expected ({n}, {n}) on the shape DOFs")
    return W


def _inner(A, B, W=None):
    """A^H W B."""
    return A.conj().T @ (B if W is None else np.asarray(W @ B))


# ------------------------------------------------------------------ mode criteria
def mac(phi_a, phi_x, *, weight=None) -> np.ndarray:
    """Modal Assurance Criterion matrix, eq. 2.63.

    ``MAC_ij = |φ_aiᴴ W φ_xj|² / ((φ_aiᴴ W φ_ai)(φ_xjᴴ W φ_xj))`` with ``W = I`` by
    default (a mass matrix gives the mass-weighted MAC).  Complex shapes use the
    conjugate transpose.  Shape (n_analysis_modes, n_test_modes), values in [0, 1];
    a zero vector gives 0.
    """
    A, X = _pair_shapes(phi_a, phi_x)
    A, X = _rescale(A), _rescale(X)
    W = _weight(weight, A.shape[0])
    num = np.abs(_inner(A, X, W)) ** 2
    da = np.real(np.einsum("ij,ij->j", A.conj(), A if W is None else np.asarray(W @ A)))
    dx = np.real(np.einsum("ij,ij->j", X.conj(), X if W is None else np.asarray(W @ X)))
    den = np.outer(da, dx)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(den > _TINY, num / np.where(den > _TINY, den, 1.0), 0.0)
    return np.clip(out, 0.0, 1.0)


def automac(phi, *, weight=None) -> np.ndarray:
    """AutoMAC: the MAC of a mode set with itself (symmetric, unit diagonal for non-zero shapes).

    Off-diagonal values near 1 show modes the sensor set cannot tell apart (spatial aliasing).
    """
    P = _shapes(phi, "shapes")
    M = mac(P, P, weight=weight)
    return 0.5 * (M + M.T)


def macx(phi_a, phi_x) -> np.ndarray:
    """Complex MAC (MACX of Vacher, Jacquier & Bucharles 2010) for complex modes.

    ``MACX = (|aᴴx| + |aᵀx|)² / ((aᴴa + |aᵀa|)(xᴴx + |xᵀx|))``.  It equals the MAC
    (eq. 2.63) for real shapes and, unlike the MAC, is insensitive to the
    distinction between a complex mode and its conjugate.
    """
    A, X = _pair_shapes(phi_a, phi_x)
    A, X = _rescale(A), _rescale(X)
    num = (np.abs(A.conj().T @ X) + np.abs(A.T @ X)) ** 2
    da = np.real(np.einsum("ij,ij->j", A.conj(), A)) + np.abs(np.einsum("ij,ij->j", A, A))
    dx = np.real(np.einsum("ij,ij->j", X.conj(), X)) + np.abs(np.einsum("ij,ij->j", X, X))
    den = np.outer(da, dx)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(den > _TINY, num / np.where(den > _TINY, den, 1.0), 0.0)
    return np.clip(out, 0.0, 1.0)


def msf(phi_x, phi_a) -> np.ndarray:
    """Modal Scale Factor of paired columns, eq. 2.62: the factor that scales ``φ_a`` onto ``φ_x``.

    ``MSF = φ_aᴴ φ_x / φ_aᴴ φ_a`` (least squares), so ``φ_a * MSF ≈ φ_x``; its modulus is
    eq. 2.62 and its sign (phase for complex shapes) tells whether the shapes are
    inverted.  Shape (n_pairs,); 0 where ``φ_a`` is zero.
    """
    X, A = _pair_shapes(phi_x, phi_a, "shapes phi_x", "shapes phi_a", same_modes=True)
    num = np.einsum("ij,ij->j", A.conj(), X)
    den = np.real(np.einsum("ij,ij->j", A.conj(), A))
    out = np.where(den > _TINY, num / np.where(den > _TINY, den, 1.0), 0.0)
    return out.real if not np.iscomplexobj(out) or np.all(out.imag == 0) else out


def _unit(P):
    n = np.linalg.norm(P, axis=0)
    return P / np.where(n > _TINY, n, 1.0)[None, :]


def comac(phi_a, phi_x, *, normalize: bool = True) -> np.ndarray:
    """Coordinate MAC per DOF over L paired modes (columns in pair order), eq. 2.64.

    ``COMAC_i = (Σ_r |φ_a,ir φ_x,ir|)² / (Σ_r |φ_a,ir|² Σ_r |φ_x,ir|²)`` (Lieven & Ewins; the
    printed eq. 2.64 omits the square of the numerator, without which the value would not
    be bounded by 1).  ``normalize=True`` scales every mode vector to unit length first, so
    each pair counts equally whatever the test scaling.  Values in [0, 1]; 1 = correlated.
    A DOF that is zero in every mode of both sets (a common node line) counts as 1,
    a DOF zero in only one of them as 0.
    """
    A, X = _pair_shapes(phi_a, phi_x, same_modes=True)
    if normalize:
        A, X = _unit(_rescale(A)), _unit(_rescale(X))
    # COMAC_i is invariant to scaling row i of A or X: divide each row by its largest modulus
    ra, rx = np.abs(A).max(axis=1, initial=0.0), np.abs(X).max(axis=1, initial=0.0)
    A = A / np.where(ra > 0, ra, 1.0)[:, None]
    X = X / np.where(rx > 0, rx, 1.0)[:, None]
    num = np.sum(np.abs(A * X), axis=1) ** 2
    sa, sx = np.sum(np.abs(A) ** 2, axis=1), np.sum(np.abs(X) ** 2, axis=1)
    den = sa * sx
    both_zero = (sa <= _TINY) & (sx <= _TINY)
    out = np.where(den > _TINY, num / np.where(den > _TINY, den, 1.0), np.where(both_zero, 1.0, 0.0))
    return np.clip(out, 0.0, 1.0)


def ecomac(phi_a, phi_x) -> np.ndarray:
    """Enhanced COMAC per DOF (Hunt 1992): ``ECOMAC_i = Σ_r |φ_a,ir - φ̃_x,ir| / (2L)``.

    Each analysis mode is scaled to a largest entry of 1 and each test mode is
    scaled onto it with its MSF (eq. 2.62), so the value measures the remaining
    shape difference: 0 for perfect correlation, larger for worse.
    """
    A, X = _pair_shapes(phi_a, phi_x, same_modes=True)
    L = A.shape[1]
    if L == 0:
        return np.zeros(A.shape[0])
    k = np.argmax(np.abs(A), axis=0)
    peak = A[k, np.arange(L)]
    A = A / np.where(np.abs(peak) > _TINY, peak, 1.0)[None, :]
    s = msf(A, X)                                   # scales X onto A
    Xs = X * s[None, :]
    return np.sum(np.abs(A - Xs), axis=1) / (2 * L)


def _ortho(A, M, B):
    Mm = sp.csr_matrix(M) if sp.issparse(M) else np.asarray(M)
    if Mm.shape != (A.shape[0], A.shape[0]):
        raise ShapeError(f"mass matrix has shape {Mm.shape}; expected ({A.shape[0]}, {A.shape[0]}) on the shape "
                         "DOFs (a reduced mass on the test DOFs, or the full mass with expanded test modes)")
    return A.T @ np.asarray(Mm @ B), Mm


def cross_orthogonality(phi_a, phi_x, M, *, normalize: bool = False) -> np.ndarray:
    """Cross orthogonality (Targoff), eq. 2.65: ``COM = Φ_Aᵀ M_A Φ_X``.

    ``M`` is the analytical mass on the shape DOFs (reduced to the test DOFs, or
    the full mass with expanded test shapes).  Identity for well-correlated,
    mass-normalised modes.  ``normalize=True`` divides by
    ``sqrt(|diag(Φ_AᵀMΦ_A)| |diag(Φ_XᵀMΦ_X)|)`` so differently scaled sets compare.
    """
    A, X = _pair_shapes(phi_a, phi_x)
    O, Mm = _ortho(A, M, X)
    if normalize:
        da = np.sqrt(np.abs(np.einsum("ij,ij->j", A, np.asarray(Mm @ A))))
        dx = np.sqrt(np.abs(np.einsum("ij,ij->j", X, np.asarray(Mm @ X))))
        O = O / np.outer(np.where(da > _TINY, da, 1.0), np.where(dx > _TINY, dx, 1.0))
    return O


def mixed_orthogonality(phi_x, M, *, normalize: bool = False) -> np.ndarray:
    """Mixed orthogonality, eq. 2.66: ``MOC = Φ_Xᵀ M_A Φ_X`` (test modes with the analytical mass).

    Identity for mass-normalised modes of a correct model; ``normalize=True``
    divides by ``sqrt(|d_i d_j|)`` with ``d = diag(MOC)`` (unit diagonal).
    """
    X = _shapes(phi_x, "test shapes")
    O, _ = _ortho(X, M, X)
    if normalize:
        d = np.sqrt(np.abs(np.diag(O)))
        d = np.where(d > _TINY, d, 1.0)
        O = O / np.outer(d, d)
    return O


def frequency_table(freq_a_hz, freq_x_hz, pairs) -> list[dict]:
    """Paired frequencies and relative errors ``(f_a - f_x)/f_x`` in %, one dict per pair (0-based indices)."""
    fa, fx = np.asarray(freq_a_hz, float), np.asarray(freq_x_hz, float)
    rows = []
    for ia, jx in pairs:
        err = (fa[ia] - fx[jx]) / fx[jx] * 100 if fx[jx] != 0 else (0.0 if fa[ia] == 0 else np.inf)
        rows.append({"analysis": int(ia), "test": int(jx), "analysis_freq_hz": float(fa[ia]),
                     "test_freq_hz": float(fx[jx]), "freq_error_pct": float(err)})
    return rows


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
               merge_gain: float = MERGE_GAIN) -> Pairing:
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
    """
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

    # --- analysis modes kept out on purpose
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

    # --- candidates
    shapes = mac_matrix is not None
    allowed = np.ones((na, nx), bool)
    if shapes:
        allowed &= Mc >= mac_min
    if window is not None:
        allowed &= rel <= window
    allowed &= elastic[:, None]

    merged: dict[int, str] = {}
    Sa = Sx = None
    if mode_shapes is not None and shapes and has_f:
        Sa, Sx = (np.asarray(v) for v in mode_shapes)
        if Sa.ndim != 2 or Sx.ndim != 2 or Sa.shape[1] != na or Sx.shape[1] != nx or Sa.shape[0] != Sx.shape[0]:
            raise ShapeError(f"mode_shapes are {Sa.shape} and {Sx.shape}; expected (n_dof, {na}) and (n_dof, {nx}) "
                             "on the same DOFs as the MAC matrix")
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

    rigid_pairs: list = []
    if rigid == "pair" and shapes and rigid_a.any() and nx:
        lowest = fa[elastic].min(initial=np.inf) if has_f else np.inf
        used_x = {x for _, x in pairs}
        rx = [j for j in range(nx) if j not in used_x and fx[j] < 0.5 * lowest]
        ra = list(np.flatnonzero(rigid_a))
        if rx and ra:
            sub = Mc[np.ix_(ra, rx)]
            r, c = linear_sum_assignment(1.0 - sub)
            rigid_pairs = sorted([(int(ra[i]), int(rx[j])) for i, j in zip(r, c) if sub[i, j] >= mac_min],
                                 key=lambda p: p[1])

    used_a = {a for a, _ in pairs} | {a for a, _ in rigid_pairs}
    used_x = {x for _, x in pairs} | {x for _, x in rigid_pairs}
    partner_of_a = {a: x for a, x in pairs}
    reasons: dict[int, str] = {}
    for j in range(nx):
        if j in used_x:
            continue
        reasons[j] = merged[j] if j in merged else _unpaired_reason(j, Mc, rel, fa, fx, elastic, excluded,
                                                                       partner_of_a, mac_min, window, shapes)
    ooo = [p for p in pairs if any((q[1] - p[1]) * (q[0] - p[0]) < 0 for q in pairs)]
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
    res = Pairing(pairs=pairs, mac=np.asarray([Mc[i, j] for i, j in pairs], float),
                  unpaired_test=[j for j in range(nx) if j not in used_x],
                  unpaired_analysis=[i for i in range(na) if i not in used_a], out_of_order=ooo,
                  rigid_pairs=rigid_pairs, excluded_analysis=excluded, unpaired_reason=reasons, method=how)
    if res.unpaired_test:
        log.info("test modes without an analysis partner: %s",
                 "; ".join(f"{j + 1}: {reasons[j]}" for j in res.unpaired_test))
    return res


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


# ------------------------------------------------------------------ FRF criteria
def _frf_arrays(a, x):
    Ha = a.H if isinstance(a, FRF) else np.asarray(a)
    Hx = x.H if isinstance(x, FRF) else np.asarray(x)
    if Ha.shape != Hx.shape:
        raise ShapeError(f"FRF arrays have shapes {Ha.shape} and {Hx.shape}; expected equal shapes "
                         "(n_out, n_in, n_freq). Align them with frf_correlation")
    if Ha.ndim == 1:
        Ha, Hx = Ha[None, None], Hx[None, None]
    elif Ha.ndim == 2:
        Ha, Hx = Ha[:, None], Hx[:, None]
    if Ha.ndim != 3:
        raise ShapeError(f"FRF arrays have {Ha.ndim} dimensions; expected (n_out, n_in, n_freq)")
    return Ha, Hx


def frac(analysis, test) -> np.ndarray:
    """Frequency Response Assurance Criterion per FRF, over the frequency lines.

    ``FRAC_ij = |Σ_ω H_x,ij H_a,ij*|² / (Σ_ω |H_x,ij|² Σ_ω |H_a,ij|²)`` — shape
    (n_out, n_in), values in [0, 1], 1 when the two FRFs are proportional.
    """
    Ha, Hx = _frf_arrays(analysis, test)
    num = np.abs(np.sum(Hx * Ha.conj(), axis=2)) ** 2
    den = np.sum(np.abs(Hx) ** 2, axis=2) * np.sum(np.abs(Ha) ** 2, axis=2)
    return np.clip(np.where(den > _TINY, num / np.where(den > _TINY, den, 1.0), 0.0), 0, 1)


def csac(analysis, test) -> np.ndarray:
    """Cross-Signature Assurance Criterion per frequency line (a MAC between the response vectors).

    ``CSAC(ω) = |H_x(ω)ᴴ H_a(ω)|² / ((H_xᴴH_x)(H_aᴴH_a))`` with all FRFs at ω
    stacked into one vector; shape (n_freq,), values in [0, 1].
    """
    Ha, Hx = _frf_arrays(analysis, test)
    a = Ha.reshape(-1, Ha.shape[2])
    x = Hx.reshape(-1, Hx.shape[2])
    num = np.abs(np.sum(x.conj() * a, axis=0)) ** 2
    den = np.sum(np.abs(x) ** 2, axis=0) * np.sum(np.abs(a) ** 2, axis=0)
    return np.clip(np.where(den > _TINY, num / np.where(den > _TINY, den, 1.0), 0.0), 0, 1)


def csf(analysis, test) -> np.ndarray:
    """Cross-Signature Scale Factor per frequency line: ``2|H_xᴴH_a| / (H_xᴴH_x + H_aᴴH_a)``.

    Sensitive to amplitude as well as shape; 1 only when the FRFs are equal in modulus and shape.
    """
    Ha, Hx = _frf_arrays(analysis, test)
    a = Ha.reshape(-1, Ha.shape[2])
    x = Hx.reshape(-1, Hx.shape[2])
    num = 2 * np.abs(np.sum(x.conj() * a, axis=0))
    den = np.sum(np.abs(x) ** 2, axis=0) + np.sum(np.abs(a) ** 2, axis=0)
    return np.clip(np.where(den > _TINY, num / np.where(den > _TINY, den, 1.0), 0.0), 0, 1)


@dataclass
class FrfCorrelation:
    """FRF correlation on the test labels: aligned FRFs, FRAC per FRF, CSAC and CSF per line."""

    analysis: FRF
    test: FRF
    frac: np.ndarray
    csac: np.ndarray
    csf: np.ndarray

    def to_dict(self) -> dict:
        return {"responses": [str(d) for d in self.test.responses],
                "references": [str(d) for d in self.test.references],
                "frac": self.frac.tolist(), "freq_hz": self.test.freq_hz.tolist(),
                "csac": self.csac.tolist(), "csf": self.csf.tolist(),
                "mean_frac": float(np.mean(self.frac)) if self.frac.size else None}


def frf_correlation(analysis, test: FRF, *, dofmap=None, rtol: float = 1e-9) -> FrfCorrelation:
    """Correlate analytical FRFs with measured ones on the test labels.

    Parameters
    ----------
    analysis : :class:`~modalab.core.frf.FRF` on model labels (same frequency lines as the test),
        or a :class:`~modalab.core.structure.Structure` whose exact FRFs are synthesised at the test lines.
    test : measured FRF.
    dofmap : maps test labels onto model DOFs (oblique sensors allowed: ``H_t = C_o H_a C_iᵀ``).
    """
    if not isinstance(test, FRF):
        raise ModalabValueError(f"test: got {type(test).__name__}; expected a modalab.core.frf.FRF")
    dm = as_dofmap(dofmap)
    if isinstance(analysis, Structure):
        Co_full = dm.matrix(test.responses, analysis.dofs)
        Ci_full = dm.matrix(test.references, analysis.dofs)
        ro = np.unique(sp.csr_matrix(Co_full).indices)
        ri = np.unique(sp.csr_matrix(Ci_full).indices)
        analysis = analysis.frf(test.freq_hz, responses=[analysis.dofs[i] for i in ro],
                                references=[analysis.dofs[i] for i in ri], quantity=test.quantity)
    if not isinstance(analysis, FRF):
        raise ModalabValueError(f"analysis: got {type(analysis).__name__}; expected an FRF or a Structure")
    if analysis.freq_hz.shape != test.freq_hz.shape or not np.allclose(analysis.freq_hz, test.freq_hz, rtol=rtol,
                                                                        atol=0):
        raise ShapeError(f"the analysis FRF has {analysis.n_freq} lines ({analysis.freq_hz[:1]}..) but the test "
                         f"has {test.n_freq}; synthesise the analysis at the test lines "
                         "(Structure.frf(test.freq_hz, ...)) or pass the Structure itself")
    if analysis.quantity != test.quantity:
        analysis = analysis.to(test.quantity)
    Co = sp.csr_matrix(dm.matrix(test.responses, analysis.responses))
    Ci = sp.csr_matrix(dm.matrix(test.references, analysis.references))
    H = np.einsum("oa,abf,ib->oif", Co.toarray(), analysis.H, Ci.toarray(), optimize=True)
    aligned = FRF(freq_hz=test.freq_hz, H=H, responses=test.responses, references=test.references,
                  quantity=test.quantity, metadata={"source": "analysis on test DOFs"})
    return FrfCorrelation(analysis=aligned, test=test, frac=frac(aligned, test), csac=csac(aligned, test),
                          csf=csf(aligned, test))


# -------------------------------------------------------------------- high level
def _enc(v):
    v = complex(v)
    return v.real if v.imag == 0 else {"re": v.real, "im": v.imag}


@dataclass
class CorrelationResult:
    """Everything :func:`correlate` found (0-based indices in attributes).

    analysis : analysis modes observed at the test DOFs.
    test : test modes.
    mac : (n_analysis, n_test) MAC matrix (NaN everywhere for a frequency-only test set).
    pairing : :class:`Pairing`.
    freq_error_pct : (n_pairs,) ``(f_a - f_x)/f_x`` in %.
    msf : (n_pairs,) factor scaling each analysis mode onto its test mode (eq. 2.62).
    comac, ecomac : (n_test_dofs,) per test DOF over the pairs.
    mac_min : threshold used.
    observability : (n_analysis,) observed/full amplitude of each analysis mode (:func:`observability`).
    dof_mapping : how test DOFs were put on model DOFs (a sentence), and ``geometry`` the
        per-node distances when they were mapped by geometry.
    """

    analysis: ModeSet
    test: ModeSet
    mac: np.ndarray
    pairing: Pairing
    freq_error_pct: np.ndarray
    msf: np.ndarray
    comac: np.ndarray
    ecomac: np.ndarray
    mac_min: float
    observability: np.ndarray = None
    dof_mapping: str = "same node ids"
    geometry: dict = None

    @property
    def pairs(self) -> list:
        return self.pairing.pairs

    @property
    def dofs(self) -> list:
        return self.test.dofs

    @property
    def has_shapes(self) -> bool:
        return self.test.has_shapes

    def paired(self) -> tuple[ModeSet, ModeSet]:
        """(analysis, test) mode sets restricted to the pairs, in pair order."""
        return (self.analysis.select_modes(self.pairing.analysis_index),
                self.test.select_modes(self.pairing.test_index))

    def summary(self) -> dict:
        fe = np.abs(self.freq_error_pct)
        shp = self.has_shapes and len(self.pairs)
        return {"n_pairs": len(self.pairs), "n_test_modes": self.test.n_modes,
                "n_analysis_modes": self.analysis.n_modes,
                "n_unpaired_test_modes": len(self.pairing.unpaired_test),
                "mean_abs_freq_error_pct": float(fe.mean()) if fe.size else None,
                "max_abs_freq_error_pct": float(fe.max()) if fe.size else None,
                "min_pair_mac": float(self.pairing.mac.min()) if shp else None,
                "mean_pair_mac": float(self.pairing.mac.mean()) if shp else None}

    def to_dict(self) -> dict:
        """JSON-ready dict; mode numbers are 1-based."""
        fa, fx = self.analysis.freq_hz, self.test.freq_hz
        ooo = set(self.pairing.out_of_order)
        pairs = []
        for k, (ia, jx) in enumerate(self.pairs):
            pairs.append({"test_mode": jx + 1, "analysis_mode": ia + 1, "test_freq_hz": float(fx[jx]),
                          "analysis_freq_hz": float(fa[ia]), "freq_error_pct": float(self.freq_error_pct[k]),
                          "mac": float(self.pairing.mac[k]) if self.has_shapes else None,
                          "msf": _enc(self.msf[k]) if self.has_shapes else None,
                          "out_of_order": (ia, jx) in ooo})
        out = {
            "test_dofs": [str(d) for d in self.test.dofs],
            "test_freq_hz": fx.tolist(), "analysis_freq_hz": fa.tolist(),
            "mac_min": self.mac_min, "mac": self.mac.tolist() if self.has_shapes else None, "pairs": pairs,
            "pairing": self.pairing.to_dict(), "dof_mapping": self.dof_mapping,
            "unpaired_test_modes": [j + 1 for j in self.pairing.unpaired_test],
            "unpaired_analysis_modes": [i + 1 for i in self.pairing.unpaired_analysis],
            "comac": {str(d): float(v) for d, v in zip(self.test.dofs, self.comac)},
            "ecomac": {str(d): float(v) for d, v in zip(self.test.dofs, self.ecomac)},
            "summary": self.summary(),
        }
        if self.observability is not None:
            out["analysis_observability"] = [float(v) for v in self.observability]
        if self.geometry is not None:
            out["geometry_map"] = self.geometry
        return out

    def table(self) -> str:
        """Plain-text frequency and MAC comparison (1-based mode numbers), with how the pairs were made."""
        fa, fx = self.analysis.freq_hz, self.test.freq_hz
        ooo = set(self.pairing.out_of_order)
        lines = [f"DOFs: {self.dof_mapping}", f"pairing: {self.pairing.method}"]
        if not self.has_shapes:
            lines.append("the test set has no mode shapes: no MAC, pairs by frequency order only")
        lines.append(f"{'test':>4} {'f_test [Hz]':>12} {'FE':>4} {'f_FE [Hz]':>12} {'df [%]':>8} {'MAC':>6} "
                     f"{'|MSF|':>9}  note")
        by_test = {jx: (k, ia) for k, (ia, jx) in enumerate(self.pairs)}
        rigid = {jx: ia for ia, jx in self.pairing.rigid_pairs}
        for jx in range(self.test.n_modes):
            if jx in by_test:
                k, ia = by_test[jx]
                note = "out of order" if (ia, jx) in ooo else ""
                m = f"{self.pairing.mac[k]:>6.3f}" if self.has_shapes else f"{'-':>6}"
                s = f"{abs(self.msf[k]):>9.4g}" if self.has_shapes else f"{'-':>9}"
                lines.append(f"{jx + 1:>4} {fx[jx]:>12.4f} {ia + 1:>4} {fa[ia]:>12.4f} "
                             f"{self.freq_error_pct[k]:>+8.2f} {m} {s}  {note}")
            elif jx in rigid:
                ia = rigid[jx]
                lines.append(f"{jx + 1:>4} {fx[jx]:>12.4f} {ia + 1:>4} {fa[ia]:>12.4f} {'-':>8} "
                             f"{self.mac[ia, jx]:>6.3f} {'-':>9}  rigid-body pair (not in any objective)")
            else:
                lines.append(f"{jx + 1:>4} {fx[jx]:>12.4f} {'-':>4} {'-':>12} {'-':>8} {'-':>6} {'-':>9}  "
                             f"unpaired: {self.pairing.unpaired_reason.get(jx, '')}")
        if len(fx):
            excl = self.pairing.excluded_analysis
            band = [i for i in self.pairing.unpaired_analysis if fa[i] <= fx.max() * 1.1 and i not in excl]
            if band:
                lines.append("analysis modes in the test band without a test partner: "
                             + ", ".join(f"{i + 1} ({fa[i]:.4g} Hz)" for i in band))
            ex = [i for i in sorted(excl) if fa[i] <= fx.max() * 1.1]
            if ex:
                lines.append("analysis modes kept out of the pairing: "
                             + "; ".join(f"{i + 1} ({fa[i]:.4g} Hz) {excl[i]}" for i in ex))
        s = self.summary()
        if s["n_pairs"]:
            lines.append(f"{s['n_pairs']} pairs, {s['n_unpaired_test_modes']} test mode(s) unpaired; mean |df| "
                         f"{s['mean_abs_freq_error_pct']:.2f} %"
                         + (f", min MAC {s['min_pair_mac']:.3f}" if s["min_pair_mac"] is not None else ""))
        else:
            lines.append("no pairs: " + self.pairing.method)
        return "\n".join(lines)


def analysis_modes(structure: Structure, n_modes: int | None = None) -> ModeSet:
    """Mass-normalised normal modes of a Structure as a :class:`~modalab.core.modes.ModeSet` (Hz, undamped)."""
    if not isinstance(structure, Structure):
        raise ModalabValueError(f"expected a Structure; got {type(structure).__name__}")
    if n_modes is not None and not 1 <= int(n_modes) <= structure.n_dof:
        raise ModalabValueError(f"n_modes {n_modes}; expected 1..{structure.n_dof} (the model's DOF count)")
    omega, phi = structure.normal_modes(None if n_modes is None else int(n_modes))
    return ModeSet(freq_hz=omega / (2 * np.pi), shapes=phi, dofs=structure.dofs, scaling="unit_modal_mass",
                   metadata={"source": f"normal modes of {structure.name or 'the model'}"})


def correlate(analysis, test: ModeSet, *, dofmap=None, mac_min: float = MAC_MIN, freq_weight: float | None = None,
              max_freq_error: float | None = FREQ_WINDOW, n_analysis_modes: int | None = None,
              min_observability: float = MIN_OBSERVABILITY, rigid_hz: float | None = None,
              rigid: str = "exclude", dof_mapping: str | None = None, geometry: dict | None = None
              ) -> CorrelationResult:
    """Correlate analysis modes with test modes on the test DOFs.

    The analysis modes are observed at the test DOFs through ``dofmap``
    (:class:`~updating.correlation.dofmap.DofMap`, dict, TOML/CSV path, or None for the same
    node numbers — the CLI refuses that without ``--same-ids`` and maps by geometry
    instead, :func:`updating.correlation.dofmap.geometry_map`; unmapped test DOFs raise
    :class:`~modalab.core.errors.DofError`).  Then: MAC matrix (eq. 2.63), the one
    pairing rule :func:`pair_modes` (Hungarian assignment on MAC and frequency, a
    frequency window, unobservable and rigid-body analysis modes kept out and said
    so), frequency errors (section 2.2.1), MSF (eq. 2.62), COMAC (eq. 2.64) and
    ECOMAC over the pairs.  Complex test shapes are used as they are (the MAC is
    complex-aware).  A frequency-only test set (no shapes) is paired by frequency order
    inside the window.

    ``analysis`` may also be a :class:`~modalab.core.structure.Structure`: its lowest
    ``n_analysis_modes`` normal modes are used (default: twice the number of test
    modes plus 5, at most the model size).  ``dof_mapping``/``geometry`` only label the
    result (how the map was made, distances of a geometry map).
    """
    if isinstance(analysis, Structure):
        if not isinstance(test, ModeSet):
            raise ModalabValueError(f"test: got {type(test).__name__}; expected a modalab.core.modes.ModeSet")
        n = n_analysis_modes or min(analysis.n_dof, 2 * test.n_modes + 5)
        analysis = analysis_modes(analysis, n)
    for name, ms in (("analysis", analysis), ("test", test)):
        if not isinstance(ms, ModeSet):
            raise ModalabValueError(f"{name}: got {type(ms).__name__}; expected a modalab.core.modes.ModeSet")
    if dof_mapping is None:
        dof_mapping = ("same node ids (no map given)" if dofmap is None else
                       f"DOF map {getattr(as_dofmap(dofmap), 'name', '') or 'given'}")
    if not test.has_shapes:
        fa = analysis.freq_hz
        pairing = pair_modes(None, fa, test.freq_hz, mac_min=mac_min, max_freq_error=max_freq_error,
                             rigid_hz=rigid_hz, rigid="exclude")
        rows = frequency_table(fa, test.freq_hz, pairing.pairs)
        ana = analysis.select_dofs([]) if analysis.n_dof else analysis
        return CorrelationResult(analysis=ana, test=test, mac=np.full((analysis.n_modes, test.n_modes), np.nan),
                                 pairing=pairing, freq_error_pct=np.array([r["freq_error_pct"] for r in rows], float),
                                 msf=np.full(len(pairing.pairs), np.nan), comac=np.zeros(0), ecomac=np.zeros(0),
                                 mac_min=float(mac_min), observability=None, dof_mapping="none (no test shapes)",
                                 geometry=None)
    ana = as_dofmap(dofmap).apply(analysis, test.dofs)
    X = np.asarray(test.shapes)
    A = np.asarray(ana.shapes)
    M = mac(A, X)
    obs = observability(A, analysis.shapes, analysis.dofs)
    pairing = pair_modes(M, ana.freq_hz, test.freq_hz, mac_min=mac_min, freq_weight=freq_weight,
                         max_freq_error=max_freq_error, observability=obs, min_observability=min_observability,
                         rigid_hz=rigid_hz, rigid=rigid, mode_shapes=(A, X))
    ia, jx = pairing.analysis_index, pairing.test_index
    rows = frequency_table(ana.freq_hz, test.freq_hz, pairing.pairs)
    ferr = np.array([r["freq_error_pct"] for r in rows], float)
    if len(ia):
        Ap, Xp = A[:, ia], X[:, jx]
        s = msf(Xp, Ap)
        cm, ec = comac(Ap, Xp), ecomac(Ap, Xp)
    else:
        s, cm, ec = np.zeros(0), np.zeros(test.n_dof), np.zeros(test.n_dof)
    return CorrelationResult(analysis=ana, test=test, mac=M, pairing=pairing, freq_error_pct=ferr, msf=np.asarray(s),
                             comac=cm, ecomac=ec, mac_min=float(mac_min), observability=obs,
                             dof_mapping=dof_mapping, geometry=geometry)
