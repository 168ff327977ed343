"""Shared by the stages: their result type and the loaders of models, modes and parameters."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
import re
from pathlib import Path

import numpy as np

from modalab.core import uff
from modalab.core.errors import ModalabError, ModalabValueError, PlanError, UffError
from modalab.core.frf import roving_hammer_layout
from updating.fe.bulk import build_model, read_bdf
from updating.fe.parameters import ParametricFEModel
from modalab.core.modes import ModeSet
from updating.fe.parameter_file import read_parameter_file
from updating.diagnosis.priors import default_parameters

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class StageResult:
    """What a stage produced: ``result`` (the product), ``files`` (written, in order) and ``summary``."""

    result: object
    files: tuple = ()
    summary: dict = field(default_factory=dict)


def _tuple(x):
    return None if x is None else tuple(x)


# ============================================================================ shared inputs
_KIND_TEXT = {"toml": "a TOML file (a parameter, plan or project file)", "json": "a JSON file",
              "uff": "a universal file (UFF: FRFs, modes or time records)",
              "bulk": "Nastran bulk data (an FE model)"}


def sniff_kind(path) -> str | None:
    """What a text file holds, from its first lines: 'uff', 'json', 'toml', 'bulk', or None (cannot tell).

    Used to say "this is a TOML file, expected bulk data" instead of a parser's complaint about its first line."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096).decode("utf-8", errors="replace")
    except OSError:
        return None
    lines = [ln.strip() for ln in head.splitlines() if ln.strip()]
    if not lines:
        return None
    first = lines[0]
    if first == "-1":
        return "uff"
    if first[0] in "{[" and not first.startswith("[[") and not (first.startswith("[") and first.endswith("]")
                                                                  and "=" not in first and '"' not in first):
        return "json"

    code = [ln for ln in lines if not ln.startswith(("#", "$"))]
    cards = re.compile(r"^(GRID|CBAR|CBEAM|CROD|CQUAD4|CTRIA3|CHEXA|CTETRA|CELAS\d|CONM\d|PBAR|PBEAM|PBARL|PSHELL|"
                       r"PSOLID|PROD|MAT\d|SPC\d?|RBE\d|CORD\d\w|PARAM|INCLUDE|BEGIN|ENDDATA|SOL|CEND|EIGRL|"
                       r"CDAMP\d|PELAS|PDAMP|CMASS\d|PBUSH|CBUSH)\b[ ,*]?", re.I)
    if any(cards.match(ln) for ln in code[:20]) or (lines[0].startswith("$") and not code):
        return "bulk"
    toml = re.compile(r"^(\[\[?[A-Za-z_][\w.\- ]*\]\]?\s*(#.*)?|[A-Za-z_][\w\-]*\s*=\s*.+)$")
    if code and all(toml.match(ln) for ln in code[:10]):
        return "toml"
    return None


def _expect(path, wanted: str, what: str, hint: str) -> None:
    """Refuse ``path`` when it plainly holds something other than ``wanted`` (a kind of :func:`sniff_kind`)."""
    kind = sniff_kind(path)
    if kind is not None and kind != wanted:
        raise PlanError(f"'{path}' is {_KIND_TEXT[kind]}, but {what} is expected here; {hint}")


def load_model(path, ignore_unsupported: bool = False):
    """An FE model from Nastran bulk data (``.bdf``, ``.dat``, ``.nas``, ``.blk``); a structural card the
    builder does not model, or a misspelt card name (CBAT for CBAR), is an error unless ``ignore_unsupported``
    (``--ignore-unsupported``)."""

    p = Path(path)
    if not p.is_file():
        raise PlanError(f"model file {str(p)!r} does not exist; give a Nastran bulk-data file (.bdf)")
    _expect(p, "bulk", "Nastran bulk data (the FE model, e.g. model.bdf)",
            "check the order of the arguments (the model comes first)")
    return build_model(read_bdf(p, whole_model=True, ignore_unsupported=ignore_unsupported),
                       ignore_unsupported=ignore_unsupported)


def _frfs_not_modes(path: Path) -> PlanError | None:
    """The error for a UFF of FRFs given where modes belong (what to run first, and for a roving-hammer file that
    identify transposes it); None when the file holds no FRFs either."""
    try:
        frf = uff.read_frf(path)
    except ModalabError:
        return None                          # neither modes nor FRFs: the modes reader's own error stands
    n_out, n_in = frf.n_out, frf.n_in
    roving = (f"; it is a roving-hammer file (its {n_in} hit points are its references): keep identify's "
              f"reciprocity (no --no-reciprocity), which transposes it so that the hit points become the shapes' "
              "DOFs" if roving_hammer_layout(n_in, n_out) else "")
    return PlanError(f"'{path}' holds FRFs ({n_out} response{'s' * (n_out != 1)} x {n_in} "
                     f"reference{'s' * (n_in != 1)}), not modes: identify them first, e.g. modalab identify {path} "
                     f"--band LOW HIGH -o modes.uff --json modes.json, and give modes.json here{roving}")


def load_modes(path):
    """Test modes from a UFF (dataset 55) or a ``modes.json`` written by ``modalab identify``."""

    p = Path(path)
    if p.suffix.lower() == ".json":
        ms = ModeSet.from_json(p)
    else:
        if p.is_file():
            _expect(p, "uff", "test modes (UFF dataset 55, or modes.json from 'modalab identify')",
                    "check the order of the arguments")
        try:
            ms = ModeSet.from_uff(p)
        except UffError as e:
            raise _frfs_not_modes(p) or e from None
    f = np.asarray(ms.freq_hz, float)
    if f.size == 0:
        raise PlanError(f"'{path}' holds no modes; expected the modes of 'modalab identify' (at least one)")
    bad = np.flatnonzero(~(np.isfinite(f) & (f >= 0)))
    if bad.size:               # a negative or NaN frequency ran the update silently
        k = int(bad[0])
        raise PlanError(f"'{path}': mode {k + 1} has frequency {f[k]:g} Hz; expected natural frequencies of 0 Hz "
                        "or more. Correct the file (or identify the modes again)")
    return ms


def load_parameters(path, model=None) -> tuple[list, np.ndarray, np.ndarray]:
    """The one reader of an updating-parameter file for every entry point (stages, ``modalab run``'s project
    check, benchmarks): the TOML ``[[parameter]]`` file (:func:`updating.fe.parameter_file.read_parameter_file`:
    a mistyped key is one line naming the file, the key and the closest valid key) → (parameters, lower, upper
    bounds; ±inf where not given).  With ``model``, each parameter must select something of it and its bounds
    must admit the nominal value.  ``path`` None: the default E and density multipliers per property group of
    ``model``, without bounds."""
    if path is None:
        if model is None:
            raise ModalabValueError("load_parameters(None) needs the model whose default parameters to take")
        params = default_parameters(model)
        return params, np.full(len(params), -np.inf), np.full(len(params), np.inf)

    params, lo, hi = read_parameter_file(Path(path))
    lo = np.array([-np.inf if v is None else float(v) for v in lo])
    hi = np.array([np.inf if v is None else float(v) for v in hi])
    if model is None:
        return params, lo, hi
    try:
        pm = ParametricFEModel(model, params)       # each parameter selects something of this model
    except ModalabValueError as e:
        raise PlanError(f"{path}: {e}") from None
    for k, (prm, p0) in enumerate(zip(params, np.asarray(pm.p0, float))):
        if not lo[k] <= p0 <= hi[k]:           # the updating starts at the nominal: bounds must admit it
            what = "1 (factor: the model as it is)" if prm.mode == "factor" else f"{p0:g} (the model's value)"
            raise PlanError(f"{path}: parameter {prm.name!r}: bounds lower = {lo[k]:g}, upper = {hi[k]:g} exclude "
                            f"its nominal value {what}; give bounds around it, e.g. lower = {0.5 * p0:g}, "
                            f"upper = {2 * p0:g}")
    return params, lo, hi


#: the fewest frequency lines a band must hold to be identified (a band of a few lines is a mistake: kHz for Hz)
MIN_BAND_LINES = 16


def check_band_lines(H, band, frf_path, option: str = "--band", source=None) -> None:
    """Refuse, in one line, a band (Hz) that holds fewer than :data:`MIN_BAND_LINES` lines of the FRFs ``H`` read
    from ``frf_path`` (a band given in kHz, ``--band 0.005 0.7`` for 5-700 Hz; or one beyond the data's top line);
    ``option`` names it in the message (a command-line option, or a project key such as ``[identify] band_hz``),
    ``source`` the file that gave it (a project file), when not the command line."""
    if not band:
        return
    lo, hi = float(band[0]), float(band[1])
    f = H.freq_hz
    n = int(np.count_nonzero((f >= lo) & (f <= hi)))
    if n >= MIN_BAND_LINES or not lo < hi:
        return
    data = f"in {frf_path} the data spans {f[0]:.4g}..{f[-1]:.4g} Hz" + (f", lines {f[1] - f[0]:g} Hz apart"
                                                                         if f.size > 1 else "")
    top = float(f"{0.9 * f[-1]:.3g}")

    def as_given(a, b):           # --band 5 700 on the command line, band_hz = [5, 700] in a project
        return f"{option} {a:g} {b:g}" if option.startswith("-") else f"{option} = [{a:g}, {b:g}]"

    if n == 0 and lo > f[-1]:
        todo = f"give a band below {f[-1]:g} Hz (the top line: fs/2.56), e.g. {as_given(5, top)}"
    elif 1e3 * hi <= 1.01 * f[-1] and 1e3 * lo >= f[0] and hi < 1e-2 * f[-1]:
        todo = f"the band is in Hz, not kHz: give {as_given(1e3 * lo, 1e3 * hi)}"
    else:
        todo = f"give a wider band, e.g. {as_given(max(f[0], 1.0), top)}"
    raise ModalabValueError(f"{str(source) + ': ' if source else ''}{as_given(lo, hi)} Hz holds {n} frequency line(s) ({data}); a band needs at least "
                            f"{MIN_BAND_LINES}: {todo}")


def _band(H, band):
    """The lines of ``H`` in ``band`` (Hz); a band reaching beyond the data is clipped to the data with a warning
    naming the data's range, a band without any line of the data is refused (by :meth:`FRF.band`)."""
    if band:
        lo, hi = float(band[0]), float(band[1])
        f = H.freq_hz
        if lo < hi and (lo < f[0] or hi > f[-1]) and hi >= f[0] and lo <= f[-1]:
            log.warning("band %g-%g Hz reaches beyond the data (%g-%g Hz); using %g-%g Hz", lo, hi, f[0], f[-1],
                        max(lo, f[0]), min(hi, f[-1]))
        return H.band(lo, hi)
    f = H.freq_hz
    return H.band(float(f[f > 0][0]), float(f[-1]))
