"""The report stage: ONE self-contained HTML file plus a JSON summary of a run folder.

:func:`build_report` reads what the stages wrote into the run folder (``frf/``, ``identify/``,
``correlate/``, ``update/``, ``diagnose/``) and writes ``report/report.html`` — every figure embedded as
a base64 PNG ``data:`` URI, the style inline, no script, no external resource of any kind — and
``report/summary.json`` (the numbers of every section; schema ``modalab/app/schemas/summary.schema.json``).
Sections: whether the data are simulated, the model to use, the diagnosis (selected terms, the first
screening's ranking, candidates turned down and why), test overview (geometry with the measured DOFs,
coherence map, reciprocity), stabilisation diagram, mode table with indicators (units and a legend), MAC
before and after updating, frequency 45° plots, parameter convergence, FRF overlays.  A section whose stage
did not run says so.  :func:`report` is the stage function (``modalab run``); the figures the other stages
draw for it are in :mod:`modalab.app.figures`.
"""
from __future__ import annotations

import base64
import datetime as _dt
import html
import json
import logging
from dataclasses import dataclass
from pathlib import Path

from modalab.core.errors import ModalabError, ModalabValueError
from modalab.app.figures import plot_coherence_map
from modalab.app.outputs import write_json, write_text
from modalab.app.stages._common import StageResult, load_model
from modalab.core import uff
from modalab.core.plots import plot_geometry

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ReportOptions:
    """``modalab report``: the report's title (None: the run folder's name) and the FE model (bulk data) whose wire
    frame is drawn under the test geometry (None: the measured points alone; ``modalab run``: the project's)."""

    title: str | None = None
    model: str | None = None
    #: where the updated and diagnosed bulk data are, for outputs of commands run one by one (:func:`model_files`)
    model_files: dict | None = None


def report(run_dir, report_dir=None, opts: ReportOptions = ReportOptions()) -> StageResult:
    """The self-contained HTML report of a run folder and its ``summary.json`` (:func:`build_report`)."""

    html_path, summary = build_report(run_dir, report_dir, title=opts.title, model=opts.model,
                                      model_files=opts.model_files)
    return StageResult(html_path, (html_path, summary), {"report": str(html_path)})


# ----------------------------------------------------------------------------- HTML
def embed_png(path) -> str:
    """An ``<img>`` whose source is the PNG itself (base64 data URI)."""
    data = base64.b64encode(Path(path).read_bytes()).decode("ascii")
    alt = html.escape(Path(path).stem.replace("_", " "))
    return f'<img src="data:image/png;base64,{data}" alt="{alt}">'


_CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;
color:#222;line-height:1.45}
h1{font-size:1.6em;border-bottom:2px solid #345;padding-bottom:.2em}
h2{font-size:1.25em;margin-top:2em;border-bottom:1px solid #bbb}
table{border-collapse:collapse;font-size:.85em;margin:.6em 0}
td,th{border:1px solid #ccc;padding:.2em .5em;text-align:right}
th{background:#eef}
td.l,th.l{text-align:left}
img{max-width:100%;height:auto;display:block;margin:.5em 0}
.statement{background:#f5f8ff;border-left:4px solid #36c;padding:.6em 1em}
.muted{color:#777}
figure{margin:0 0 1em 0}
figcaption{font-size:.85em;color:#555}
"""


def _fig(path, caption: str) -> str:
    p = Path(path)
    if not p.is_file():
        return f'<p class="muted">({html.escape(caption)}: not available)</p>'
    return f"<figure>{embed_png(p)}<figcaption>{html.escape(caption)}</figcaption></figure>"


def _table(rows: list, cols: list, fmt=None) -> str:
    fmt = fmt or {}
    h = "".join(f"<th>{html.escape(str(c))}</th>" for c in cols)
    body = []
    for r in rows:
        cells = []
        for c in cols:
            v = r.get(c, "")
            if v is None:                   # a value the stage could not give (JSON null): say so, never 0
                v = "—"
            elif isinstance(v, float):
                v = fmt.get(c, "{:.4g}").format(v)
            cells.append(f'<td class="{"l" if isinstance(v, str) and not v[:1].isdigit() else ""}">'
                         f"{html.escape(str(v))}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table><tr>{h}</tr>{''.join(body)}</table>"


_FIT_LABELS = {"frf_error_train": "FRF error on the training DOFs", "frf_error_held_out": "on held-out DOFs",
               "freq_error_max_pct": "largest frequency error [%]", "mac_min": "lowest MAC"}


def _num(v, fmt: str) -> str:
    """A number formatted, or "—" for a value the stage could not give (None)."""
    return "—" if v is None else format(float(v), fmt)


#: the mode table's columns: heading (with unit) and what it means; damping columns are printed in % like
#: damping_pct (modes.json keeps damping_std etc. as fractions, as ModeSet.indicators does)
_MODE_COLUMNS = {
    "mode": ("mode", ""),
    "freq_hz": ("f [Hz]", "natural frequency"),
    "damping_pct": ("ζ [%]", "damping ratio, exponential-window corrected"),
    "freq_std_hz": ("σ f [Hz]", "standard deviation of f: FRF noise and spread over the stable orders combined"),
    "damping_std": ("σ ζ [%]", "standard deviation of ζ (same combination)"),
    "MPC": ("MPC [0-1]", "modal phase collinearity: 1 for a real (normal) mode"),
    "MPD": ("MPD [°]", "mean phase deviation of the shape's components from their best straight line: 0° for a "
                       "normal mode"),
    "MCF": ("MCF [0-1]", "modal complexity factor, 1 − MPC"),
    "MOV": ("MOV [0-1]", "mode overcomplexity value: share of responses whose frequency falls with added mass"),
    "contribution": ("contribution [0-1]", "share of the measured FRFs' energy (Σ|H|²) this mode's synthesis "
                                            "carries"),
    "chi2_ratio": ("χ² ratio [-]", "residual of the local fit over its expected value from the FRF noise: about 1 "
                                   "when the noise model explains the scatter, above 1 when the model misses "
                                   "something (close modes, leakage, nonlinearity)"),
    "cluster_size": ("cluster [poles]", "stable poles gathered into this mode over the model orders"),
    "order": ("order", "model order the pole was taken from"),
    "freq_std_noise_hz": ("σ f noise [Hz]", "part of σ f from the FRF noise"),
    "damping_std_noise": ("σ ζ noise [%]", "part of σ ζ from the FRF noise"),
    "freq_std_orders_hz": ("σ f orders [Hz]", "part of σ f from the spread over the stable orders"),
    "damping_std_orders": ("σ ζ orders [%]", "part of σ ζ from the spread over the stable orders"),
}
_PCT_COLUMNS = ("damping_std", "damping_std_noise", "damping_std_orders")


def _mode_table(modes: list) -> str:
    """The identified modes with every indicator in stated units (damping columns in %) and a legend."""
    keys = ["mode", "freq_hz", "damping_pct"] + [c for c in modes[0] if c not in ("mode", "freq_hz", "damping_pct")]
    rows = [{_MODE_COLUMNS.get(k, (k, ""))[0]: (100 * float(r[k]) if k in _PCT_COLUMNS and r.get(k) is not None
                                                else r.get(k)) for k in keys} for r in modes]
    cols = [_MODE_COLUMNS.get(k, (k, ""))[0] for k in keys]
    fmt = {"f [Hz]": "{:.3f}", "ζ [%]": "{:.3f}", "σ ζ [%]": "{:.2g}", "MPD [°]": "{:.3g}"}
    legend = "".join(f"<li><b>{html.escape(_MODE_COLUMNS[k][0])}</b>: {html.escape(_MODE_COLUMNS[k][1])}</li>"
                     for k in keys if k in _MODE_COLUMNS and _MODE_COLUMNS[k][1])
    return _table(rows, cols, fmt) + f'<ul class="muted">{legend}</ul>'


def _which_model(diag: dict | None, upd: dict | None, files: dict | None = None) -> tuple[str, str] | None:
    """(file to use, why) between the parameter-updated model (``update/updated.bdf`` of a run folder) and the
    diagnosed one (``diagnose/diagnosed.bdf``: the diagnosed physics added, parameters re-fitted with it).
    ``files``: where those two are for outputs of commands run one by one (``{"update": path, "diagnose":
    path}``, relative to the report's folder; :func:`model_files`)."""
    files = {"update": "update/updated.bdf", "diagnose": "diagnose/diagnosed.bdf", **(files or {})}
    u, d = files["update"], files["diagnose"]
    if not diag:
        return (u, "the diagnosis has not run: the parameter-updated model is the best there is") if upd else None
    if diag.get("findings"):
        what = "; ".join(f.get("description", f.get("physics", "")) for f in diag["findings"])
        return (d,
                f"the diagnosis added physics the nominal model leaves out ({what}) and re-fitted the parameters "
                f"with it. {u} is a parameters-only update: its parameters absorb the missing "
                "physics and are biased by it (compare the two parameter tables); do not use it as the model of "
                "the structure")
    if not upd:
        return (d, "the diagnosis found no missing physics and no parameter update ran: the "
                "diagnosis' own parameter fit on the FRFs is the model")
    return (u,
            "the diagnosis found no missing physics: the parameter update (inverse eigensensitivity on the "
            f"identified modes) is the model to use; {d} holds the diagnosis' own parameter "
            "fit on the FRFs, without added physics, for comparison")


def model_files(folder, found: dict) -> dict:
    """``{"update": path, "diagnose": path}``: the bulk data ``modalab update`` (``updated.bdf``) and
    ``modalab diagnose`` (``diagnosed.bdf``) wrote beside the outputs :func:`collect_outputs` found in
    ``folder`` (``found``: {stage: [sources]}), relative to ``folder``; a stage without one is left out."""
    folder = Path(folder)
    out = {}
    for stage, name in (("update", "updated.bdf"), ("diagnose", "diagnosed.bdf")):
        near = [Path(s).parent / name for s in found.get(stage, [])]
        near += sorted(folder.glob(name)) + sorted(folder.glob(f"*/{name}"))
        hit = next((p for p in near if p.is_file()), None)
        if hit is not None:
            try:
                out[stage] = str(hit.resolve().relative_to(folder.resolve()))
            except ValueError:
                out[stage] = str(hit)
    return out


def _load(path):
    p = Path(path)
    if not p.is_file():
        return None
    try:
        return json.loads(p.read_text())
    except json.JSONDecodeError as e:         # a damaged output is not "the stage has not run"
        raise ModalabValueError(f"'{p}' line {e.lineno}: not valid JSON ({e.msg}); it is a stage output that was "
                                f"changed or cut: rerun that stage (modalab run ... --from {p.parent.name})") from None


def _geometry_figure(run_dir: Path, report_dir: Path, model=None) -> Path | None:
    """The FE model's wire frame (when ``model``, a bulk-data file, is given) with the measured DOFs of the test."""

    frf_path = run_dir / "frf" / "frf.uff"
    if not frf_path.is_file():
        return None
    coords, lines = {}, []
    try:
        coords = dict(uff.read_geometry(frf_path))
    except Exception:  # noqa: BLE001 - FRFs without geometry
        coords = {}
    if model is not None:
        try:     # the wire frame needs the grids and elements only: cards the builder does not model are left out
            m = load_model(model, ignore_unsupported=True)
        except ModalabError as e:
            log.warning("no wire frame in the geometry plot: %s", e)
        else:
            for nid, n in m.nodes.items():
                coords.setdefault(nid, tuple(float(x) for x in n.xyz))
            lines = [tuple(e.nodes[:2]) for e in m.elements.values() if len(getattr(e, "nodes", ())) >= 2]
            lines += [(r.independent, d) for r in m.rbe2s.values() for d in r.dependents]
    if not coords:
        return None
    frf = uff.read_frf(frf_path)
    dofs = list(dict.fromkeys(list(frf.responses) + list(frf.references)))
    path = report_dir / "geometry.png"
    fig = plot_geometry(coords, dofs=dofs, lines=lines, title="Test geometry: FE model and measured DOFs (arrows)")
    fig.savefig(path, dpi=90, metadata={"Software": None})
    return path


#: captions of the diagnosis engine's figures (:func:`updating.diagnosis.report.write_figures`)
_ENGINE_FIGURES = {
    "mci_maps.png": "MCI maps: condensed residual force per measured DOF and frequency line, after parameter "
                    "updating and with the diagnosed physics",
    "frf_overlay.png": "Receptance at the located DOFs: measured, nominal, parameters only, with the physics "
                       "(the engine's lines, at s = iω + β)",
    "frequencies.png": "Paired frequencies of the nominal, parameters-only and diagnosed models"}


def _selection_html(diag: dict) -> list:
    """The selected terms, the first screening's ranking (with the selected terms marked or said to be outside
    it) and the candidates the selection turned down with the engine's reason (``diagnosis.json``'s
    ``decisions``)."""
    out = []
    ranked = [r.get("candidate") for r in diag.get("ranking", [])]
    chosen = [f.get("description", f.get("physics", "")) for f in diag.get("findings", [])]
    if chosen:
        rows = [{"selected term": c, "physics": f.get("physics", ""),
                 "rank in the first screening": (ranked.index(c) + 1) if c in ranked else
                 f"not in its top {len(ranked)}" if ranked else "—"}
                for c, f in zip(chosen, diag["findings"])]
        out += ["<p>Selected terms (modelled, fitted with the parameters and kept because they cut the held-out "
                "error):</p>", _table(rows, ["selected term", "physics", "rank in the first screening"])]
    if ranked:
        rk = [{**r, "selected": "yes" if r.get("candidate") in chosen else ""} for r in diag["ranking"][:8]]
        out += ["<p>First screening: candidates ranked by the share of the residual each explains alone "
                "(a selected term outside this list was found by the exact FRF screening's picks):</p>",
                _table(rk, ["candidate", "physics", "explained", "selected"])]
    rej = [d for d in diag.get("decisions") or [] if d.get("decision") in ("rejected", "dropped")]
    if rej:
        out += ["<p>Candidates the selection tried and turned down (or dropped later), with the reason:</p>",
                _table(rej[:10], ["candidate", "decision", "reason"])]
    elif "decisions" not in diag and ranked:
        out.append('<p class="muted">(Why other candidates were turned down is not recorded in this '
                   "diagnosis.json: it was written before decisions were kept.)</p>")
    return out


def build_report(run_dir, report_dir=None, *, title: str | None = None, model=None,
                 model_files: dict | None = None) -> tuple[Path, Path]:
    """Write ``report.html`` (self-contained) and ``summary.json`` into ``report_dir``; returns both paths.

    ``title``: the report's (None: the run folder's name); ``model``: the FE model's bulk data, drawn as a wire
    frame under the test geometry."""
    run_dir = Path(run_dir)
    rd = Path(report_dir) if report_dir is not None else run_dir / "report"
    rd.mkdir(parents=True, exist_ok=True)
    name = title or run_dir.name
    frf_s = _load(run_dir / "frf" / "frf.json")
    rec = _load(run_dir / "frf" / "reciprocity.json")
    modes = (_load(run_dir / "identify" / "modes.json") or {}).get("table")
    ident = _load(run_dir / "identify" / "identification.json")
    corr = _load(run_dir / "correlate" / "correlation.json")
    upd = _load(run_dir / "update" / "update.json")
    diag = _load(run_dir / "diagnose" / "diagnosis.json")
    manifest = _load(run_dir / "manifest.json") or {"stages": {}}
    backend = (frf_s or {}).get("backend")
    if frf_s is None and (run_dir / "frf" / "frf.uff").is_file():
        # FRFs of commands run one by one (no frf.json): the backend their ID lines carry
        backend = (uff.read_frf(run_dir / "frf" / "frf.uff").metadata or {}).get("backend")
    use = _which_model(diag, upd, model_files)
    parts = [f"<h1>{html.escape(name)}</h1>",
             f'<p class="muted">{"modalab run" if (run_dir / "manifest.json").is_file() else "modalab"} report, '
             f'{_dt.datetime.now(_dt.timezone.utc):%Y-%m-%d %H:%M} UTC. '
             "Every figure is embedded in this file.</p>"]
    if backend == "sim":
        parts.append('<p class="statement"><b>Simulated data.</b> The hits were produced by the simulated lab '
                     "(hardware_sim, backend sim), not measured on hardware.</p>")
    elif backend:
        parts.append(f"<p>Data acquired with the {html.escape(str(backend))} backend.</p>")
    if use:
        parts.append(f'<p class="statement"><b>Model to use: {html.escape(use[0])}</b> — {html.escape(use[1])}.</p>')
    rows = [{"stage": s, "completed (UTC)": e.get("completed_utc", ""), "time [s]": float(e.get("elapsed_s", 0.0)),
             "key": e.get("key", "")[:12]} for s, e in manifest.get("stages", {}).items()]
    if rows:                    # a run's manifest; the commands run one by one keep none
        parts += ["<h2>Stages</h2>", _table(rows, ["stage", "completed (UTC)", "time [s]", "key"],
                                             {"time [s]": "{:.1f}"})]
    # diagnosis first: it is what people came for
    parts += _diagnosis_section(run_dir, diag)
    parts += _test_section(run_dir, rd, model, frf_s, rec)
    parts += _identification_section(run_dir, modes)
    parts += _correlation_and_update_sections(run_dir, upd, diag)
    doc = ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
           f"<title>{html.escape(name)}</title><style>{_CSS}</style></head><body>\n"
           + "\n".join(parts) + "\n</body></html>\n")
    out = rd / "report.html"
    write_text(out, doc)
    summary = {"title": name, "backend": backend, "simulated": backend == "sim" if backend else None,
               "model_to_use": {"file": use[0], "why": use[1]} if use else None, "frf": frf_s, "reciprocity": {"max_rel_diff": (rec or {}).get("max_rel_diff")},
               "modes": modes, "identification": {k: (ident or {}).get(k) for k in ("settings", "elapsed_s")},
               "correlation_before": corr, "update": upd, "diagnosis": diag,
               "stages": {s: {"key": e.get("key"), "elapsed_s": e.get("elapsed_s")}
                          for s, e in manifest.get("stages", {}).items()}}
    return out, write_json(rd / "summary.json", summary)


def _diagnosis_section(run_dir, diag) -> list:
    """The findings with their values and evidence, the error of each model, the candidate ranking, the
    parameters and the diagnosis figures."""
    parts = ["<h2>Diagnosis</h2>"]
    if not diag:
        return parts + ['<p class="muted">The diagnosis stage has not run.</p>']
    parts.append(f'<p class="statement">{html.escape(diag.get("statement", ""))}</p>')
    for f in diag.get("findings", []):
        # a std of None: the data do not determine the value (a flat direction, or the value on its bound)
        vals = "; ".join(f"{v['name']} = {_num(v['value'], '.4g')} ± {_num(v.get('std'), '.2g')} {v['unit']}"
                         if v.get("std") is not None else
                         f"{v['name']} = {_num(v['value'], '.4g')} {v['unit']} (± not determined by these data)"
                         for v in f.get("values", []))
        parts.append(f"<p><b>{html.escape(f.get('description', f.get('physics', '')))}</b> — {html.escape(vals)}"
                     f"<br><i>Evidence:</i> {html.escape(f.get('evidence', ''))}</p>")
    fit = diag.get("fit", {})
    if fit:
        # values may be null (no held-out DOFs; a modes-only diagnosis has no FRF error): shown as "—"
        frows = [{"model": k, **{kk: None if vv is None else float(vv) for kk, vv in v.items()}}
                 for k, v in fit.items()]
        keys = [c for c in ("frf_error_train", "frf_error_held_out", "freq_error_max_pct", "mac_min")
                if any(r.get(c) is not None for r in frows)]
        if keys:
            parts += ["<p>Error of each model (" + ", ".join(_FIT_LABELS[c] for c in keys) + "):</p>",
                      _table(frows, ["model"] + keys)]
    parts += _selection_html(diag)
    pars = diag.get("parameters", {})
    if pars:
        prow = [{"parameter": k, **{kk: v[kk] for kk in ("initial", "parameters_only", "updated", "std") if kk in v},
                 **({"loss factor in all": v["total"]["updated"]} if isinstance(v.get("total"), dict) else {})}
                for k, v in pars.items()]
        cols = ["parameter", "initial", "parameters_only", "updated", "std"]
        note = ""
        if any("loss factor in all" in r for r in prow):     # eta_<group>: offsets added to eta_global
            cols.append("loss factor in all")
            note = (" A group's eta is an offset added to eta_global (PARAM G); its loss factor in all is in the "
                    "last column.")
        parts += ["<p>Parameters in the diagnosis (parameter-only updating and jointly with the physics)."
                  f"{note}</p>", _table(prow, cols)]
    figs = sorted((run_dir / "diagnose" / "figures").glob("*.png")) if (run_dir / "diagnose" / "figures").is_dir() else []
    return parts + [_fig(p, _ENGINE_FIGURES.get(p.name, p.stem.replace("_", " "))) for p in figs]


def _test_section(run_dir, rd, model, frf_s, rec) -> list:
    """Geometry, the FRF set, reciprocity and coherence."""
    parts = ["<h2>Test overview</h2>"]
    g = _geometry_figure(run_dir, rd, model)
    if g:
        parts.append(_fig(g, "Geometry and measured DOFs"))
    if frf_s:
        parts.append(f"<p>{frf_s['responses']} response DOFs × references {', '.join(frf_s['references'])}; "
                     f"{frf_s['lines']} lines, {frf_s['band_hz'][0]:.3g}–{frf_s['band_hz'][1]:.4g} Hz; median "
                     f"coherence {frf_s['median_coherence']:.3f}.</p>")
    if rec and "max_rel_diff" in rec:
        parts.append(f"<p>Reciprocity: largest relative difference between reciprocal FRFs "
                     f"{100 * float(rec['max_rel_diff']):.1f} %.</p>")
    return parts + [_coherence_figure(run_dir, rd)]


def _coherence_figure(run_dir: Path, report_dir: Path) -> str:
    """The coherence map: the frf stage's (``modalab run``), else drawn here from the FRF file the report found
    (outputs of commands run one by one: ``modalab frf`` writes no map); where there is none, why in words."""
    frf_path, done = run_dir / "frf" / "frf.uff", run_dir / "frf" / "coherence.png"
    frf = uff.read_frf(frf_path) if frf_path.is_file() else None
    if frf is not None and frf.coherence is None:
        why = (f"the FRF file {frf_path.resolve().name} holds no coherence functions (they are estimated from "
               "repeated hits: modalab frf writes them beside the FRFs, an export may leave them out)")
    elif done.is_file():
        return _fig(done, "Coherence map")
    elif frf is not None:
        return _fig(plot_coherence_map(frf, report_dir / "coherence.png"), "Coherence map")
    else:
        why = ("no FRF file with this report: it takes the FRFs that identify read (the input named in "
               "modes.json), and found none in the folder")
    return f'<p class="muted">(No coherence map: {html.escape(why)}.)</p>'


def _identification_section(run_dir, modes) -> list:
    """Stabilisation diagram, the modes table and the synthesis."""
    parts = ["<h2>Identification</h2>", _fig(run_dir / "identify" / "stabilisation.png", "Stabilisation diagram")]
    if modes:
        parts += ["<p>Identified modes with their indicators:</p>", _mode_table(modes)]
    return parts + [_fig(run_dir / "identify" / "synthesis.png", "Synthesised vs measured FRFs")]


def _correlation_and_update_sections(run_dir, upd, diag=None) -> list:
    """MAC and frequency plots before and after updating, the updated parameters and the FRF overlays."""
    parts = ["<h2>Correlation before and after updating</h2>",
             _fig(run_dir / "correlate" / "mac_before.png", "MAC, nominal model"),
             _fig(run_dir / "update" / "mac_after.png", "MAC, updated model"),
             _fig(run_dir / "correlate" / "frequencies_before.png", "Frequencies, nominal model (45° plot)"),
             _fig(run_dir / "update" / "frequencies_after.png", "Frequencies, updated model (45° plot)"),
             "<h2>Model updating (inverse eigensensitivity)</h2>"]
    if upd:
        if diag and diag.get("findings"):
            parts.append("<p>Parameters only (update/updated.bdf): with physics missing from the model these values "
                         "absorb it; the diagnosis' joint fit above is the one to trust.</p>")
        prow = [{"parameter": k, **{kk: v[kk] for kk in ("initial", "updated", "std")}} for k, v in upd["parameters"].items()]
        parts.append(_table(prow, ["parameter", "initial", "updated", "std"]))
        parts.append(f"<p>{'Converged' if upd.get('converged') else 'Not converged'} after {upd.get('iterations')} "
                     "iterations.</p>")
        if upd.get("frequency_weights"):
            parts.append(f"<p>Frequency weights: {html.escape(str(upd['frequency_weights']))}.</p>")
        for g, c in ((upd.get("identifiability") or {}).get("residual_check") or {}).items():
            if c.get("std_factor", 1.0) > 1:
                parts.append(f"<p>The {html.escape(g)} residuals are {c['std_factor']:.3g} times their stated standard "
                             "deviations: the std above are raised by that factor. Either those deviations are too "
                             "small, or the model leaves out physics that the parameters absorb (see the diagnosis); "
                             "then no std bounds the parameters' bias.</p>")
    parts.append(_fig(run_dir / "update" / "convergence.png", "Parameter convergence"))
    parts.append("<h2>FRF overlays</h2>")
    return parts + [_fig(run_dir / "diagnose" / "frf_overlay_models.png",
                         "Measured FRFs and the nominal, parameter-updated and diagnosed models at the chosen DOFs "
                         "(models evaluated at s = iω + β of the measurement's exponential window)")]


# ----------------------------------------------------------------------------- step-by-step outputs
#: where build_report looks for each figure (stage folder), by file name
_FIGURE_STAGE = {"stabilisation.png": "identify", "synthesis.png": "identify", "coherence.png": "frf",
                 "mac_before.png": "correlate", "frequencies_before.png": "correlate",
                 "mac_after.png": "update", "frequencies_after.png": "update", "convergence.png": "update",
                 "frf_overlay_models.png": "diagnose"}


def _kind_of_json(path: Path) -> str | None:
    """Which stage wrote a JSON output, from its keys: 'identify' (modes.json), 'correlate', 'update',
    'diagnose', or None (another JSON)."""
    try:
        d = json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise ModalabValueError(f"'{path}': not valid JSON ({e}); it is a stage output that was changed or cut: "
                                "rerun the command that wrote it, or move it out of the folder") from None
    if not isinstance(d, dict):
        return None
    if "findings" in d and "statement" in d:
        return "diagnose"
    if "parameters" in d and "history" in d and "method" in d:
        return "update"
    if "pairs" in d and "test_dofs" in d:
        return "correlate"
    if "table" in d and "freq_hz" in d and "shapes" in d:
        return "identify"
    return None


def collect_outputs(folder, staging) -> dict:
    """Lay the outputs of commands run one by one in ``folder`` (``modalab frf/identify/correlate/update/
    diagnose`` with any ``-o``/``--json``/``--plots``/``--report`` names, in the folder or one sub-folder down,
    the diagnosis figures in ``<report>/figures``) out
    as the run folder :func:`build_report` reads, by symbolic links in ``staging``; returns {stage: [sources]}.

    A stage output is recognised by its content (the keys of its JSON), a figure by its name; two outputs of one
    stage are an error naming both (the report would have to pick one)."""
    folder, staging = Path(folder), Path(staging)
    found: dict = {}
    candidates = sorted(p for p in list(folder.glob("*")) + list(folder.glob("*/*")) + list(folder.glob("*/figures/*"))
                        if p.is_file() and "report" not in p.relative_to(folder).parts[:-1])

    def put(stage, name, src):
        dst = staging / stage / name
        if dst.exists() and dst.read_bytes() == src.read_bytes():
            return                              # the same output twice (diagnose --json X --report D writes both)
        if dst.exists():
            raise ModalabValueError(f"{folder}: two {stage} outputs, '{dst.resolve()}' and '{src}'; keep one in the "
                                    "folder (or give each run its own folder) and run modalab report again")
        dst.parent.mkdir(parents=True, exist_ok=True)
        dst.symlink_to(src.resolve())
        found.setdefault(stage, []).append(str(src))

    names = {"identify": "modes.json", "correlate": "correlation.json", "update": "update.json",
             "diagnose": "diagnosis.json"}
    for p in candidates:
        if p.suffix.lower() == ".json":
            kind = _kind_of_json(p)
            if kind:
                put(kind, names[kind], p)
    modes = staging / "identify" / "modes.json"
    frf = Path(json.loads(modes.read_text()).get("input") or "") if modes.exists() else None
    if frf is not None and not frf.is_absolute():
        frf = folder / frf                      # identify ran in the folder (as written in the README)
    if frf is not None and frf.suffix.lower() == ".uff" and frf.is_file():
        put("frf", "frf.uff", frf)              # the FRFs the modes came from: the test geometry figure
    for p in candidates:
        if p.suffix.lower() != ".png":
            continue
        stage = _FIGURE_STAGE.get(p.name)
        if p.parent.name == "figures" and (p.parent.parent / "diagnosis.json").is_file():
            put("diagnose", f"figures/{p.name}", p)
        elif stage == "correlate" and p.name == "mac_before.png" and (p.parent / "update.json").is_file():
            continue                            # update's copy of the nominal MAC: the correlation's own is used
        elif stage:
            put(stage, p.name, p)
    return found
