"""File helpers of the command line (the stages themselves, acquire included, are in :mod:`modalab.app.stages`).

:func:`file_info` says what a UFF holds, :func:`demo` runs the embedded demo project; ``acquire`` and
``make_sim_backend`` are re-exported from :mod:`modalab.app.stages._acquire`;
``load_model``/``load_modes`` come from :mod:`modalab.app.stages` (a parameter file: its ``load_parameters``).
"""
from __future__ import annotations

import logging

from modalab.app.stages import load_model, load_modes  # re-exported (listed in __all__)
# the acquire stage lives in modalab.app.stages._acquire (one implementation); its names stay importable here
from modalab.app.stages._acquire import acquire, make_sim_backend
from modalab.core import uff
from modalab.app.demo_project import run_demo

log = logging.getLogger(__name__)

__all__ = ["file_info", "make_sim_backend", "acquire", "demo", "load_model", "load_modes"]


# ------------------------------------------------------------------------- files
def file_info(path) -> dict:

    return uff.info(path)


# ------------------------------------------------------------------------- the demo
def demo(out_dir, *, quick: bool = False, progress=None):
    """The README's main job: the whole chain on the embedded demo project (:func:`modalab.app.demo_project.run_demo`);
    returns the :class:`modalab.app.run.RunResult`."""

    return run_demo(out_dir, quick=quick, progress=progress)


