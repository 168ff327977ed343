"""When modalab uses dense linear algebra and when sparse: the one rule, with its reasons.

Structural matrices (K, M, C, D) are stored sparse. An operation on a model of ``n`` DOFs works on
dense copies when ``n <= limit`` for the kind of operation it is, and on the sparse matrices above.
The results are the same either way (to round-off); only time and memory differ. The limits differ
by operation because the work does:

``SOLVE_LIMIT`` (80) — solving or factorising a dynamic stiffness ``Z(s) = K + iD + sC + s²M`` at
    frequency lines (receptance columns, dynamic expansion, condensed residuals, per-mode static
    solves). A frequency-domain method does this at hundreds of lines; the dense path costs
    ``O(n³)`` per line against a sparse LU's ``O(n·b²)`` (b the band width after reordering).
    Measured on this project's 2-core machine, single-threaded SuperLU beat batched dense LAPACK
    by 30x at 400 DOFs; below about 80 DOFs the batched dense solve wins (fewer Python calls).
    Above the limit a narrow band (beam frames, half band up to
    :data:`updating.correlation.condensation.BAND_LIMIT` after reordering) is factorised by LAPACK's
    banded LU, which on the discovery benchmark's frames (60-300 DOFs, half band 5-29) takes the
    receptance columns 1.3-3x faster than SuperLU (the whole diagnosis 1.16x, median of 30 cases).

``EIGEN_LIMIT`` (2000) — real symmetric eigenproblems ``K φ = ω² M φ`` (normal modes, SEREP's
    modes) and the factorisations made once per mode (Nelson's eigenvector sensitivity, the
    eigendynamic expansion at each test frequency). Dense ``eigh`` returns every mode in one
    LAPACK call and needs no shift; shift-invert Lanczos (ARPACK) needs a number of modes and a
    shift, and only pays once the dense ``O(n³)`` cost dominates (a few seconds at 2000 DOFs).
    A per-mode factorisation is done a handful of times, not at hundreds of lines, so it shares
    this limit rather than ``SOLVE_LIMIT``.

``MODES_LIMIT`` (600) — the lowest modes of a model only (a Ritz basis, the modes pairing looks at),
    computed again for every candidate model diagnosis tries. Shift-invert Lanczos finds a few dozen
    modes at a fraction of a dense eigensolution's cost from a few hundred DOFs on, and the solve
    repeats hundreds of times, so the switch comes earlier than ``EIGEN_LIMIT``.

``PROJECTED_LIMIT`` (400) — algorithms that are dense by nature, not by storage: the
    variable-projection Jacobian of the MCI updater (a dense QR of ``Z_{:,s}`` at every line,
    :class:`updating.methods.mci.MCIUpdater`, ``jacobian='projected'``, and its noise weights from
    the dense ``Z``) and the response-function method's full coefficient matrix (stored whole up
    to here; above, its normal equations are accumulated chunk by chunk). Above the limit the same
    step is computed from sparse factorisations (``jacobian='condensed'``); the limit is where the
    dense arrays (``F·n²`` complex values) stop fitting comfortably in memory.

``NULL_SPACE_LIMIT`` (300) — the null space of the stiffness of a model's massless DOFs (the mechanisms
    :mod:`modalab.core.eigen` constrains before the modes). Dense ``eigh`` returns every null vector in one
    call, however many there are; above, shift-invert Lanczos around zero looks for them a few at a time,
    which only pays for the large massless parts of a big model (a component is small in practice).

:func:`use_dense` is the test every module applies.

Not dense-versus-sparse choices, and so not here: where diagnosis replaces the exact model by a reduced
one (:data:`updating.diagnosis.fit.RITZ_LIMIT`, :data:`updating.diagnosis.modal_fit.SUBSPACE_ABOVE`) — those
change the answer (within a checked tolerance), not only the time.
"""
from __future__ import annotations

from .errors import ModalabValueError

__all__ = ["SOLVE_LIMIT", "EIGEN_LIMIT", "MODES_LIMIT", "PROJECTED_LIMIT", "NULL_SPACE_LIMIT", "use_dense"]

SOLVE_LIMIT = 80
EIGEN_LIMIT = 2000
MODES_LIMIT = 600
PROJECTED_LIMIT = 400
NULL_SPACE_LIMIT = 300

_LIMITS = {"solve": "SOLVE_LIMIT", "eigen": "EIGEN_LIMIT", "modes": "MODES_LIMIT", "projected": "PROJECTED_LIMIT",
           "null_space": "NULL_SPACE_LIMIT"}


def use_dense(n: int, operation: str) -> bool:
    """True when an ``operation`` ('solve', 'eigen', 'modes', 'projected' or 'null_space') on ``n`` DOFs uses
    dense matrices.

    The limits are read at call time, so a test may lower one (e.g. to 1) to exercise the sparse path.
    """
    try:
        name = _LIMITS[operation]
    except KeyError:
        raise ModalabValueError(f"operation={operation!r}; expected one of {sorted(_LIMITS)}") from None
    return int(n) <= globals()[name]
