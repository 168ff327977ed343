"""Missing-physics diagnosis: locate the mismatch, name the physics, model it, prove it.

:class:`Diagnoser` / :func:`diagnose` (workflow on measured FRFs; ``criterion='auto'|'mci'|'frf'``), :func:`diagnose_modes` (from
identified modes only), :func:`build_library` (candidate augmentations), :func:`screen` (MCI localisation and
candidate ranking), :func:`frf_screen` (exact single-candidate FRF screening by low-rank updates),
:func:`fit_frf` (non-linear FRF fit; in a :class:`RitzBasis` for large models), :func:`peak_modes` (test modes by
peak picking),
:mod:`~updating.diagnosis.report` (figures).  ``Diagnosis.to_dict()`` is the content of ``diagnosis.json``,
which the diagnose stage (:func:`modalab.app.stages.diagnose`) writes, alone, with the figures and ``diagnosed.bdf``.  The FRF workflow's parts: :mod:`~updating.diagnosis.workflow` (the steps),
:mod:`~updating.diagnosis.acceptance` (the tests a term must pass), :mod:`~updating.diagnosis.proof` (the held-out
comparison and the findings' record), :mod:`~updating.diagnosis.priors` (parameters, their priors and the background loss factors per property
group), :mod:`~updating.diagnosis.terms` (a term's effect, its tests and the augmented model),
:mod:`~updating.diagnosis.mesh` (the nominal beam mesh's own frequency error, which a term must exceed),
:mod:`~updating.diagnosis.testmodes` (test modes and their
pairing), :mod:`~updating.diagnosis.findings` (findings, ``Diagnosis``, the statement).

``diagnosis.json`` (``Diagnosis.to_dict()``)::

    {"findings": [{"physics": "ground_spring" | "added_mass" | "joint_flexibility" | "local_damping"
                              | "boundary_flexibility",
                   "nodes": [14], "dofs": ["14+Z"], "elements": [], "description": "spring to ground at 14+Z",
                   "values": [{"name": "k", "value": 210.0, "unit": "N/m", "std": 16.0}],
                   "parts": [...],          # same-physics terms next to it (a mass lumped on two nodes)
                   "ambiguous": false, "alternatives": [{"physics", "nodes", "dofs", "description", "value",
                                                         "unit"}],   # explaining the data as well
                   "evidence": "..."}],
     "parameters": {"E_wing": {"initial": 1.0, "updated": 0.97, "parameters_only": 0.99, "std": 0.01,
                               "mode": "factor", "prior_std": 0.05, "prior_z": -0.6, "at_prior": false}},
     "fit": {"nominal" | "parameters_only" | "with_physics":
                {"frf_error_held_out": 0.04,   # coherence-weighted relative RMS on held-out response rows
                 "frf_error_train": 0.03,
                 "freq_error_max_pct": 1.2,    # vs test modes (given, or peak-picked from the FRFs), MAC-paired
                 "mac_min": 0.98, "n_pairs": 6, "n_unpaired_test": 0, "suspension_cutoff_hz": 2.7,
                 "n_excluded_test": 0, "n_excluded_model": 6}},   # rigid-body/suspension modes left out
     "pairing": {"nominal" | ...: {"pairs": [{"model_hz", "test_hz", "mac", "freq_error_pct"}],
                                   "unpaired_test_hz": [...], "excluded_test_hz": [...], "excluded_model_hz": [...],
                                   "cutoff_hz": 2.7}},
     "statement": "...", "ranking": [...],
     "decisions": [{"decision": "found" | "ambiguous" | "rejected" | "dropped", "candidate", "physics", "reason"}],
     "unobservable": [...], "not_evaluated": [...], "timings_s": {...}}

``"findings": []`` means nothing is missing beyond parameter error.  Values are in SI units (``unit``);
``std`` is the linearised standard deviation of the final joint fit.
"""
from updating.diagnosis.fit import FRFData, fit_frf, frf_data, frf_error, model_frf
from updating.diagnosis.frfscreen import frf_screen
from updating.diagnosis.ritz import RitzBasis
from updating.diagnosis.library import Candidate, build_library
from updating.diagnosis.screen import ScreenResult, residual_map, screen
from updating.diagnosis.workflow import Diagnoser, DiagnoserConfig, diagnose
from updating.diagnosis.priors import default_parameters
from updating.diagnosis.testmodes import peak_modes
from updating.diagnosis.findings import Diagnosis, Finding
from updating.diagnosis.modes import diagnose_modes, fit_modes, modes_data

__all__ = ["diagnose", "Diagnoser", "DiagnoserConfig", "diagnose_modes", "fit_modes", "modes_data", "peak_modes", "Diagnosis", "Finding", "default_parameters", "build_library", "Candidate", "screen",
           "ScreenResult", "residual_map", "fit_frf", "frf_data", "frf_error", "model_frf", "FRFData", "frf_screen",
           "RitzBasis"]
