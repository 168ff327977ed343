"""The ``modalab`` command line.  ``main(args=None)`` parses, builds the options and calls :mod:`modalab.app.stages`.

The user's description (``modalab --help``) is :data:`DESCRIPTION`; each command is registered in
:func:`build_parser` or in its ``modalab/_cli_<command>.py`` module; what is shown at the console (progress,
the acquisition's per-hit report, the prompt) is in :mod:`modalab.app._cli_console`.

Outputs (:mod:`modalab.core._output`): an output is never written over an input (not even with ``--force``); an
existing output file, or an output folder holding an earlier run's products (``update -o``, ``diagnose --report``,
``report``), is replaced only with ``--force`` (``sim``: ``--overwrite``); files are written to a
temporary file and renamed, with the user's umask, and what a failed command created is removed.  Bad input
gives one line ``modalab COMMAND: error: ...`` naming the file (and line) and exit code 2.
"""
from __future__ import annotations

import argparse
import json
import logging
import os
import shutil
import sys
from pathlib import Path

from threadpoolctl import threadpool_limits

from modalab.core.errors import ModalabError, PlanError
from modalab.app.stages import SimOptions, sim
from modalab.app.stages import FRFOptions, frf
from modalab.core.uff import assume_quantity
from modalab.app.stages import AcquireOptions, acquire
from modalab.app._cli_console import _ConsoleObserver, _CountProgress, _print, _TerminalPrompter  # noqa: F401
from modalab.app import _cli_correlate, _cli_diagnose, _cli_identify, _cli_info, _cli_report, _cli_run, _cli_update
from modalab.app._cli_info import info_table  # noqa: F401  (modalab info's lines; the tests read them here)
from modalab.app._cli_run import run_with_progress
from modalab.app.demo_project import run_demo
from modalab.core._output import check_outputs
from modalab.core.errors import OutputError
from modalab.core._output import protect
from modalab.app._cli_parse import parse_args as _parse

DESCRIPTION = """\
Modal testing from the bench to an updated FE model: impact tests on NI hardware or the simulated lab,
FRFs with coherence, PolyMAX identification, correlation with a Nastran model, model updating, and a
diagnosis of the physics the model leaves out.

Try it without hardware:   modalab demo -o modalab-demo     (then open modalab-demo/report/report.html)
Step by step:              modalab sim -> frf -> identify -> correlate -> update -> diagnose
A whole project:           modalab run project.toml -o out  (reruns only what changed)

Every command has --help, e.g. modalab identify --help."""
#: what ``modalab demo --quick`` changes (the same words in the README; the demo's plan_quick/project_quick files)
QUICK_HELP = ("the demo on the same points with 2 accepted averages per point instead of 3 (at most 3 hits instead "
              "of 4), identification up to order 24 instead of 40, at most 10 updating iterations instead of 20; "
              "not shorter: the diagnosis takes most of the time, and it leaves the diagnosis as it is")
UNITS_EPILOG = ("Units: SI throughout - frequencies in Hz, times in s, forces in N, accelerations in m/s^2, "
                "stiffness in N/m (N*m/rad), masses in kg; DOFs as node+direction, e.g. 12+Z.")


# ----------------------------------------------------------------------------- commands
def first_hit_path(output) -> Path:
    """The figure ``modalab sim`` writes next to its UFF: ``hits.uff`` -> ``hits_first_hit.png``."""
    p = Path(output)
    return p.with_name(p.stem + "_first_hit.png")


def cmd_sim(a):

    opts = SimOptions(structure=a.structure, points=a.points, references=a.references, hits=a.hits, seed=a.seed,
                      force_n=a.force, double_hit_probability=a.double_hits, sample_rate_hz=a.sample_rate,
                      n_samples=a.samples)
    with _CountProgress("points") as bar:
        r = sim(a.output, opts, plot_path=None if a.no_plot else first_hit_path(a.output),
                export_model=a.export_model, progress=bar)
    recs = r.result
    _print(f"wrote {len(recs)} hits x {recs[0].n_channels} channels to {r.files[0]}")
    if not a.no_plot:
        _print(f"first hit (force and responses against time): {first_hit_path(a.output)}")
    if a.export_model:
        _print("FE model and updating parameters of the structure: "
               + ", ".join(str(p) for p in r.files if Path(p).suffix in (".bdf", ".toml")))
    return 0


def cmd_frf(a):

    plot = None if a.no_plot else (a.plot or str(Path(a.output).with_suffix(".png")))
    _frf_option_values(a)
    opts = FRFOptions(estimator=a.estimator, force_fraction=a.force_window, exp_end_level=a.exp_end,
                      exp_beta=a.exp_beta, reciprocity=not a.no_reciprocity, bandwidth_hz=a.bandwidth)
    r = frf(a.input, a.output, opts, plot_path=plot)
    H = r.result
    _print(f"wrote {H.n_out} x {H.n_in} {H.metadata.get('estimator', a.estimator)} FRFs "
           f"({H.n_freq} lines, {H.freq_hz[0]:g}-{H.freq_hz[-1]:g} Hz) with coherence to {r.files[0]}")
    if H.metadata.get("backend") == "sim":
        _print("note: the hits are simulated (backend sim), not measured")
    if plot:
        _print(f"plot: {plot}")
    return 0


def _frf_option_values(a) -> None:
    """One-line refusals of ``frf`` option values, naming the option (the stage's names are a project's keys)."""
    if a.exp_end is not None and not 0 <= a.exp_end < 1:
        raise PlanError(f"--exp-end {a.exp_end:g}: expected the level the exponential window reaches at the record's "
                        "end, a fraction from 0 to below 1 (0.01 = 1 %; 0 = no window); give e.g. --exp-end 0.01")
    if a.exp_beta is not None and not 0 <= a.exp_beta < float("inf"):
        raise PlanError(f"--exp-beta {a.exp_beta:g}: expected the window's decay rate >= 0 in 1/s (0 = no window); "
                        "give e.g. --exp-beta 1.15 (or --exp-end 0.01)")
    if a.force_window is not None and not 0 <= a.force_window <= 1:
        raise PlanError(f"--force-window {a.force_window:g}: expected a fraction of the record after the trigger from "
                        "0 to 1 (0 = off; 0.05 = the first 5 %); give e.g. --force-window 0.05")


def cmd_acquire(a):

    out = Path(a.output)
    live = bool(getattr(a, "live_plot", False)) or os.environ.get("MODALAB_LIVE_PLOT", "") not in ("", "0")
    obs = _ConsoleObserver(out, live_plot=live, quiet=a.quiet)
    prompter = None if a.auto else _TerminalPrompter()
    resume_cmd = (f"modalab acquire {a.plan} --backend {a.backend} {'--auto ' if a.auto else ''}--resume -o {out}")
    line = "backend: " + ("sim - the simulated lab (hardware_sim): the data are SIMULATED, not measured; "
                          "--backend nidaqmx for NI hardware" if a.backend == "sim" else f"{a.backend} (NI hardware)")
    try:       # the backend line once every check has passed: a refused plan prints the error alone
        r = acquire(a.plan, out, AcquireOptions(backend=a.backend, auto=a.auto, resume=a.resume, seed=a.seed),
                    prompter=prompter, observer=obs, on_ready=lambda: _print(line))
    except KeyboardInterrupt:
        obs.close()
        _print(f"interrupted; every accepted hit is stored. Continue with: {resume_cmd}")
        return 130
    finally:
        obs.close()
    summary, exported = r.result.summary, r.result.uff
    _print(summary.table())
    for name, s in summary.range_suggestions.items():
        _print(f"range suggestion: {name}: peak {s['peak']:g}, range {s['range']:g} -> {s['suggested']:g}")
    for d in summary.resume:
        _print(f"on resume: {d}")
    if summary.stopped:
        _print(summary.stopped)
    if exported:
        _print(f"session complete: {exported}")
    else:
        _print(f"session incomplete; continue with: {resume_cmd}")
    return 0 if summary.complete else 3


def cmd_demo(a):

    out = Path(a.output)
    again = f"modalab demo -o {out}" + (" --quick" if a.quick else "")
    return run_with_progress(lambda progress: run_demo(out, quick=a.quick, progress=progress), again)


# ----------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="modalab", description=DESCRIPTION,
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog=UNITS_EPILOG)
    p.add_argument("-v", "--verbose", action="count", default=0, help="more log output (-vv for debug)")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    _add_demo(sub)
    _add_sim(sub)
    _add_frf(sub)
    _cli_info.register(sub)
    _add_acquire(sub)
    for m in (_cli_identify, _cli_correlate, _cli_update, _cli_diagnose, _cli_run, _cli_report):   # their modules
        m.register(sub)
    _add_shared_options(sub)
    return p


def _add_demo(sub):
    s = sub.add_parser("demo", help="simulate the demo structure's hammer test end to end (no hardware)")
    s.add_argument("-o", "--output", default="modalab-demo", help="output folder (default: modalab-demo)")
    s.add_argument("--quick", action="store_true", help=QUICK_HELP)
    s.set_defaults(func=cmd_demo)


def _add_sim(sub):
    s = sub.add_parser("sim", help="simulate a roving-hammer test into a UFF of raw hits")
    s.add_argument("-o", "--output", required=True, help="UFF file to write (raw hits: dataset 58 time records, written in binary form, 58b)")
    s.add_argument("--structure", default="demo", help="'demo' or a Nastran bulk-data file (default: demo)")
    s.add_argument("--points", nargs="+", help="DOFs to hit, e.g. 1+Z 3+Z (default: the demo's points)")
    s.add_argument("--references", nargs="+", help="accelerometer DOFs (default: the demo's three)")
    s.add_argument("--hits", type=int, default=3, help="hits per point (default 3)")
    s.add_argument("--force", type=float, help="nominal peak force in N (default: the hammer's)")
    s.add_argument("--double-hits", type=float, default=0.0, help="probability of a double hit, 0..1")
    s.add_argument("--sample-rate", type=float, help="sampling rate in Hz (default 2048; at least 100)")
    s.add_argument("--samples", type=int, help="samples per record (default 8192; at least 256)")
    s.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    s.add_argument("--no-plot", action="store_true", help="do not write the figure of the first hit (by default "
                                                          "OUTPUT_first_hit.png next to OUTPUT, e.g. hits_first_hit.png)")
    s.add_argument("--export-model", metavar="FOLDER",
                   help="also write the simulated structure's FE model (FOLDER/model.bdf, Nastran bulk data) and "
                        "updating parameters (FOLDER/params.toml) for correlate, update and diagnose")
    s.set_defaults(func=cmd_sim)


def _add_frf(sub):
    s = sub.add_parser("frf", help="raw hits -> H1 FRFs and coherence")
    s.add_argument("input", help="UFF with raw hits (dataset 58 time records)")
    s.add_argument("-o", "--output", required=True, help="UFF to write (FRFs func type 4, coherence func type 6)")
    s.add_argument("--estimator", default="H1", choices=["H1", "H2", "Hv"], help="FRF estimator (default H1)")
    s.add_argument("--force-window", type=float, default=0.05,
                   help="force window length as a fraction of the record after the trigger (default 0.05; 0 = off)")
    s.add_argument("--exp-end", type=float, help="exponential window: level at the record end, e.g. 0.01 (1 %%)")
    s.add_argument("--exp-beta", type=float, help="exponential window decay rate beta in 1/s (instead of --exp-end)")
    s.add_argument("--no-reciprocity", action="store_true",
                   help="keep hit points as references (default: accelerometers become references)")
    s.add_argument("--bandwidth", type=float, help="keep lines up to this frequency in Hz (default fs/2.56)")
    s.add_argument("--plot", help="figure path (default: OUTPUT with .png)")
    s.add_argument("--no-plot", action="store_true", help="no figure")
    s.set_defaults(func=cmd_frf)


def _add_acquire(sub):
    s = sub.add_parser("acquire", help="run a test plan (impact test) on NI hardware or the simulated lab")
    s.add_argument("plan", help="test plan (TOML; see the README)")
    s.add_argument("--backend", default="sim", choices=["sim", "nidaqmx"],
                   help="DAQ backend (default sim: the simulated lab; the backend is printed and recorded in "
                        "session.json and the UFF's ID lines)")
    s.add_argument("--auto", action="store_true", help="accept automatically: best N of M hits by coherence")
    s.add_argument("--resume", action="store_true", help="continue an interrupted session in OUTPUT")
    s.add_argument("-o", "--output", required=True, help="session folder")
    s.add_argument("--seed", type=int, help="simulated lab seed (sim backend)")
    s.add_argument("--quiet", action="store_true", help="no per-hit output")
    s.add_argument("--live-plot", action="store_true",
                   help="open a live plot window (only with a display; preview PNGs are always written)")
    s.set_defaults(func=cmd_acquire)


def _add_shared_options(sub):
    """Options several commands share: --force/--overwrite, --quantity, and the units note under every --help."""
    for name in ("sim", "frf", "identify", "correlate", "update", "diagnose", "report"):
        sp = sub.choices.get(name)
        if sp is None:
            continue
        taken = any("--force" in act.option_strings for act in sp._actions)   # sim: --force is the hammer's
        sp.add_argument(*(() if taken else ("--force",)), "--overwrite", dest="overwrite", action="store_true",
                        help="replace existing output files (an input is never replaced)")
    for name in ("info", "identify", "update", "diagnose"):
        sp = sub.choices.get(name)
        if sp is not None and not any("--quantity" in act.option_strings for act in sp._actions):
            sp.add_argument("--quantity", choices=("accelerance", "mobility", "receptance"),
                            help="what the FRFs are when the file does not say (ordinate data type 0/1 without "
                                 "a units label); an error when the file says otherwise")
    for sp in sub.choices.values():
        sp.epilog = (sp.epilog + "\n" if sp.epilog else "") + UNITS_EPILOG


def blas_threads(n: int | None = None):
    """Context limiting the BLAS/OpenMP thread pools of this process to ``n`` threads (default: the
    ``MODALAB_BLAS_THREADS`` environment variable, else 1), and setting the usual environment variables so
    that worker processes start the same way.

    modalab's work is many small dense products and solves (line-by-line FRFs, reduced bases, per-candidate
    fits), for which threaded BLAS costs more than it gains: the demo's diagnosis takes 22 s on one thread and
    42 s on two on a 2-core machine.  ``threadpoolctl`` (a dependency) does the limiting.
    """

    if n is None:
        try:
            n = max(int(os.environ.get("MODALAB_BLAS_THREADS", "1")), 1)
        except ValueError:
            raise ModalabError(f"MODALAB_BLAS_THREADS={os.environ['MODALAB_BLAS_THREADS']!r}; expected a "
                               "positive integer (the number of BLAS threads)") from None
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, str(n))
    return threadpool_limits(limits=n)


#: per command: argparse attributes naming input files, output files and output folders
_IO = {
    "sim": (("structure",), ("output",), ()),
    "frf": (("input",), ("output", "plot"), ()),
    "info": (("file",), (), ()),
    "identify": (("inputs", "select"), ("output", "json"), ("plots",)),
    "correlate": (("model", "modes", "map"), ("json",), ("plots",)),
    "update": (("model", "modes", "frf", "params", "map"), (), ("output",)),
    "diagnose": (("model", "measured", "modes", "params", "map"), ("json",), ("report",)),
    "run": (("project",), (), ("output",)),
    "demo": ((), (), ("output",)),
    "acquire": (("plan",), (), ("output",)),
    "report": ((), (), ("output",)),
}
#: suffixes of the files modalab reads or writes: a folder output named like one is a mistake
#: (``update -o updated.bdf`` would make a folder ``updated.bdf``)
_FILE_SUFFIXES = (".bdf", ".dat", ".nas", ".blk", ".uff", ".unv", ".json", ".toml", ".png", ".html", ".htm", ".csv",
                  ".npz", ".txt", ".pdf", ".svg", ".lvm", ".h5", ".hdf5", ".mat")
#: the option naming each output folder, by argparse attribute
_FOLDER_FLAGS = {"output": "-o", "plots": "--plots", "report": "--report", "export_model": "--export-model"}
#: files a command writes into its output folder (checked against its inputs)
_WRITES_INTO = {"update": ("output", ("updated.bdf", "update.json", "updated_matrices.npz", "mac_before.png",
                                      "mac_after.png", "frequencies_after.png", "convergence.png")),
                "diagnose": ("report", ("diagnosis.json", "diagnosed.bdf", "frf_overlay_models.png"))}
#: output folders and the files a command puts there (its own products): a folder that already holds one of them
#: is the output of an earlier run, replaced only with --force (never silently)
_EARLIER = {"update": [("output", ("update.json", "updated.bdf", "updated_matrices.npz"))],
            "diagnose": [("report", ("diagnosis.json", "diagnosed.bdf", "campaign.json"))],
            "report": [("output", ("report.html", "summary.json"))],
            "identify": [("output", ("campaign.json",)), ("plots", ("stabilisation.png", "synthesis.png", "automac.png"))],
            "correlate": [("plots", ("mac_before.png", "frequencies_before.png", "comac.png"))]}
#: commands whose output folder is a resumable session/run: kept on failure unless empty
_KEEP_FOLDER = {"run", "demo", "acquire"}


def _values(a, names):
    out = []
    for n in names:
        v = getattr(a, n, None)
        if v is None or v is False:
            continue
        out += [str(x) for x in v] if isinstance(v, (list, tuple)) else [str(v)]
    return out


def _io_plan(a):
    """(inputs, output files, output folders) of the parsed command ``a``."""
    ins, files, folders = _IO.get(a.command, ((), (), ()))
    inputs = [p for p in _values(a, ins) if os.path.isfile(p)]
    files, folders = _values(a, files), _values(a, folders)
    if a.command == "frf" and not a.no_plot and not a.plot:
        files.append(str(Path(a.output).with_suffix(".png")))
    if a.command == "sim" and not a.no_plot:
        files.append(str(first_hit_path(a.output)))
    if a.command == "identify" and len(a.inputs) > 1:      # a campaign: -o names a folder
        files.remove(a.output)
        folders.append(a.output)
    if a.command == "sim" and getattr(a, "export_model", None):
        folders.append(a.export_model)
    return inputs, files, folders


def _check_folder_names(a) -> None:
    """Refuse a folder output that does not exist yet and is named like a file (``-o updated.bdf``)."""
    ins, _, folders = _IO.get(a.command, ((), (), ()))
    attrs = list(folders) + (["export_model"] if a.command == "sim" else [])
    if a.command == "identify" and len(getattr(a, "inputs", ())) > 1:
        attrs.append("output")
    for attr in attrs:
        v = getattr(a, attr, None)
        if not v or os.path.lexists(v) or str(v).endswith(("/", os.sep)):     # an existing path: check_outputs
            continue
        suf = Path(v).suffix.lower()
        if suf in _FILE_SUFFIXES:
            flag = _FOLDER_FLAGS.get(attr, "--" + attr.replace("_", "-"))
            raise OutputError(f"{flag} '{v}' names the folder this command writes into, but looks like a {suf} "
                              f"file; give a folder name, e.g. {flag} {Path(v).with_suffix('')}/")


def _check_earlier_output(a) -> None:
    """Refuse an output folder that holds the products of an earlier run of this command, unless ``--force``."""
    if a.command not in _EARLIER or getattr(a, "overwrite", False):
        return
    for attr, names in _EARLIER[a.command]:
        folder = getattr(a, attr, None)
        if a.command == "report" and not folder:
            folder = Path(a.folder) / "report"
        if a.command == "identify" and (len(a.inputs) > 1) != (attr == "output"):
            continue        # one input: -o is a file (check_outputs); a campaign puts figures in each input's folder
        if not folder or not os.path.isdir(folder):
            continue
        found = [n for n in names if os.path.lexists(os.path.join(folder, n))]
        if found:
            flag = _FOLDER_FLAGS.get(attr, "--" + attr) if getattr(a, attr, None) else "the report folder"
            raise OutputError(f"{flag} '{folder}' holds the output of an earlier run ({', '.join(found)}); pass "
                              "--force to replace it, or choose another folder")


def _prepare_outputs(a):
    """Refuse unsafe outputs before any work; returns the outputs this run creates (removed on failure)."""

    _check_folder_names(a)
    inputs, files, folders = _io_plan(a)
    into = {}
    if a.command in _WRITES_INTO:
        attr, names = _WRITES_INTO[a.command]
        into = {getattr(a, attr, None): names}
    # the option that replaces outputs, as this command spells it (sim's --force is the hammer's peak force)
    option = None if not hasattr(a, "overwrite") else "--overwrite" if a.command == "sim" else "--force"
    check_outputs(inputs, files, folders, force=bool(getattr(a, "overwrite", False)),
                  writes_into=into, force_option=option)
    _check_earlier_output(a)
    created = [Path(p) for p in files + folders if not os.path.lexists(p)]
    return inputs, created


def _remove_created(a, created):
    """After a failure: remove the outputs this run created (a session/run folder, or a campaign's folder
    holding the results of the inputs that succeeded, only when empty)."""

    keep = a.command in _KEEP_FOLDER or (a.command == "identify" and len(a.inputs) > 1)
    for p in created:
        try:
            if p.is_dir():
                if keep:
                    p.rmdir()             # fails (kept) when not empty
                else:
                    shutil.rmtree(p)
            elif os.path.lexists(p):
                p.unlink()
        except OSError:
            pass


def _decode_failure(a, exc) -> str:
    """A one-line message for a text/JSON decoding error, naming the input file that fails to decode."""
    ins = _IO.get(a.command, ((),))[0] + (("plan",) if a.command == "acquire" else ())
    for p in _values(a, ins):
        if not os.path.isfile(p):
            continue
        try:
            text = Path(p).read_bytes().decode("utf-8")
        except UnicodeDecodeError as e:
            return (f"'{p}' is not a text file (byte {e.start} is not UTF-8); expected "
                    f"{'a ' + Path(p).suffix + ' file' if Path(p).suffix else 'a text file'}. Check the argument")
        except OSError:
            continue
        if isinstance(exc, json.JSONDecodeError) and Path(p).suffix.lower() == ".json":
            try:
                json.loads(text)
            except json.JSONDecodeError as e:
                return (f"'{p}' is not valid JSON (line {e.lineno}, column {e.colno}: {e.msg}); the file is "
                        "truncated or not JSON. Write it again (e.g. with 'modalab identify --json')")
    return f"an input could not be decoded ({exc}); check the file arguments"


#: exit status when the reader of stdout goes away (a process killed by SIGPIPE: 128 + 13)
EXIT_BROKEN_PIPE = 141


class _LogFormatter(logging.Formatter):
    """Log records as the user reads them: ``warning: ...`` (the module path and level name only with -v)."""

    def __init__(self, verbose: int = 0):
        super().__init__()
        self.verbose = verbose

    def format(self, record):
        msg = record.getMessage()
        if record.exc_info and self.verbose:
            msg += "\n" + self.formatException(record.exc_info)
        if self.verbose:
            return f"{record.levelname.lower()} [{record.name}]: {msg}"
        return f"{record.levelname.lower()}: {msg}"


def main(args=None) -> int:
    parser = build_parser()
    a = _parse(parser, args)
    level = logging.WARNING - 10 * min(a.verbose, 2)
    if not logging.getLogger().handlers:
        h = logging.StreamHandler()
        h.setFormatter(_LogFormatter(verbose=a.verbose))
        logging.basicConfig(level=level, handlers=[h])
    if not getattr(a, "func", None):
        parser.print_help()
        return 2
    os.environ.setdefault("MPLBACKEND", "Agg")

    created = []
    try:
        inputs, created = _prepare_outputs(a)

        with blas_threads(), protect(inputs), assume_quantity(getattr(a, "quantity", None)):
            return int(a.func(a) or 0)
    except BrokenPipeError:
        # the reader of our output went away (``modalab info x.uff | head -3``): stop quietly, as a Unix tool
        # killed by SIGPIPE does (exit status 128 + 13), with nothing half-written left behind
        _remove_created(a, created)
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        return EXIT_BROKEN_PIPE
    except KeyboardInterrupt:
        _remove_created(a, created)
        print(f"modalab {a.command}: interrupted", file=sys.stderr)
        return 130
    except (ModalabError, OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        _remove_created(a, created)
        if isinstance(e, ModalabError):
            msg = str(e)
        elif isinstance(e, (UnicodeDecodeError, json.JSONDecodeError)):
            msg = _decode_failure(a, e)
        else:
            name = e.filename if e.filename is not None else "a file"
            msg = f"cannot use '{name}': {e.strerror or e}" + (
                "; expected a file, not a folder" if isinstance(e, IsADirectoryError) else "")
        print(f"modalab {a.command}: error: {msg}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
