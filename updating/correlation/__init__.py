"""Test–analysis correlation (thesis section 2.2) and the maps between test and model DOFs.

By task:

Compare mode sets
    :func:`mac`, :func:`automac`, :func:`macx`, :func:`msf`, :func:`comac`, :func:`ecomac`,
    :func:`cross_orthogonality`, :func:`mixed_orthogonality`, :func:`frequency_table`.
Pair test and analysis modes
    :func:`pair_modes` → :class:`Pairing`; :func:`correlate` → :class:`CorrelationResult`.
Compare FRFs
    :func:`frac`, :func:`csac`, :func:`csf`, :func:`frf_correlation`.
Map test DOFs onto the model
    :class:`DofMap`, :func:`as_dofmap`, :func:`observation_matrix`.
Measured FRFs on the model, and their dynamic expansion
    :mod:`updating.correlation.receptance` (:class:`~.receptance.FRFData`, :func:`~.receptance.frf_data`,
    :func:`~.receptance.measured_columns`); :mod:`updating.correlation.condensation`
    (:func:`~.condensation.condensed_residual`, :func:`~.condensation.solve_columns`) — the one
    adapter and the one Kidder-type expansion that MCI, RFM and diagnosis share.
Reduce and expand (section 2.1)
    :func:`guyan`, :func:`irs`, :func:`serep`, :func:`reduce`; :func:`kidder`, :func:`serep_expand`,
    :func:`modal_expand`.
Figures
    :mod:`updating.correlation.plots`.
"""
from updating.correlation.dofmap import DofMap, as_dofmap, observation_matrix
from updating.correlation.expansion import kidder, modal_expand, serep_expand
from updating.correlation.metrics import *  # noqa: F401,F403  (the public names are metrics.__all__)
from updating.correlation.metrics import __all__ as _metrics_all
from updating.correlation.reduction import ReducedModel, guyan, irs, master_indices, reduce, serep

__all__ = [*_metrics_all, "DofMap", "as_dofmap", "observation_matrix", "kidder", "modal_expand",
           "serep_expand", "ReducedModel", "guyan", "irs", "master_indices", "reduce", "serep"]
