"""The stages of modalab, one function each: ``modalab <verb>``, ``modalab run`` and campaigns all call these.

The chain is acquire → frf → identify → correlate → update → diagnose → report (``sim`` makes raw hits
without a test plan).  Each stage is implemented once, in its own module: ``_acquire.py``, ``_sim.py``,
``_frf.py``, ``_identify.py``, ``_correlate.py``, ``_update.py``, ``_diagnose.py``, ``_report.py`` (shared
loaders in ``_common.py``); this namespace is the API.

=============  ==============================================  ===================================================
stage          function                                        writes
=============  ==============================================  ===================================================
acquire        :func:`acquire` (:class:`AcquireOptions`)       the session folder (hits, journal,
                                                               ``session.json`` with the backend,
                                                               ``summary.json``), its UFF
sim            :func:`sim` (:class:`SimOptions`)               raw hits (UFF 58), ``OUTPUT_first_hit.png``;
                                                               ``model.bdf``, ``params.toml`` with ``export_model``
frf            :func:`frf` (:class:`FRFOptions`)               FRFs + coherence (UFF 58), figure; with
                                                               ``details_dir``: ``frf.json``, ``reciprocity.json``,
                                                               ``coherence.png``
identify       :func:`identify` (:class:`IdentifyOptions`)     modes (UFF 55), ``modes.json``,
                                                               ``identification.json``, stabilisation diagram,
                                                               synthesis, AutoMAC
correlate      :func:`correlate` (:class:`CorrelateOptions`)   ``correlation.json``, ``mac_before.png``,
                                                               ``frequencies_before.png``, ``comac.png``
update         :func:`update` (:class:`UpdateOptions`)         ``updated.bdf`` (or ``updated_matrices.npz``),
                                                               ``update.json``, MAC/frequency plots,
                                                               ``convergence.png``
diagnose       :func:`diagnose` (:class:`DiagnoseOptions`)     ``diagnosis.json``; with ``out_dir``: the engine's
                                                               ``figures/``, ``diagnosed.bdf``,
                                                               ``frf_overlay_models.png``
report         :func:`report` (:class:`ReportOptions`)         ``report.html``, ``summary.json``
=============  ==============================================  ===================================================

Each function takes its input files, its output locations and one frozen options dataclass, and returns a
:class:`StageResult`: the product (an :class:`Acquisition` — the session, its summary and the exported UFF —,
an FRF, a ModeSet, a correlation, a summary dict, a Diagnosis, the report's path), the files it wrote and a
short JSON-ready summary.  Run-time objects are keywords beside the options (a ``progress`` callable, the
acquisition's prompter, observer or a ready backend).  Every text/JSON file goes through
:mod:`modalab.app.outputs` (one writer, umask permissions, atomic replace); ``modes.json``, ``diagnosis.json``,
the report's ``summary.json`` and the session folder's ``summary.json`` follow the schemas shipped in
``modalab/app/schemas``.  Library code logs; ``progress`` callables let the CLI show progress.
"""
from __future__ import annotations

from modalab.app.stages._acquire import AcquireOptions, Acquisition, acquire, make_sim_backend
from modalab.app.stages._common import StageResult, load_model, load_modes, load_parameters
from modalab.app.stages._correlate import CorrelateOptions, DofMapping, analysis_modes_covering, correlate, resolve_dof_map
from modalab.app.stages._diagnose import DiagnoseOptions, diagnose
from modalab.app.stages._frf import FRFOptions, frf
from modalab.app.stages._identify import IdentifyOptions, identify
from modalab.app.stages._report import ReportOptions, report
from modalab.app.stages._sim import SimOptions, _sim_structure, demo_fe_model, sim
from modalab.app.stages._update import UPDATE_METHODS, UpdateOptions, update

__all__ = ["StageResult", "acquire", "make_sim_backend", "AcquireOptions", "Acquisition", "ReportOptions", "SimOptions", "FRFOptions", "IdentifyOptions", "CorrelateOptions", "UpdateOptions",
           "DiagnoseOptions", "sim", "frf", "identify", "correlate", "update", "diagnose", "report",
           "load_model", "load_modes", "load_parameters", "demo_fe_model", "UPDATE_METHODS",
           "DofMapping", "resolve_dof_map", "analysis_modes_covering"]
