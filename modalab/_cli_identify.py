"""``modalab identify``: poly-reference PolyMAX identification of FRFs in UFF files."""
from __future__ import annotations

import argparse
import json
from pathlib import Path


def _one(path, out_uff, out_json, plots, band, max_order, references, select, weighting, reciprocity=None,
         exp_beta=None, force_window=False):
    from identification import identify

    from .frf import FRF

    frf = FRF.from_uff(path)
    sel = select
    if select not in ("auto",) and not Path(select).exists():
        sel = [float(x) for x in select.split(",")]
    modes, report = identify(frf, band_hz=band, max_order=max_order, references=references, select=sel,
                             plots_dir=plots, weighting=weighting, reciprocity=reciprocity, exp_beta=exp_beta,
                             force_window=force_window)
    from ._output import write_text

    Path(out_uff).parent.mkdir(parents=True, exist_ok=True)
    modes.to_uff(out_uff)                     # atomic; never over an input (modalab._output)
    summary = {"input": str(path), "reciprocity": report.settings["reciprocity"],
               "window_correction": report.settings["window_correction"],
               "modes": modes.to_dict(), "report": report.to_dict()}
    if out_json:
        write_text(out_json, json.dumps(summary, indent=1, default=str))
    return modes, report


def _window_line(wc) -> str:
    """The window correction applied, in words."""
    b, src = wc["beta_per_s"], wc["source"]
    if src.startswith("not"):
        return f"exponential-window correction: {src}"
    if src == "none":
        return "exponential-window correction: none (no beta in the file; give --exp-beta B if a window was used)"
    if b == 0:
        return f"exponential-window correction: none (--exp-beta 0, {src})"
    where = "file" if src == "file" else f"--exp-beta {src[len('option'):].strip()}".rstrip()
    return (f"exponential-window correction: beta = {b:g} 1/s from the {where} "
            "(each damping ratio lowered by about beta/omega_n)")


def cmd_identify(a):
    from .cli import _print

    inputs = list(a.inputs)
    band = tuple(a.band) if a.band else None
    if len(inputs) == 1:
        modes, report = _one(inputs[0], a.output, a.json, a.plots, band, a.max_order, a.references, a.select,
                             a.weighting, a.reciprocity, a.exp_beta, a.force_window)
        rc = report.settings["reciprocity"]
        if rc["applied"]:
            n_out, n_in = rc["measured_shape"]
            _print(f"reciprocity: {rc['reason']}: identified as {n_in} responses x {n_out} references "
                   "(the accelerometers are the references)")
        elif rc["reason"].startswith("refused"):
            _print(f"reciprocity refused: {rc['measured_shape'][0]} responses x {rc['measured_shape'][1]} "
                   "references identified as given")
        _print(_window_line(report.settings["window_correction"]))
        nan = [float("nan")] * modes.n_modes
        mpc = modes.indicators.get("MPC", nan)
        fs, zs = modes.indicators.get("freq_std_hz", nan), modes.indicators.get("damping_std", nan)
        _print(f"{'mode':>4} {'f [Hz]':>10} {'± [Hz]':>8} {'zeta [%]':>9} {'± [%]':>7} {'MPC':>6}")
        for k, (f, z) in enumerate(zip(modes.freq_hz, modes.damping)):
            _print(f"{k + 1:>4} {f:>10.3f} {float(fs[k]):>8.3f} {100 * z:>9.3f} {100 * float(zs[k]):>7.3f} "
                   f"{float(mpc[k]):>6.3f}")
        src = modes.metadata.get("pole_std_source")
        if src:
            _print(f"(± one standard deviation: FRF noise from {src}, first order, combined with the spread "
                   "of the pole over the stable orders)")
        _print(f"wrote {modes.n_modes} modes to {a.output}" + (f" and {a.json}" if a.json else ""))
        return 0
    # a campaign: one output folder per input, in parallel
    out_dir = Path(a.output)
    jobs = []
    for p in inputs:
        d = out_dir / Path(p).stem
        jobs.append((p, d / "modes.uff", d / "modes.json", d / "plots" if a.plots else None, band, a.max_order,
                     a.references, a.select, a.weighting, a.reciprocity, a.exp_beta, a.force_window))
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
    s.add_argument("--reciprocity", action=argparse.BooleanOptionalAction, default=None,
                   help="transpose by Maxwell-Betti reciprocity (accelerometers become the references); "
                        "default: automatic for a roving-hammer export (references far more than responses); "
                        "--no-reciprocity identifies the matrix as given")
    s.add_argument("--exp-beta", type=float, metavar="B",
                   help="decay rate (1/s) of the exponential window the FRFs were measured with, when the file "
                        "does not say; removed from the damping (zeta - beta/omega_n)")
    s.add_argument("--force-window", action="store_true",
                   help="use --exp-beta even when the file carries a different beta")
    s.add_argument("--dask", help="address of an existing Dask scheduler (tcp://host:port) for campaigns")
    s.set_defaults(func=cmd_identify)
