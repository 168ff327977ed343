"""Test-suite settings.

Small dense eigenproblems dominate identification and the FE tests; on a 2-core
machine a multi-threaded BLAS makes them 10-30x slower, so the suite runs with
one BLAS thread (set before numpy loads its BLAS).
"""
import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
os.environ.setdefault("MPLBACKEND", "Agg")
_NUMPY_FIRST = "numpy" in __import__("sys").modules  # True would mean the BLAS setting came too late

# In CI (CI=true) hypothesis runs derandomised: the same examples every run, so a red build is
# reproducible; locally it explores new examples each time.
try:
    from hypothesis import settings as _hsettings

    _hsettings.register_profile("ci", derandomize=True, print_blob=True)
    if os.environ.get("CI"):
        _hsettings.load_profile("ci")
except ImportError:  # pragma: no cover
    pass
