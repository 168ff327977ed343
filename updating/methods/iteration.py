"""The one parameter iteration of the FRF-based updaters: MCI, the response-function method and diagnosis.

Thesis section 3.2.4 (and 3.2.3 alike) prescribes the same loop for every FRF-based method: linearise the
residual at the current parameters (re-expanding the unmeasured DOFs with the current model,
:mod:`updating.correlation.condensation`), solve the linear system for a parameter step, update, repeat
until the parameters stop moving.  :func:`iterate` is that loop, written once: bounds, the limit on the
relative step, the halving line search, the convergence test, the history and the log.  What differs
between the methods is only how a step is computed at ``p`` (their residual, weights and least-squares
step), which each passes as ``propose``:

- :class:`~updating.methods.mci.MCIUpdater` (``modalab update --method mci``): the projected, whitened or
  fixed-expansion MCI (Eq. 3.70–3.78), penalty on the departure from the start, step limit, line search;
- :class:`~updating.methods.rfm.ResponseFunctionMethod` (Eq. 3.54–3.57): normal equations of the response
  residual;
- :func:`~updating.methods.mci_condensed.mci_update` (diagnosis' background fit): the condensed MCI with
  coherence/noise line weights and a damped (Levenberg-type) step.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from modalab.core.errors import ModalabValueError, ShapeError

log = logging.getLogger(__name__)

__all__ = ["Proposal", "Iterations", "iterate", "start", "default_bounds"]


@dataclass
class Proposal:
    """A step proposed at ``p``: ``dp`` for the parameters being updated, the cost at ``p`` and, for a line
    search, ``accept(p_new) -> bool`` (None: take the step as it is)."""

    dp: np.ndarray
    cost: float
    accept: Callable[[np.ndarray], bool] | None = None


@dataclass
class Iterations:
    """What :func:`iterate` returns: the last parameters, one history dict per iteration
    (iteration, p, max_rel_change, cost — the cost at the start of the iteration), whether the change fell
    below ``tol``, the number of iterations run and the last relative change."""

    p: np.ndarray
    history: list = field(default_factory=list)
    converged: bool = False
    n_iter: int = 0
    change: float = np.inf


def iterate(propose: Callable[[np.ndarray], Proposal], p, idx, lower, upper, *, max_iter: int, tol: float,
            change_ref: Callable[[np.ndarray, np.ndarray], np.ndarray], step_limit: float | None = None,
            step_ref=None, halvings: int = 12, label: str = "update") -> Iterations:
    """Iterate ``p[idx] ← clip(p[idx] + step·dp)`` with ``dp`` from ``propose(p)`` until the parameters stop.

    ``lower``/``upper`` bound every parameter; ``change_ref(p, p_new)`` gives the scale of each parameter
    for the relative change (converged when ``max |Δp| / change_ref < tol``); ``step_limit`` scales ``dp``
    down to that largest relative change (relative to ``step_ref``); a proposal with ``accept`` is halved up
    to ``halvings`` times until accepted (the last, smallest step is taken if none is).
    """
    p = np.array(p, dtype=float)
    idx = np.asarray(idx, int)
    out = Iterations(p=p)
    for it in range(1, max_iter + 1):
        prop = propose(p)
        dp = prop.dp
        if step_limit is not None:
            rel = np.abs(dp) / step_ref[idx]
            if rel.max() > step_limit:
                dp = dp * (step_limit / rel.max())
        p_new = _line_search(p, idx, dp, lower, upper, prop.accept, halvings)
        out.change = float(np.max(np.abs(p_new[idx] - p[idx]) / change_ref(p, p_new)[idx]))
        p = p_new
        out.history.append({"iteration": it, "p": p.copy(), "max_rel_change": out.change, "cost": prop.cost})
        out.n_iter = it
        log.debug("%s iteration %d: cost %.4g, max relative change %.3g", label, it, prop.cost, out.change)
        if out.change < tol:
            out.converged = True
            break
    out.p = p
    return out


def _line_search(p, idx, dp, lower, upper, accept, halvings):
    step = 1.0
    for _ in range(halvings):
        p_new = p.copy()
        p_new[idx] = np.clip(p[idx] + step * dp, lower[idx], upper[idx])
        if accept is None or accept(p_new):
            break
        step *= 0.5
    return p_new


def start(model, p_init, bounds):
    """The starting parameters (``model.p0`` or ``p_init``, checked against its shape) and their bounds
    (:func:`default_bounds`)."""
    p = np.array(model.p0 if p_init is None else p_init, dtype=float)
    if p.shape != np.shape(model.p0):
        raise ShapeError(f"p_init has shape {p.shape}; expected {np.shape(model.p0)}")
    return (p,) + default_bounds(bounds, p)


def default_bounds(bounds, p0):
    """``(lower, upper)`` arrays: ``bounds`` broadcast to ``p0``, or by default ``[0.05, 20]×p0`` with the sign
    kept and ``≥ 0`` where ``p0 = 0`` (the guard against the trivial solution, thesis 6.1.2)."""
    if bounds is None:
        lo = np.where(p0 > 0, 0.05 * p0, np.where(p0 < 0, 20 * p0, 0.0))
        hi = np.where(p0 > 0, 20 * p0, np.where(p0 < 0, 0.05 * p0, np.inf))
        return lo, hi
    lo, hi = bounds
    lo = np.broadcast_to(np.asarray(-np.inf if lo is None else lo, float), p0.shape).copy()
    hi = np.broadcast_to(np.asarray(np.inf if hi is None else hi, float), p0.shape).copy()
    if np.any(lo > hi):
        raise ModalabValueError("bounds: some lower bounds exceed the upper ones; pass (lower, upper) arrays")
    return lo, hi
