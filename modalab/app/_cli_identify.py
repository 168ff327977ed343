"""``modalab identify``: poly-reference PolyMAX identification of FRFs in UFF files."""
from __future__ import annotations

import argparse
from pathlib import Path
from modalab.app.stages import IdentifyOptions
from modalab.app._cli_console import _print
from modalab.app.stages import identify
from modalab.app.campaign import identify_many
from modalab.core import uff
from modalab.core.errors import PlanError


def _options(a):
    """The command's options as :class:`modalab.app.stages.IdentifyOptions`."""

    sel = a.select
    if sel != "auto" and not Path(sel).exists():
        sel = _frequencies(sel)
    if a.band is not None and not 0 <= a.band[0] < a.band[1]:
        raise PlanError(f"--band {a.band[0]:g} {a.band[1]:g}: expected 0 <= LO < HI in Hz; give e.g. --band 5 700")
    if a.max_order is not None and a.max_order < 1:
        raise PlanError(f"--max-order {a.max_order}: expected a positive model order; give e.g. --max-order 40 (or "
                        "leave it out: chosen from the data)")
    if a.exp_beta is not None and not 0 <= a.exp_beta < float("inf"):
        raise PlanError(f"--exp-beta {a.exp_beta:g}: expected the window's decay rate >= 0 in 1/s; give e.g. "
                        "--exp-beta 1.15 (or leave it out: the file's beta)")
    if a.select_tol is not None and not 0 < a.select_tol < 1:
        raise PlanError(f"--select-tol {a.select_tol:g}: expected a fraction of the frequency between 0 and 1 "
                        "(0.05 = ±5 %); give e.g. --select-tol 0.05")
    return IdentifyOptions(band_hz=tuple(a.band) if a.band else None, max_order=a.max_order, select=sel,
                           references=a.references, weighting=a.weighting, reciprocity=a.reciprocity,
                           exp_beta=a.exp_beta, force_window=a.force_window, select_tol=a.select_tol)


def _frequencies(text: str) -> tuple:
    """``--select 10,20.5,31``: frequencies in Hz (a number per comma-separated item), or a one-line error."""
    out = []
    for item in text.split(","):
        try:
            out.append(float(item))
        except ValueError:
            raise PlanError(f"--select {text!r}: {item.strip()!r} is not a frequency in Hz and {text!r} is not a "
                            "file; expected 'auto', a selection file or numbers in Hz separated by commas, e.g. "
                            "--select 10,20") from None
        if not out[-1] > 0:
            raise PlanError(f"--select {text!r}: {item.strip()!r} is not a positive frequency in Hz; give "
                            "frequencies above 0 Hz, e.g. --select 10,20")
    return tuple(out)


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


def _print_settings(report, _print):
    """What identification did with the matrix and the window, in words."""
    rc = report.settings["reciprocity"]
    if rc["applied"]:
        n_out, n_in = rc["measured_shape"]
        _print(f"reciprocity: {rc['reason']}: identified as {n_in} responses x {n_out} references "
               "(the accelerometers are the references)")
    elif rc["reason"].startswith("refused"):
        _print(f"reciprocity refused: {rc['measured_shape'][0]} responses x {rc['measured_shape'][1]} "
               "references identified as given")
    _print(_window_line(report.settings["window_correction"]))
    ext = report.settings.get("max_order_extended")
    if ext:
        hz = ", ".join(f"{x:.5g}" for x in ext["modes_hz"])
        _print(f"model order raised from {ext['from']} to {ext['to']}: {hz} Hz still resolving into close modes "
               "at the top orders" + ("" if ext["kept"] else f"; order {ext['to']} did not resolve them, "
                                      f"order {ext['from']} kept"))


def cmd_identify(a):

    opts = _options(a)
    if len(a.inputs) > 1:
        return _campaign(a, opts)
    r = identify(a.inputs[0], a.output, opts, json_path=a.json, plots_dir=a.plots)
    modes, report = r.result
    _print_settings(report, _print)
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


def _campaign(a, opts):
    """Several inputs: one folder per input under OUTPUT, in parallel (local processes or a Dask cluster)."""

    if a.json:
        raise PlanError("--json names one file; with several inputs every OUTPUT/<input>/modes.json is written")
    for p in a.inputs:          # a damaged input is refused before any is identified (no partial campaign)
        uff.read_frf(p)
    res = identify_many(a.inputs, a.output, opts, plots=bool(a.plots), dask=a.dask, workers=a.workers)
    for r in res:
        _print(f"{r['input']}: {len(r['freq_hz'])} modes -> {r['out']}")
    _print(f"campaign index: {Path(a.output) / 'campaign.json'}")
    return 0


def register(sub):
    s = sub.add_parser("identify", help="identify modes from FRFs (poly-reference PolyMAX, LSFD)")
    s.add_argument("inputs", nargs="+", help="UFF file(s) with FRFs (dataset 58, func type 4); several = a campaign")
    s.add_argument("-o", "--output", required=True,
                   help="mode shapes UFF (dataset 55); with several inputs, a folder")
    s.add_argument("--json", help="modes.json: the modes (correlate and update read it like the UFF) and a mode table "
                                   "with the indicators (schema: modalab/app/schemas/modes.schema.json)")
    s.add_argument("--plots", help="folder for the stabilisation diagram, synthesis overlays and AutoMAC (campaigns: any value "
                                         "puts them in each input's folder)")
    s.add_argument("--band", nargs=2, type=float, metavar=("LO", "HI"),
                   help="band in Hz (default: every line of the FRFs above 0 Hz)")
    s.add_argument("--max-order", type=int, help="highest model order (default: chosen from the data)")
    s.add_argument("--references", nargs="+", help="use only these reference DOFs, e.g. 1+Z 12+Z")
    s.add_argument("--select", default="auto",
                   help="'auto', a selection file (JSON/TOML list of Hz) or comma-separated frequencies in Hz")
    s.add_argument("--select-tol", type=float, metavar="FRACTION",
                   help="with --select Hz: how far (relative) from each frequency a pole may be, default 0.02 (±2 %%)")
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
    s.add_argument("--workers", type=int, help="local processes for campaigns (default: the number of CPUs)")
    s.set_defaults(func=cmd_identify)
