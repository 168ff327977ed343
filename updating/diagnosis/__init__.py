"""Missing-physics diagnosis: locate the mismatch, name the physics, model it, prove it.

:func:`diagnose` (workflow), :func:`diagnose_modes` (from identified modes only), :func:`build_library` (candidate augmentations),
:func:`screen` (MCI localisation and candidate ranking), :func:`fit_frf` (non-linear FRF fit).
"""
from .fit import FRFData, fit_frf, frf_data, frf_error, model_frf
from .library import Candidate, build_library
from .screen import ScreenResult, residual_map, screen
from .workflow import Diagnosis, Finding, default_parameters, diagnose, peak_modes
from .modes import diagnose_modes, fit_modes, modes_data

__all__ = ["diagnose", "diagnose_modes", "fit_modes", "modes_data", "peak_modes", "Diagnosis", "Finding", "default_parameters", "build_library", "Candidate", "screen",
           "ScreenResult", "residual_map", "fit_frf", "frf_data", "frf_error", "model_frf", "FRFData"]
