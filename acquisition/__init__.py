"""
acquisition — impact testing in the lab: DAQ, serial instruments, hit checks, FRFs, sessions
==========================================================================================

This is the bench engineer's stage (``modalab acquire``): a test plan is run on a
DAQ backend, every hit is checked, accepted or rejected, stored durably and
averaged into H1 FRFs with coherence, exported as one UFF.  It depends on the
:mod:`modalab` core only (the simulated lab in :mod:`hardware_sim` satisfies
:class:`DaqBackend` structurally and is wired in by :mod:`modalab.app.pipeline`).

Test plans (:mod:`acquisition.plan`)
------------------------------------
.. autosummary::

   load_plan            -- read and validate a TOML test plan (errors name the key and the fix)
   TestPlan             -- the validated plan: timing, trigger, windows, channels, roving pattern, geometry
   PlanChannel          -- one channel of the plan (sensitivity in V per SI unit, range, DOF or 'roving')

DAQ backends (:mod:`acquisition.backend`, :mod:`acquisition.nidaqmx_backend`)
-----------------------------------------------------------------------------
.. autosummary::

   DaqBackend           -- protocol: configure / notify_point / arm / wait / abort / close, context manager
   open_backend         -- a backend by name ('nidaqmx'; 'sim' comes from modalab.app.pipeline.make_sim_backend)
   NidaqmxBackend       -- NI-DAQmx: IEPE force/accel channels, finite timing, analog reference trigger
   BACKENDS             -- the backend names

Serial instruments (:mod:`acquisition.instruments`)
---------------------------------------------------
.. autosummary::

   open_serial          -- ``serial.serial_for_url`` with our defaults
   LineTransport        -- ASCII line transport (write_line / read_line / query)
   IEPEConditioner      -- ``unit:channel:CMD=value`` signal conditioner (gain, mode, excitation, overload)
   AutoHammer           -- automatic impact hammer (ARM, FIRE <N>, status)

Checking a hit (:mod:`acquisition.checks`)
------------------------------------------
.. autosummary::

   check_hit            -- double hit, overload, weak/missing trigger, not decayed, pretrigger content
   check_hits           -- check_hit for many records
   HitCheckConfig       -- the thresholds
   HitReport            -- flags, messages and measured values of one hit
   FLAGS                -- every flag check_hit can raise

Windows (:mod:`acquisition.windows`)
------------------------------------
.. autosummary::

   ForceWindow, force_window              -- rectangular force window with cosine taper
   ExponentialWindow, exponential_window  -- exponential window (end level or decay rate beta)
   ExpWindowResult                        -- window array and its beta
   beta_from_end_level                    -- beta (1/s) for a given level at the record end
   correct_poles, correct_damping         -- remove the window's added damping (s = i*omega + beta)

FRF estimation (:mod:`acquisition.spectral`; array estimators in :mod:`acquisition.estimators`)
-----------------------------------------------------------------------------------------------
.. autosummary::

   estimate_frf          -- H1/H2/Hv + coherence from hits with one channel layout (SIMO, MIMO)
   estimate_frf_roving   -- roving-hammer hits grouped by hit DOF, concatenated along references
   SpectralAverager      -- running average for a live FRF: add / remove a hit, frf()
   group_by_reference    -- hits grouped by their force DOFs
   cross_spectra, CrossSpectra                 -- averaged auto/cross spectra of arrays
   h1, h2, hv, coherence, multiple_coherence   -- array estimators (scipy.signal style)
   quantity_from_unit, ESTIMATORS              -- helpers

Reciprocity (:mod:`acquisition.reciprocity`)
--------------------------------------------
.. autosummary::

   reorder_by_reciprocity -- roving-hammer matrix transposed so accelerometers become references
   reciprocity_check      -- H_ij against H_ji where both are measured
   ReciprocityReport, ReciprocityPair

Sessions: measure, never lose a hit (:mod:`acquisition.session`, :mod:`acquisition.store`)
------------------------------------------------------------------------------------------
The session's FRFs, hit choice and export are in :mod:`acquisition.session_results`, its observer,
prompter and summaries in :mod:`acquisition.session_summary`, resume checks and reconnecting in
:mod:`acquisition.session_resume`; every name below is importable from :mod:`acquisition.session`.

.. autosummary::

   AcquisitionSession   -- arm (then fire an automatic hammer), wait, check, accept/reject, store, export
   ScriptedPrompter     -- scripted answers for interactive mode (tests, batch runs)
   SessionObserver      -- what the session shows (hits, running FRF, decisions, messages)
   SessionSummary, PointSummary -- per point: hits taken, accepted, rejected and why, warnings, coherence
   suggest_range        -- a better input range for a peak that uses the current one badly
   frf_from_hits        -- one point's H1 FRF with the plan's windows
   session_frf          -- a session's FRF matrix (reordered by reciprocity for a roving hammer)
   export_session       -- geometry, raw records, FRFs and coherence to one UFF
   mean_coherence, best_subset -- coherence score, best N of M hits
   REJECT_FLAGS, WARN_FLAGS, STANDARD_RANGES
   HitStore             -- crash-safe, fsync-ed journal + raw hit files of a session directory
   PointState           -- what the journal says about one point

Example
-------
>>> from acquisition import load_plan, AcquisitionSession        # doctest: +SKIP
>>> from modalab.app.pipeline import make_sim_backend                 # doctest: +SKIP
>>> plan = load_plan("examples/plans/demo_roving_hammer.toml")    # doctest: +SKIP
>>> session = AcquisitionSession(plan, make_sim_backend(plan), "session", mode="auto")  # doctest: +SKIP
>>> summary = session.run(); session.export()                     # doctest: +SKIP
"""
from .backend import BACKENDS, DaqBackend, open_backend
from .checks import FLAGS, HitCheckConfig, HitReport, check_hit, check_hits
from .instruments import AutoHammer, IEPEConditioner, LineTransport, open_serial
from .nidaqmx_backend import NidaqmxBackend
from .plan import PlanChannel, TestPlan, load_plan
from .reciprocity import ReciprocityPair, ReciprocityReport, reciprocity_check, reorder_by_reciprocity
from .session import (REJECT_FLAGS, STANDARD_RANGES, WARN_FLAGS, AcquisitionSession, PointSummary, ScriptedPrompter,
                      SessionObserver, SessionSummary, best_subset, export_session, frf_from_hits, mean_coherence,
                      session_frf, suggest_range)
from .spectral import (ESTIMATORS, CrossSpectra, SpectralAverager, coherence, cross_spectra, estimate_frf,
                       estimate_frf_roving, group_by_reference, h1, h2, hv, multiple_coherence, quantity_from_unit)
from .store import HitStore, PointState
from .windows import (ExponentialWindow, ExpWindowResult, ForceWindow, beta_from_end_level, correct_damping,
                      correct_poles, exponential_window, force_window)

__all__ = [
    # plans
    "load_plan", "TestPlan", "PlanChannel",
    # backends
    "DaqBackend", "open_backend", "NidaqmxBackend", "BACKENDS",
    # serial instruments
    "open_serial", "LineTransport", "IEPEConditioner", "AutoHammer",
    # checks
    "check_hit", "check_hits", "HitCheckConfig", "HitReport", "FLAGS",
    # windows
    "ForceWindow", "force_window", "ExponentialWindow", "exponential_window", "ExpWindowResult",
    "beta_from_end_level", "correct_poles", "correct_damping",
    # spectral
    "estimate_frf", "estimate_frf_roving", "SpectralAverager", "group_by_reference", "cross_spectra",
    "CrossSpectra", "h1", "h2", "hv", "coherence", "multiple_coherence", "quantity_from_unit", "ESTIMATORS",
    # reciprocity
    "reorder_by_reciprocity", "reciprocity_check", "ReciprocityReport", "ReciprocityPair",
    # sessions and storage
    "AcquisitionSession", "ScriptedPrompter", "SessionObserver", "SessionSummary", "PointSummary",
    "suggest_range", "frf_from_hits", "session_frf", "export_session", "mean_coherence", "best_subset",
    "REJECT_FLAGS", "WARN_FLAGS", "STANDARD_RANGES", "HitStore", "PointState",
]
