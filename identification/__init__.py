"""Modal identification from FRFs (``modalab`` stage 2: acquisition → **identification** → updating).

One call
========
:func:`identify`
    ``identify(frf, *, band_hz=None, max_order=None, select='auto', references=None,
    plots_dir=None, weighting=None, ...) -> (ModeSet, IdentificationReport)`` — poly-reference
    pLSCF, stabilisation, automatic or manual pole selection, LSFD, scaling, indicators, figures.

Estimator
=========
:class:`PolyMAX`
    scikit-learn style estimator: ``PolyMAX(max_order=64, weighting=None, ...).fit(frf)`` sets
    ``orders_``, ``poles_``, ``participation_``, ``stabilisation_``, ``selected_``, ``lsfd_``,
    ``modes_``.  Raises :class:`modalab.core.errors.NotFittedError` before ``fit``.
:func:`reduced_normal_matrix`, :func:`poles_at_order`, :func:`frequency_weights`
    the building blocks: reduced normal equations built once for the highest order (Toeplitz lag
    sums, vectorised over outputs), poles and participation vectors of any lower order from its
    leading block.

Stabilisation and selection
===========================
:class:`StabilisationCriteria`  frozen tolerances (1 % frequency, 5 % damping, MAC 0.98).
:func:`stabilise`, :class:`StabilisationDiagram`  flags per pole against the previous order.
:class:`SelectionOptions`, :func:`select_poles`, :func:`auto_select`, :func:`select_frequencies`,
:func:`load_selection_file`, :class:`SelectedPoles`  clustering or the analyst's choice.

Mode shapes
===========
:func:`lsfd`, :class:`LSFDResult`  poly-reference LSFD with lower/upper residuals, synthesis.
:func:`refine_poles`  local variable-projection refinement of the selected poles.
:func:`modes_from_poles`  LSFD + exponential-window correction + unit-modal-mass scaling + indicators.
:func:`driving_points`  response/reference pairs on the same DOF.

Indicators
==========
:func:`mpc`, :func:`mpd`, :func:`mcf`, :func:`mov`, :func:`frf_correlation`, :func:`synthesis_error`,
:func:`auto_mac`, :func:`mac_vectors`; :func:`edge_resonances` (resonances an edge of the band cuts).

Figures
=======
:func:`plot_stabilisation` (with CMIF or Σ|H|), :func:`plot_synthesis`, :func:`plot_automac`.

Synthetic data
==============
:func:`modal_system`, :func:`noisy_frf`  known modes by modal superposition, noisy FRFs.

Notes
-----
Small dense eigenproblems dominate the order loop; on a loaded machine a multi-threaded BLAS can be
much slower than one thread: set ``OPENBLAS_NUM_THREADS=1`` (or the equivalent) before starting Python.
"""
from .api import IdentificationReport, default_max_order, identify
from .indicators import auto_mac, edge_resonances, frf_correlation, mcf, mov, mpc, mpd, synthesis_error
from .lsfd import (LSFDResult, driving_points, frf_noise_variance, lsfd, modes_from_poles, pole_uncertainty,
                   refine_poles, window_corrected_covariance)
from .plots import plot_automac, plot_stabilisation, plot_synthesis
from .polymax import PolyMAX, frequency_weights, poles_at_order, reduced_normal_matrix
from .selection import (SelectedPoles, SelectionOptions, auto_select, load_selection_file, select_frequencies,
                        select_poles)
from .synthetic import modal_system, noisy_frf
from .stabilisation import StabilisationCriteria, StabilisationDiagram, mac_vectors, pole_freq_damping, stabilise

__all__ = [
    "identify", "IdentificationReport", "default_max_order",
    "PolyMAX", "frequency_weights", "reduced_normal_matrix", "poles_at_order",
    "StabilisationCriteria", "StabilisationDiagram", "stabilise", "mac_vectors", "pole_freq_damping",
    "SelectionOptions", "SelectedPoles", "select_poles", "auto_select", "select_frequencies", "load_selection_file",
    "LSFDResult", "lsfd", "refine_poles", "driving_points", "modes_from_poles",
    "pole_uncertainty", "frf_noise_variance", "window_corrected_covariance",
    "mpc", "mpd", "mcf", "mov", "frf_correlation", "synthesis_error", "auto_mac", "edge_resonances",
    "plot_stabilisation", "plot_synthesis", "plot_automac", "modal_system", "noisy_frf",
]
