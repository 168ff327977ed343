"""modalab — from the lab bench to an updated, diagnosed finite-element model.

The core package holds what every stage shares:

DOF labels
    :class:`Dof`, :func:`parse_dofs` — ``"12+Z"`` ↔ node 12, UFF direction +3.
Containers
    :class:`FRF` — labelled ``(n_out, n_in, n_freq)`` FRFs with coherence and units.
    :class:`TimeRecord` — one hammer hit, all channels.
    :class:`ModeSet` — modes on DOF labels (identification → updating).
Structures
    :class:`Structure` — sparse M, K, C, D with exact FRFs; :class:`ModalModel`.
Files
    :mod:`modalab.core.uff` — universal file I/O (15, 2411, 55, 58/58b, 164).
Errors
    :class:`ModalabError` and its subclasses in :mod:`modalab.core.errors`.

The core lives in :mod:`modalab.core`; the stages in their own top-level packages (``acquisition`` →
``identification`` → ``updating``, with ``hardware_sim`` beside acquisition); the command line, stage
runner, campaigns and report in :mod:`modalab.app` on top.
"""
import logging

from .core.dof import Dof, parse_dofs
from .core.errors import ModalabError
from .core.frf import FRF, concat
from .core.modes import ModeSet
from .core.records import TimeRecord
from .core.structure import ModalModel, Structure

__version__ = "0.1.0"
__all__ = ["Dof", "parse_dofs", "ModalabError", "FRF", "concat", "ModeSet", "TimeRecord",
           "Structure", "ModalModel", "__version__"]

logging.getLogger(__name__).addHandler(logging.NullHandler())
