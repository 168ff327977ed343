"""Shared by the stages: their result type and the loaders of models, modes and parameters."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from modalab.core.errors import PlanError
from updating.fe.bulk import build_model, read_bdf
from modalab.core.modes import ModeSet
from modalab.app.project import load_parameters as _load

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class StageResult:
    """What a stage produced: ``result`` (the product), ``files`` (written, in order) and ``summary``."""

    result: object
    files: tuple = ()
    summary: dict = field(default_factory=dict)


def _tuple(x):
    return None if x is None else tuple(x)


# ============================================================================ shared inputs
def load_model(path):
    """An FE model from Nastran bulk data (``.bdf``, ``.dat``, ``.nas``, ``.blk``)."""

    p = Path(path)
    if not p.is_file():
        raise PlanError(f"model file {str(p)!r} does not exist; give a Nastran bulk-data file (.bdf)")
    return build_model(read_bdf(p, whole_model=True))


def load_modes(path):
    """Test modes from a UFF (dataset 55) or a ``modes.json`` written by ``modalab identify``."""

    p = Path(path)
    if p.suffix.lower() == ".json":
        return ModeSet.from_json(p)
    return ModeSet.from_uff(p)


def load_parameters(path, model) -> tuple[list, np.ndarray, np.ndarray]:
    """Updating parameters and their bounds: the TOML ``[[parameter]]`` file, or (``path`` None) the default
    E and density multipliers per property group without bounds."""
    if path is None:
        from updating.diagnosis.workflow import default_parameters

        params = default_parameters(model)
        return params, np.full(len(params), -np.inf), np.full(len(params), np.inf)

    params, lo, hi = _load(path)
    return (params, np.array([-np.inf if v is None else float(v) for v in lo]),
            np.array([np.inf if v is None else float(v) for v in hi]))


def _band(H, band):
    if band:
        return H.band(float(band[0]), float(band[1]))
    f = H.freq_hz
    return H.band(float(f[f > 0][0]), float(f[-1]))
