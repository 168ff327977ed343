"""Figures of the MCI (thesis Figures 17, 26–27, 34–35): the MCI map, its per-DOF maxima and the parameter
convergence figure, the only one in modalab (:class:`~updating.methods.mci.MCIUpdater`, the update stage of
:mod:`modalab.app.stages`, the examples).  Saved as files (matplotlib's object interface).

matplotlib is imported when a figure is drawn, as in :mod:`modalab.core.plots`, so that importing the
updating methods does not load it."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from modalab.core.errors import ModalabValueError

__all__ = ["plot_mci_map", "plot_mci_maxima", "plot_convergence"]


def _figure(figsize):
    from matplotlib.figure import Figure  # lazy: matplotlib, only when drawing (start-up time)

    return Figure(figsize=figsize, constrained_layout=True)


def plot_mci_map(result, path, *, reference: int = 0, title: str = "MCI map"):
    """|MCI| of ``result`` (an :class:`~updating.methods.mci.MCIResult`, not imported here:
    :mod:`~updating.methods.mci` imports these figures) as an image, DOF (rows) × frequency (columns), log
    colour scale; saved to ``path``."""
    from matplotlib.colors import LogNorm  # lazy: matplotlib, only when drawing (start-up time)

    fig = _figure((8, 4))
    ax = fig.add_subplot(1, 1, 1)
    v = np.abs(result.values[:, reference, :])
    pos = v[v > 0]
    norm = LogNorm(vmin=max(pos.min(), pos.max() * 1e-8), vmax=pos.max()) if pos.size else None
    f = result.freq_hz
    im = ax.imshow(np.where(v > 0, v, np.nan), aspect="auto", origin="lower", norm=norm,
                   extent=(f[0], f[-1], -0.5, len(result.dofs) - 0.5), interpolation="nearest")
    ax.set_yticks(range(len(result.dofs)))
    ax.set_yticklabels([str(d) for d in result.dofs])
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("DOF")
    ax.set_title(f"{title} (reference {result.references[reference]})")
    fig.colorbar(im, ax=ax, label="|MCI|")
    fig.savefig(path)
    return fig


def plot_mci_maxima(results, path, *, labels=None, title: str = "absolute maxima of MCI per DOF"):
    """Bar chart of the per-DOF maxima of one or several :class:`~updating.methods.mci.MCIResult` (e.g. initial
    and final)."""
    if hasattr(results, "max_per_dof"):                  # one MCIResult
        results = [results]
    labels = labels or [f"set {k + 1}" for k in range(len(results))]
    fig = _figure((7, 3.5))
    ax = fig.add_subplot(1, 1, 1)
    nd = len(results[0].dofs)
    wdt = 0.8 / len(results)
    for k, (r, lab) in enumerate(zip(results, labels)):
        ax.bar(np.arange(nd) + k * wdt - 0.4 + wdt / 2, r.max_per_dof(), width=wdt, label=lab)
    ax.set_xticks(range(nd))
    ax.set_xticklabels([str(d) for d in results[0].dofs], rotation=90 if nd > 20 else 0)
    ax.set_yscale("log")
    ax.set_ylabel("max |MCI|")
    ax.set_title(title)
    ax.legend()
    fig.savefig(path)
    return fig


def plot_convergence(history, path, *, names=None, reference=None, params=None, normalise: bool = True) -> Path:
    """The one parameter-convergence figure (MCI, eigensensitivity, the update stage): parameter values per
    iteration, row 0 of ``history`` the initial (nominal) vector, saved to ``path`` (parent folders made);
    returns the path.

    ``normalise=True`` divides each parameter by ``reference`` (default the initial row; a zero reference
    divides by 1); ``normalise=False`` draws the values themselves (factors or physical values).  ``params``
    selects the columns drawn (default all); ``names`` labels every column of ``history``.
    """
    H = np.atleast_2d(np.asarray(history, float))
    if names is not None and len(names) != H.shape[1]:
        raise ModalabValueError(f"{H.shape[1]} parameters in the history but {len(names)} names")
    cols = np.arange(H.shape[1]) if params is None else np.atleast_1d(np.asarray(params))
    if normalise:
        ref = H[0] if reference is None else np.asarray(reference, float)
        ref = np.where(ref == 0, 1.0, ref)
    else:
        ref = np.ones(H.shape[1])
    fig = _figure((7, 4))
    ax = fig.add_subplot(1, 1, 1)
    it = np.arange(H.shape[0])
    for c in cols:
        ax.plot(it, H[:, c] / ref[c], marker="o", ms=3, label=None if names is None else names[c])
    ax.set_xlabel("iteration (0 = initial)")
    ax.set_ylabel("parameter / reference" if normalise else "parameter value (factor or physical)")
    ax.set_title("Parameter convergence")
    ax.grid(True, lw=0.3)
    if names is not None and len(cols) <= 30:
        ax.legend(ncol=2, fontsize="small")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100, metadata={"Software": None})
    return path
