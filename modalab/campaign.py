"""Campaigns: the same analysis over many inputs (a GVT with dozens of configurations), in parallel.

:func:`run_many` maps a function over inputs

* on a local process pool by default (``workers`` processes, default the number of CPUs; ``workers=1``
  runs serially in this process), or
* on an existing Dask cluster when given its scheduler address (``dask="tcp://host:8786"``), or a
  ``distributed.Client`` object.  Dask is an optional extra (``pip install -e .[dask]``), imported only
  then.  Start a cluster with ``dask scheduler`` on one machine and ``dask worker tcp://host:8786`` on
  each of the others (every worker needs modalab installed and the input files at the same paths, e.g.
  on a shared file system).

The results come back in the order of the inputs and are the same whichever way they were computed:
the functions are deterministic and each input is processed by one call.  A failure in one input raises
a :class:`modalab.errors.ModalabError` naming that input (the others are still computed;
``errors='collect'`` returns the exception objects in place of results instead).

:func:`identify_many` and :func:`diagnose_many` are the campaign forms of ``modalab identify`` and
``modalab diagnose``: one output folder per input file, a ``campaign.json`` index.
"""
from __future__ import annotations

import json
import logging
import os
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Callable, Sequence

from .errors import ModalabError, ModalabValueError

log = logging.getLogger(__name__)

__all__ = ["run_many", "identify_many", "diagnose_many", "identify_one", "diagnose_one", "CampaignError"]


class CampaignError(ModalabError):
    """One or more inputs of a campaign failed."""


def _client(dask):
    try:
        from distributed import Client
    except ImportError:
        raise ModalabValueError("a Dask scheduler address was given but dask.distributed is not installed; "
                                "install the extra with: pip install -e .[dask]  (or pip install dask distributed)") \
            from None
    if isinstance(dask, Client):
        return dask, False
    if not isinstance(dask, str) or "://" not in dask:
        raise ModalabValueError(f"dask = {dask!r}; expected a scheduler address such as 'tcp://10.0.0.5:8786'")
    try:
        return Client(dask, timeout="20s"), True
    except OSError as e:
        raise ModalabValueError(f"cannot reach the Dask scheduler at {dask} ({e}); start it with 'dask scheduler' "
                                "and check the address and the firewall") from None


def _call(func, x):
    try:
        return True, func(x)
    except Exception as e:  # noqa: BLE001 - returned to the caller, who names the input
        return False, e


def run_many(func: Callable, inputs: Sequence, *, dask=None, workers: int | None = None,
             errors: str = "raise", progress: Callable | None = None) -> list:
    """``[func(x) for x in inputs]`` in parallel (see the module docstring).

    func must be picklable (a module-level function or a ``functools.partial`` of one).
    progress : callable ``(n_done, n_total)``.
    errors : 'raise' (a :class:`CampaignError` listing the failed inputs) or 'collect'.
    """
    if errors not in ("raise", "collect"):
        raise ModalabValueError(f"errors = {errors!r}; expected 'raise' or 'collect'")
    inputs = list(inputs)
    n = len(inputs)
    out: list = [None] * n
    if n == 0:
        return out
    if dask is not None:
        client, own = _client(dask)
        try:
            futs = client.map(_call, [func] * n, inputs, pure=False)
            from distributed import as_completed

            index = {f.key: i for i, f in enumerate(futs)}
            done = 0
            for fut in as_completed(futs):
                out[index[fut.key]] = fut.result()
                done += 1
                if progress:
                    progress(done, n)
        finally:
            if own:
                client.close()
    else:
        w = (os.cpu_count() or 1) if workers is None else int(workers)
        if w < 1:
            raise ModalabValueError(f"workers = {workers!r}; expected a positive number of processes")
        w = min(w, n)
        if w == 1:
            for i, x in enumerate(inputs):
                out[i] = _call(func, x)
                if progress:
                    progress(i + 1, n)
        else:
            import multiprocessing as mp

            ctx = mp.get_context("spawn")     # no fork of a process holding BLAS threads or a GUI
            with ProcessPoolExecutor(max_workers=w, mp_context=ctx) as ex:
                futs = [ex.submit(_call, func, x) for x in inputs]
                for i, f in enumerate(futs):
                    out[i] = f.result()
                    if progress:
                        progress(i + 1, n)
    failed = [(i, r[1]) for i, r in enumerate(out) if not r[0]]
    if failed and errors == "raise":
        lines = "; ".join(f"input {inputs[i]!r}: {type(e).__name__}: {e}" for i, e in failed[:5])
        more = f" (and {len(failed) - 5} more)" if len(failed) > 5 else ""
        raise CampaignError(f"{len(failed)} of {n} campaign inputs failed: {lines}{more}")
    return [r[1] for r in out]


# ----------------------------------------------------------------------------- campaign commands
def identify_one(job: dict) -> dict:
    """Identify one FRF file into ``job['out']`` (modes.uff, identification.json, figures); returns a summary."""
    from identification import identify

    from . import uff

    out = Path(job["out"])
    out.mkdir(parents=True, exist_ok=True)
    frf = uff.read_frf(job["frf"])
    band = job.get("band_hz")
    if band:
        frf = frf.band(float(band[0]), float(band[1]))
    else:
        f = frf.freq_hz
        frf = frf.band(float(f[f > 0][0]), float(f[-1]))
    modes, rep = identify(frf, max_order=job.get("max_order"), plots_dir=out if job.get("plots", True) else None)
    mp = out / "modes.uff"
    if mp.exists():
        mp.unlink()
    uff.write_modes(mp, modes)
    rep.to_json(out / "identification.json")
    return {"input": str(job["frf"]), "out": str(out), "freq_hz": [float(x) for x in modes.freq_hz],
            "damping": [float(x) for x in modes.damping]}


def diagnose_one(job: dict) -> dict:
    """Diagnose one FRF file against the bulk-data model ``job['model']``; writes diagnosis.json."""
    from updating.bulk import read_bdf
    from updating.bulk.build import build_model
    from updating.diagnosis import diagnose

    from . import uff
    from .project import load_parameters

    out = Path(job["out"])
    out.mkdir(parents=True, exist_ok=True)
    model = build_model(read_bdf(job["model"]))
    params = load_parameters(job["parameters"])[0] if job.get("parameters") else None
    frf = uff.read_frf(job["frf"])
    band = job.get("band_hz")
    if band:
        frf = frf.band(float(band[0]), float(band[1]))
    kw = {k: job[k] for k in ("max_lines", "max_findings", "max_nfev", "holdout", "kinds") if job.get(k) is not None}
    d = diagnose(model, frf, parameters=params, **kw)
    dd = d.to_dict()
    (out / "diagnosis.json").write_text(json.dumps(dd, indent=1, default=float))
    return {"input": str(job["frf"]), "out": str(out), "statement": d.statement,
            "findings": dd["findings"], "parameters": dd["parameters"]}


def _jobs(frf_paths, out_dir, common: dict) -> list:
    out_dir = Path(out_dir)
    paths = [Path(p) for p in frf_paths]
    stems = [p.stem for p in paths]
    jobs = []
    for k, p in enumerate(paths):
        name = p.stem if stems.count(p.stem) == 1 else f"{k:03d}_{p.stem}"
        jobs.append({**common, "frf": str(p.resolve()), "out": str((out_dir / name).resolve())})
    return jobs


def _index(out_dir, results) -> Path:
    p = Path(out_dir) / "campaign.json"
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(json.dumps(results, indent=1, default=float))
    return p


def identify_many(frf_paths, out_dir, *, band_hz=None, max_order=None, plots: bool = True, dask=None,
                  workers=None, progress=None) -> list:
    """``modalab identify`` over many FRF files: ``out_dir/<file stem>/`` each, ``out_dir/campaign.json``."""
    jobs = _jobs(frf_paths, out_dir, {"band_hz": band_hz, "max_order": max_order, "plots": plots})
    res = run_many(identify_one, jobs, dask=dask, workers=workers, progress=progress)
    _index(out_dir, res)
    return res


def diagnose_many(model_path, frf_paths, out_dir, *, parameters=None, band_hz=None, max_lines=None,
                  max_findings=None, max_nfev=None, dask=None, workers=None, progress=None) -> list:
    """``modalab diagnose`` of one model against many FRF files (configurations) in parallel."""
    common = {"model": str(Path(model_path).resolve()), "parameters": str(Path(parameters).resolve()) if parameters
              else None, "band_hz": band_hz, "max_lines": max_lines, "max_findings": max_findings,
              "max_nfev": max_nfev}
    jobs = _jobs(frf_paths, out_dir, common)
    res = run_many(diagnose_one, jobs, dask=dask, workers=workers, progress=progress)
    _index(out_dir, res)
    return res
