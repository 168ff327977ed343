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
a :class:`modalab.core.errors.ModalabError` naming that input (the others are still computed;
``errors='collect'`` returns the exception objects in place of results instead).

:func:`identify_many` and :func:`diagnose_many` are the campaign forms of ``modalab identify`` and
``modalab diagnose``: one output folder per input file, a ``campaign.json`` index.
"""
from __future__ import annotations

import functools
import logging
import os
import multiprocessing as mp
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Callable, Sequence

from modalab.core.errors import ModalabError, ModalabValueError
from modalab.app import stages
from modalab.app.outputs import write_json

log = logging.getLogger(__name__)

__all__ = ["run_many", "identify_many", "diagnose_many", "identify_one", "diagnose_one", "CampaignError"]


class CampaignError(ModalabError):
    """One or more inputs of a campaign failed."""


def _client(dask):
    try:
        from distributed import Client  # lazy: optional distributed (dask extra)
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
            from distributed import as_completed  # lazy: optional distributed (dask extra)

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
def identify_one(frf_path, out_dir, opts=None, plots: bool = True) -> dict:
    """:func:`modalab.app.stages.identify` of one FRF file into ``out_dir`` (modes.uff, modes.json,
    identification.json, figures); returns the campaign index entry."""

    out = Path(out_dir)
    r = stages.identify(frf_path, out / "modes.uff", opts or stages.IdentifyOptions(), json_path=out / "modes.json",
                        plots_dir=out if plots else None, report_path=out / "identification.json")
    modes = r.result[0]
    return {"input": str(frf_path), "out": str(out), "freq_hz": [float(x) for x in modes.freq_hz],
            "damping": [float(x) for x in modes.damping]}


def diagnose_one(model_path, frf_path, out_dir, opts=None) -> dict:
    """:func:`modalab.app.stages.diagnose` of one FRF file against the bulk-data model into ``out_dir``
    (diagnosis.json, figures, diagnosed.bdf); returns the campaign index entry."""

    r = stages.diagnose(model_path, frf_path=frf_path, opts=opts or stages.DiagnoseOptions(), out_dir=out_dir)
    dd = r.result.to_dict()
    return {"input": str(frf_path), "out": str(out_dir), "statement": dd["statement"],
            "findings": dd["findings"], "parameters": dd["parameters"]}


def _job(item, func, **kw):
    """One campaign input: ``item`` = (input file, output folder)."""
    return func(frf_path=item[0], out_dir=item[1], **kw)


def _folders(frf_paths, out_dir) -> list:
    """(input, ``out_dir/<file stem>``) per input; stems that repeat get their position as a prefix."""
    out_dir = Path(out_dir)
    paths = [Path(p) for p in frf_paths]
    stems = [p.stem for p in paths]
    items = []
    for k, p in enumerate(paths):
        name = p.stem if stems.count(p.stem) == 1 else f"{k:03d}_{p.stem}"
        items.append((str(p.resolve()), str((out_dir / name).resolve())))
    return items


def _index(out_dir, results) -> Path:

    return write_json(Path(out_dir) / "campaign.json", results)


def identify_many(frf_paths, out_dir, opts=None, *, plots: bool = True, dask=None, workers=None,
                  progress=None) -> list:
    """``modalab identify`` over many FRF files: ``out_dir/<file stem>/`` each, ``out_dir/campaign.json``.

    ``opts``: :class:`modalab.app.stages.IdentifyOptions` (the same for every input)."""

    func = functools.partial(_job, func=identify_one, opts=opts or stages.IdentifyOptions(), plots=plots)
    res = run_many(func, _folders(frf_paths, out_dir), dask=dask, workers=workers, progress=progress)
    _index(out_dir, res)
    return res


def diagnose_many(model_path, frf_paths, out_dir, opts=None, *, dask=None, workers=None, progress=None) -> list:
    """``modalab diagnose`` of one model against many FRF files (configurations) in parallel.

    ``opts``: :class:`modalab.app.stages.DiagnoseOptions` (the same for every input)."""

    func = functools.partial(_job, func=diagnose_one, model_path=str(Path(model_path).resolve()),
                             opts=opts or stages.DiagnoseOptions())
    res = run_many(func, _folders(frf_paths, out_dir), dask=dask, workers=workers, progress=progress)
    _index(out_dir, res)
    return res
