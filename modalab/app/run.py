"""``modalab run``: the whole chain from a project file, as stages with a manifest.

Stages (:data:`modalab.app.project.STAGES`)::

    acquire → frf (+ reciprocity) → identify → correlate → update → diagnose → report

Each stage writes its artifacts (UFF, JSON, PNG, bulk data) into ``OUT/<stage>/`` and then, last and
atomically (write to a temporary file, ``os.replace``), its entry in ``OUT/manifest.json``: the stage's
key, the options it used, the sha256 of every input file and of every output it wrote.  The key is the
sha256 of (options, input-file hashes, the output hashes of the stages it depends on), so

* a rerun skips a stage whose key is unchanged and whose outputs are still there with the same hashes;
* a changed option changes only the key of that stage; a downstream stage's key holds the hashes of the
  *products* it reads (:data:`PRODUCTS`: ``session.uff``, ``frf.uff``, ``modes.uff``, ``modes.json``, ...; not
  figures or timings), so it reruns only when those changed (the dependencies are a graph, not a chain: ``update`` and
  ``diagnose`` do not depend on each other; the report depends on everything);
* a stage without a manifest entry is incomplete — an interrupted run redoes it (the acquisition itself
  resumes hit by hit through the session's store) and continues with the rest.

Dependencies: acquire ← plan; frf ← acquire (or the project's FRF file); identify ← frf;
correlate ← identify + model; update ← identify + model + parameters; diagnose ← frf + identify (the test
modes of its frequency and MAC columns) + model + parameters;
report ← everything.

:func:`run_project` is the library entry point; ``progress`` (a callable ``(stage, event, text)`` with event
in 'start', 'skip', 'done', 'info') lets the CLI show progress.  Library code logs, never prints.
"""
from __future__ import annotations

import datetime as _dt
import hashlib
import importlib
import json
import logging
import re
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path

from modalab.app import stages
from modalab.core._output import protect
from modalab.core.errors import PlanError
from modalab.app.outputs import write_json, write_text
from modalab.app.project import STAGES, Project, load_project
from acquisition.plan import load_plan

log = logging.getLogger(__name__)

__all__ = ["run_project", "RunResult", "Manifest", "stage_key", "sha256_file", "content_hash", "DEPENDS", "load_truth"]

#: upstream stages of each stage
DEPENDS = {"acquire": (), "frf": ("acquire",), "identify": ("frf",), "correlate": ("identify",),
           "update": ("identify",), "diagnose": ("frf", "identify"),
           "report": ("acquire", "frf", "identify", "correlate", "update", "diagnose")}
#: project sections each stage reads (its options)
SECTIONS = {"acquire": ("test",), "frf": ("frf", "test"), "identify": ("identify",), "correlate": ("correlate", "model"),
            "update": ("update", "model", "correlate"), "diagnose": ("diagnose", "model"), "report": ("report", "project")}
#: the outputs downstream stages consume (their hashes enter the downstream keys; figures and timings do not)
PRODUCTS = {"acquire": ("session.uff",), "frf": ("frf.uff",), "identify": ("modes.uff", "modes.json"),
            "correlate": ("correlation.json",), "update": ("updated.bdf", "update.json"),
            "diagnose": ("diagnosis.json", "diagnosed.bdf")}
MANIFEST = "manifest.json"
_VERSION = 1


def sha256_file(path, chunk: int = 1 << 20) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while True:
            b = fh.read(chunk)
            if not b:
                break
            h.update(b)
    return h.hexdigest()


_UFF_STAMP = re.compile(rb"^\d\d-[A-Z]{3}-\d\d \d\d:\d\d:\d\d modalab w=[0-9a-f]+", re.M)


def content_hash(path) -> str:
    """sha256 of a file's content; in universal files the writer's date and write-group tag are left out,
    so the same data written twice hashes the same (downstream stages are not rerun for a new timestamp)."""
    p = Path(path)
    if p.suffix.lower() not in (".uff", ".unv"):
        return sha256_file(p)
    return hashlib.sha256(_UFF_STAMP.sub(b"<stamp>", p.read_bytes())).hexdigest()


def _canon(obj) -> str:
    return json.dumps(obj, sort_keys=True, default=str, separators=(",", ":"))


def stage_key(options: dict, inputs: dict, upstream: dict) -> str:
    """sha256 over the stage's options, its input files' hashes and its upstream stages' output hashes."""
    return hashlib.sha256(_canon({"v": _VERSION, "options": options, "inputs": inputs,
                                  "upstream": upstream}).encode()).hexdigest()


class Manifest:
    """``OUT/manifest.json``: one entry per completed stage (see the module docstring)."""

    def __init__(self, out_dir):
        self.out_dir = Path(out_dir)
        self.path = self.out_dir / MANIFEST
        self.data = {"version": _VERSION, "stages": {}}
        if self.path.is_file():
            try:
                d = json.loads(self.path.read_text())
                if d.get("version") == _VERSION and isinstance(d.get("stages"), dict):
                    self.data = d
                else:
                    log.warning("%s has another format; every stage will run again", self.path)
            except json.JSONDecodeError:
                log.warning("%s is not valid JSON; every stage will run again", self.path)

    @property
    def stages(self) -> dict:
        return self.data["stages"]

    def entry(self, stage: str) -> dict | None:
        return self.stages.get(stage)

    def valid(self, stage: str, key: str) -> bool:
        """True when the stage completed with this key and its outputs are unchanged on disk."""
        e = self.entry(stage)
        if not e or e.get("key") != key:
            return False
        for rel, h in e.get("outputs", {}).items():
            p = self.out_dir / rel
            if not p.is_file() or content_hash(p) != h:
                log.info("%s: output %s changed or missing; the stage runs again", stage, rel)
                return False
        return True

    def record(self, stage: str, entry: dict) -> None:
        self.stages[stage] = entry
        self.save()

    def forget(self, stage: str) -> None:
        if self.stages.pop(stage, None) is not None:
            self.save()

    def save(self) -> None:
        self.out_dir.mkdir(parents=True, exist_ok=True)
        write_json(self.path, self.data)


@dataclass
class RunResult:
    """What :func:`run_project` did: stage -> 'ran' | 'skipped' | 'not requested'; summaries per stage."""

    out_dir: Path
    status: dict = field(default_factory=dict)
    summaries: dict = field(default_factory=dict)
    elapsed_s: dict = field(default_factory=dict)

    @property
    def report(self) -> Path:
        return self.out_dir / "report" / "report.html"


def load_truth(spec: str):
    """Import ``'package.module:function'`` and call it: the structure on the simulated bench."""
    mod, _, fn = spec.partition(":")
    try:
        f = getattr(importlib.import_module(mod), fn)
    except (ImportError, AttributeError) as e:
        raise PlanError(f"[test] truth = {spec!r} cannot be imported ({e}); give 'package.module:function'") from None
    return f()


# =================================================================================== stages
class _Context:
    def __init__(self, project: Project, out_dir: Path, backend: str, progress):
        self.project = project
        self.out = out_dir
        self.backend = backend
        self.progress = progress

    def dir(self, stage: str) -> Path:
        d = self.out / stage
        d.mkdir(parents=True, exist_ok=True)
        return d

    def info(self, stage: str, text: str) -> None:
        log.info("%s: %s", stage, text)
        if self.progress:
            self.progress(stage, "info", text)


def _plan_with(project: Project):

    return load_plan(project.plan_path)


def _truth_lab(ctx: _Context, plan):
    """The simulated bench carrying the project's ``[test] truth`` structure (:func:`modalab.app.stages.make_sim_backend`)."""
    t = ctx.project.options["test"]
    seed = t["seed"] if t["seed"] is not None else plan.sim.get("seed", 1)
    return stages.make_sim_backend(plan, seed=seed, structure=load_truth(t["truth"]))


class _AcquireObserver:
    """Session observer that reports points as stage progress."""

    def __init__(self, ctx):
        self.ctx = ctx

    def point_started(self, index, point, n_points):
        self.ctx.info("acquire", f"point {index + 1}/{n_points}: {point}")

    def hit(self, *a):
        pass

    def decided(self, *a):
        pass

    def point_finished(self, *a):
        pass

    def message(self, text):
        log.info("acquire: %s", text)


def stage_acquire(ctx: _Context, resume: bool) -> tuple[list, dict]:
    """Run the test plan (automatic mode) and export ``acquire/session.uff`` (raw hits, FRFs, geometry).

    :func:`modalab.app.stages.acquire` runs the plan on the plan's own [sim] structure or on NI hardware; with a
    ``[test] truth`` builder and the sim backend, on a simulated bench carrying that structure.
    """
    d = ctx.dir("acquire")
    plan = _plan_with(ctx.project)
    truth = ctx.backend == "sim" and bool(ctx.project.options["test"]["truth"])
    # export=False with a truth bench: its session folder never held a copy of session.uff (exported below)
    opts = stages.AcquireOptions(backend=ctx.backend, auto=True, resume=resume,
                                 seed=ctx.project.options["test"]["seed"], export=not truth)
    r = stages.acquire(ctx.project.plan_path, d / "session", opts, daq=_truth_lab(ctx, plan) if truth else None,
                       observer=_AcquireObserver(ctx))
    sess, summary = r.result.session, r.result.summary
    if not summary.complete:
        raise PlanError(f"the acquisition did not complete ({summary.table()}); run again to continue")
    out = sess.export(d / "session.uff")
    summ = summary.to_dict() if hasattr(summary, "to_dict") else {}
    return [out], {"points": len(plan.points), "summary": summ}


# Each stage of the run is the stage function of :mod:`modalab.app.stages` with the project's options; these
# adapters only map the project's sections to the options dataclasses and the run folder's layout.
def stage_frf(ctx: _Context) -> tuple[list, dict]:
    """Raw hits → H1 FRFs + coherence (reciprocity-reordered), reciprocity check, coherence map."""
    d = ctx.dir("frf")
    o = ctx.project.options["frf"]
    if ctx.project.frf_path is not None:
        r = stages.frf(ctx.project.frf_path, d / "frf.uff", measured=True, details_dir=d)
    else:
        plan = _plan_with(ctx.project)
        opts = stages.FRFOptions(
            estimator=o["estimator"], reciprocity=o["reciprocity"], exp_beta=plan.exp_beta if o["exp_end_level"] is None else None,   # the project's level wins
            force_fraction=o["force_fraction"] if o["force_fraction"] is not None else plan.force_fraction,
            exp_end_level=o["exp_end_level"] if o["exp_end_level"] is not None else (plan.exp_end_level or None))
        r = stages.frf(ctx.out / "acquire" / "session.uff", d / "frf.uff", opts, details_dir=d)
    return list(r.files), r.summary


def stage_identify(ctx: _Context) -> tuple[list, dict]:
    d = ctx.dir("identify")
    o = ctx.project.options["identify"]
    opts = stages.IdentifyOptions(band_hz=o["band_hz"], max_order=o["max_order"], select=o["select"],
                                  weighting=o["weighting"], band_option="[identify] band_hz",
                                  band_source=str(ctx.project.path))
    r = stages.identify(ctx.out / "frf" / "frf.uff", d / "modes.uff", opts, json_path=d / "modes.json",
                        plots_dir=d, report_path=d / "identification.json")
    return list(r.files), r.summary


def _correlate_options(ctx: _Context) -> stages.CorrelateOptions:
    o = ctx.project.options["correlate"]
    return stages.CorrelateOptions(mac_min=o["mac_min"], freq_weight=o["freq_weight"],
                                   n_modes=ctx.project.options["model"]["n_modes"], freq_window=o["freq_window"],
                                   dofmap=str(ctx.project.resolve(o["map"])) if o["map"] else None,
                                   geometry=str(ctx.project.resolve(o["geometry"])) if o["geometry"] else None,
                                   same_ids=o["same_ids"])


def stage_correlate(ctx: _Context) -> tuple[list, dict]:
    d = ctx.dir("correlate")
    r = stages.correlate(ctx.project.bulk_path, ctx.out / "identify" / "modes.uff", _correlate_options(ctx),
                         json_path=d / "correlation.json", plots_dir=d)
    return list(r.files), r.summary


def stage_update(ctx: _Context) -> tuple[list, dict]:
    o = ctx.project.options["update"]
    if not o["parameters"]:
        raise PlanError(f"{ctx.project.path}: [update] parameters = 'params.toml' is missing; updating needs "
                        "declared parameters")
    opts = stages.UpdateOptions(method="eigensensitivity", parameters=str(ctx.project.resolve(o["parameters"])),
                                max_iter=o["max_iter"], regularisation=o["regularisation"],
                                use_shapes=o["use_shapes"], freq_sigma=o["freq_sigma"], shape_sigma=o["shape_sigma"],
                                correlation=_correlate_options(ctx))
    # modes.json, not modes.uff: it carries the identification's frequency standard deviations (freq_std_hz),
    # which weight the frequencies; a UFF 55 cannot, and the update would fall back to an assumed 1 %
    r = stages.update(ctx.project.bulk_path, ctx.dir("update"), opts, modes_path=ctx.out / "identify" / "modes.json")
    return list(r.files), r.summary


def stage_diagnose(ctx: _Context) -> tuple[list, dict]:
    d = ctx.dir("diagnose")
    o = ctx.project.options["diagnose"]
    opts = stages.DiagnoseOptions(
        parameters=str(ctx.project.resolve(o["parameters"])) if o["parameters"] else None,
        band_hz=o["band_hz"] or ctx.project.options["identify"]["band_hz"], max_lines=o["max_lines"],
        band_option="[diagnose] band_hz" if o["band_hz"] else "[identify] band_hz", band_source=str(ctx.project.path),
        max_findings=o["max_findings"], max_nfev=o["max_nfev"], holdout=o["holdout"], kinds=o["kinds"],
        jobs=o["jobs"], overlay_dofs=ctx.project.options["report"]["frf_dofs"])
    modes = ctx.out / "identify" / "modes.uff"     # the identified modes give the frequency and MAC columns
    r = stages.diagnose(ctx.project.bulk_path, frf_path=ctx.out / "frf" / "frf.uff",
                        modes_path=modes if modes.is_file() else None, opts=opts, out_dir=d,
                        updated_model=ctx.out / "update" / "updated.bdf",
                        progress=lambda s: ctx.info("diagnose", s))
    return list(r.files), r.summary


def stage_report(ctx: _Context) -> tuple[list, dict]:
    opts = stages.ReportOptions(title=ctx.project.options["report"]["title"] or ctx.project.name,
                                model=str(ctx.project.bulk_path))
    r = stages.report(ctx.out, ctx.dir("report"), opts)
    return list(r.files), r.summary


# =================================================================================== runner
def _inputs(project: Project, stage: str, backend: str) -> dict:
    files = {}
    o = project.options
    if stage == "acquire" and project.plan_path is not None:
        files["plan"] = project.plan_path
    if stage == "frf":
        if project.frf_path is not None:
            files["frf"] = project.frf_path
        elif project.plan_path is not None:
            files["plan"] = project.plan_path
    if stage in ("correlate", "update", "diagnose"):
        files["model"] = project.bulk_path
    if stage in ("correlate", "update"):
        for key in ("map", "geometry"):
            if o["correlate"][key]:
                files[key] = project.resolve(o["correlate"][key])
    if stage == "update" and o["update"]["parameters"]:
        files["parameters"] = project.resolve(o["update"]["parameters"])
    if stage == "diagnose" and o["diagnose"]["parameters"]:
        files["parameters"] = project.resolve(o["diagnose"]["parameters"])
    out = {k: sha256_file(v) for k, v in files.items()}
    if stage == "acquire":
        out["backend"] = backend
    return out


def _options(project: Project, stage: str) -> dict:
    opts = {s: project.options.get(s, {}) for s in SECTIONS[stage]}
    if stage == "diagnose":
        opts["identify_band"] = project.options["identify"]["band_hz"]
    if stage == "diagnose" or stage == "report":
        opts["report_dofs"] = project.options["report"]["frf_dofs"]
    return opts


def _wanted(project: Project) -> list:
    st = list(STAGES)
    if project.plan_path is None:
        st.remove("acquire")
    if not project.options["update"]["parameters"]:
        st.remove("update")
    if not project.options["diagnose"]["enabled"]:
        st.remove("diagnose")
    return st


_RUN = {"frf": stage_frf, "identify": stage_identify, "correlate": stage_correlate, "update": stage_update,
        "diagnose": stage_diagnose, "report": stage_report}


def run_project(project, out_dir, *, backend: str | None = None, from_stage: str | None = None,
                until_stage: str | None = None, progress=None, force: bool = False) -> RunResult:
    """Run (or continue) a project into ``out_dir``; see the module docstring.

    backend : 'sim' | 'nidaqmx' (default: the project's [test] backend).
    from_stage : rerun this stage and every stage that depends on it, even if the manifest says they are done.
    until_stage : stop after this stage.
    progress : callable ``(stage, event, text)``.
    force : rerun every requested stage.
    """
    proj = project if isinstance(project, Project) else load_project(project)
    be = backend or proj.options["test"]["backend"]
    if be not in ("sim", "nidaqmx"):
        raise PlanError(f"backend {be!r}; expected 'sim' or 'nidaqmx'")
    for s in (from_stage, until_stage):
        if s is not None and s not in STAGES:
            raise PlanError(f"stage {s!r}; expected one of {', '.join(STAGES)}")
    out = Path(out_dir).resolve()
    out.mkdir(parents=True, exist_ok=True)
    man = Manifest(out)
    ctx = _Context(proj, out, be, progress)
    wanted = _wanted(proj)
    stop = STAGES.index(until_stage) if until_stage else len(STAGES) - 1
    forced = _downstream_of(from_stage)
    result = RunResult(out_dir=out)
    ins = _project_inputs(proj)
    _check_inputs_outside(ins, out)
    with protect(ins):           # no writer may replace a project input, whatever stage calls it
        for s in STAGES:
            if s not in wanted:
                result.status[s] = "not in project"
                continue
            if STAGES.index(s) > stop:
                result.status[s] = "not requested"
                continue
            ups = _upstream_outputs(man, s, wanted)
            opts = _options(proj, s)
            inputs = _inputs(proj, s, be)
            key = stage_key(opts, inputs, ups)
            if not force and s not in forced and man.valid(s, key):
                result.status[s] = "skipped"
                result.summaries[s] = man.entry(s).get("summary", {})
                if progress:
                    progress(s, "skip", "up to date")
                continue
            _run_stage(ctx, man, s, {"key": key, "options": opts, "inputs": inputs, "depends": list(ups)}, result)
    return result


def _downstream_of(from_stage: str | None) -> set:
    """``from_stage`` and every stage downstream of it (transitively): the stages ``--from`` reruns."""
    forced = set()
    if from_stage:
        forced = {from_stage}
        for s in STAGES:
            if any(u in forced for u in DEPENDS[s]):
                forced.add(s)
    return forced


def _check_inputs_outside(inputs: list, out: Path) -> None:
    """An output never overwrites an input: no project input may lie in a stage folder or be the manifest."""
    for s in STAGES:
        for p in inputs:
            if _inside(p, out / s) or _inside(p, out / "manifest.json"):
                raise PlanError(f"input '{p}' lies in '{out / s}', which the run replaces; an output never "
                                "overwrites an input. Move the input out of the output folder or choose another -o")


def _upstream_outputs(man: Manifest, s: str, wanted: list) -> dict:
    """The recorded output hashes of the stages ``s`` depends on (only their :data:`PRODUCTS`, except for the
    report, which reads everything); an error when a wanted upstream stage has not completed."""
    ups = {u: {k: h for k, h in man.entry(u)["outputs"].items()
               if s == "report" or Path(k).name in PRODUCTS.get(u, ())}
           for u in DEPENDS[s] if u in wanted and man.entry(u)}
    missing = [u for u in DEPENDS[s] if u in wanted and not man.entry(u)]
    if missing:
        raise PlanError(f"stage {s} needs {', '.join(missing)} first; run without --from/--until to complete "
                        "them")
    return ups


def _run_stage(ctx: _Context, man: Manifest, s: str, entry: dict, result: RunResult) -> None:
    """Run stage ``s`` into a fresh ``OUT/<s>/`` (the acquisition resumes when its key is unchanged), then record
    its manifest ``entry`` (key, options, inputs, depends) with the hashes of what it wrote."""
    out, progress, key = ctx.out, ctx.progress, entry["key"]
    if progress:
        progress(s, "start", "")
    t0 = time.perf_counter()
    previous = man.entry(s)
    man.forget(s)
    pending = out / s / ".pending_key"
    if s == "acquire":
        resume = (pending.is_file() and pending.read_text().strip() == key
                  and (out / s / "session" / "session.json").is_file())
        if not resume and (out / s).exists():
            shutil.rmtree(out / s)
        ctx.dir(s)
        write_text(pending, key)
        outputs, summary = stage_acquire(ctx, resume)
    else:
        outputs, summary = _run_keeping_previous(ctx, man, s, previous)
    elapsed = time.perf_counter() - t0
    rel = {}
    for p in outputs:
        p = Path(p)
        if p.is_file():
            rel[str(p.resolve().relative_to(out))] = content_hash(p)
    man.record(s, {**entry, "outputs": rel, "summary": summary, "elapsed_s": round(elapsed, 3),
                   "completed_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")})
    if pending.is_file():
        pending.unlink()
    result.status[s] = "ran"
    result.summaries[s] = summary
    result.elapsed_s[s] = elapsed
    if progress:
        progress(s, "done", f"{elapsed:.1f} s")


def _run_keeping_previous(ctx: _Context, man: Manifest, s: str, previous: dict | None) -> tuple[list, dict]:
    """Run stage ``s`` (not the acquisition) into a fresh ``OUT/<s>/``; its previous folder waits beside it
    (``OUT/.<s>.previous``) and, when the stage fails, comes back with its manifest entry, so that a failed
    rerun leaves the earlier complete output (and the stages built on it) as they were."""
    out = ctx.out
    keep = out / f".{s}.previous"
    if keep.exists():                       # left by a run that was killed: the manifest no longer lists it
        shutil.rmtree(keep)
    if (out / s).exists():
        (out / s).rename(keep)
    try:
        result = _RUN[s](ctx)
    except BaseException:
        if (out / s).exists():
            shutil.rmtree(out / s)
        if keep.exists():
            keep.rename(out / s)
            if previous is not None:
                man.record(s, previous)
        raise
    if keep.exists():
        shutil.rmtree(keep)
    return result


def _project_inputs(proj: Project) -> list:
    """The files a project reads: the project file, the plan or FRF file, the bulk data, the DOF map, the test
    geometry and the parameter files."""
    o = proj.options
    paths = [proj.path, proj.plan_path, proj.frf_path, proj.bulk_path]
    paths += [proj.resolve(o["correlate"][k]) for k in ("map", "geometry") if o["correlate"].get(k)]
    paths += [proj.resolve(o[sec]["parameters"]) for sec in ("update", "diagnose") if o[sec].get("parameters")]
    return [Path(p).resolve() for p in paths if p is not None]


def _inside(p: Path, folder: Path) -> bool:
    """True when ``p`` is ``folder`` or lies inside it."""
    folder = folder.resolve()
    return p == folder or folder in p.parents
