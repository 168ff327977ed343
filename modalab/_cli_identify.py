"""``modalab identify``: poly-reference PolyMAX identification of FRFs in UFF files."""
from __future__ import annotations

import json
from pathlib import Path


def _one(path, out_uff, out_json, plots, band, max_order, references, select, weighting):
    from identification import identify

    from .frf import FRF

    frf = FRF.from_uff(path)
    sel = select
    if select not in ("auto",) and not Path(select).exists():
        sel = [float(x) for x in select.split(",")]
    modes, report = identify(frf, band_hz=band, max_order=max_order, references=references, select=sel,
                             plots_dir=plots, weighting=weighting)
    from .uff import info as uff_info, read_geometry

    if {"2411", "15"} & set(uff_info(path).get("datasets", {})):
        # the test geometry travels with the modes, so correlate/update can map test nodes onto model grids
        modes.coordinates = read_geometry(path)
    Path(out_uff).parent.mkdir(parents=True, exist_ok=True)
    if Path(out_uff).exists():
        Path(out_uff).unlink()
    modes.to_uff(out_uff)
    summary = {"input": str(path), "modes": modes.to_dict(), "report": report.to_dict()}
    if out_json:
        Path(out_json).write_text(json.dumps(summary, indent=1, default=str))
    return modes, report


def cmd_identify(a):
    from .cli import _print

    inputs = list(a.inputs)
    band = tuple(a.band) if a.band else None
    if len(inputs) == 1:
        modes, report = _one(inputs[0], a.output, a.json, a.plots, band, a.max_order, a.references, a.select,
                             a.weighting)
        nan = [float("nan")] * modes.n_modes
        mpc = modes.indicators.get("MPC", nan)
        fs, zs = modes.indicators.get("freq_std_hz", nan), modes.indicators.get("damping_std", nan)
        _print(f"{'mode':>4} {'f [Hz]':>10} {'± [Hz]':>8} {'zeta [%]':>9} {'± [%]':>7} {'MPC':>6}")
        for k, (f, z) in enumerate(zip(modes.freq_hz, modes.damping)):
            _print(f"{k + 1:>4} {f:>10.3f} {float(fs[k]):>8.3f} {100 * z:>9.3f} {100 * float(zs[k]):>7.3f} "
                   f"{float(mpc[k]):>6.3f}")
        src = modes.metadata.get("pole_std_source")
        if src:
            _print(f"(± one standard deviation, first order, noise from {src})")
        _print(f"wrote {modes.n_modes} modes to {a.output}" + (f" and {a.json}" if a.json else ""))
        return 0
    # a campaign: one output folder per input, in parallel
    out_dir = Path(a.output)
    jobs = []
    for p in inputs:
        d = out_dir / Path(p).stem
        jobs.append((p, d / "modes.uff", d / "modes.json", d / "plots" if a.plots else None, band, a.max_order,
                     a.references, a.select, a.weighting))
    try:
        from .campaign import run_many
    except ImportError:
        run_many = None
    if run_many is not None:
        results = run_many(_one, jobs, dask=a.dask)
    else:
        results = [_one(*j) for j in jobs]
    for (p, *_), (modes, _) in zip(jobs, results):
        _print(f"{p}: {modes.n_modes} modes")
    return 0


def register(sub):
    s = sub.add_parser("identify", help="identify modes from FRFs (poly-reference PolyMAX, LSFD)")
    s.add_argument("inputs", nargs="+", help="UFF file(s) with FRFs (dataset 58, func type 4); several = a campaign")
    s.add_argument("-o", "--output", required=True,
                   help="mode shapes UFF (dataset 55); with several inputs, a folder")
    s.add_argument("--json", help="JSON summary (frequencies, damping, indicators, stabilisation)")
    s.add_argument("--plots", help="folder for the stabilisation diagram, synthesis overlays and AutoMAC")
    s.add_argument("--band", nargs=2, type=float, metavar=("LO", "HI"), help="band in Hz")
    s.add_argument("--max-order", type=int, help="highest model order (default: chosen from the data)")
    s.add_argument("--references", nargs="+", help="use only these reference DOFs, e.g. 1+Z 12+Z")
    s.add_argument("--select", default="auto",
                   help="'auto', a selection file (JSON/TOML list of Hz) or comma-separated frequencies in Hz")
    s.add_argument("--weighting", choices=["coherence", "variance"], help="frequency weighting")
    s.add_argument("--dask", help="address of an existing Dask scheduler (tcp://host:port) for campaigns")
    s.set_defaults(func=cmd_identify)
