"""The embedded demo of ``modalab run``: a GARTEUR SM-AG19-like frame tested in the simulated lab.

The project files (``modalab/app/demo_data/demo_project/``, copied to ``examples/demo_project/``) hold what a
test engineer has: the test plan (a roving hammer over the wings, fuselage, drums, fin and tail plane; three
fixed accelerometers at the wing tips and the fin tip), the *nominal* FE model as bulk data
(``nominal.bdf``: :func:`updating.fe.models.garteur.garteur_model` with its default mesh on a soft vertical
suspension) and the updating parameters (``params.toml``).

The structure on the simulated bench is built here, in Python, by :func:`truth_structure` — the project
names it (``[test] truth = "modalab.app.demo_project:truth_structure"``) without saying what it contains.
It differs from the nominal model by a finer mesh, by small errors in the declared parameters, and by
something the nominal model leaves out.  Finding that is the diagnosis' job.

:func:`run_demo` copies the project into ``OUT/project/`` and runs it into ``OUT`` (``quick=True``: the
lighter variant used by the tests, on the same points: 2 averages instead of 3, at most 3 hits instead of 4,
identification up to order 24 instead of 40, at most 10 updating iterations instead of 20 — not shorter, the
diagnosis takes most of the time; the CLI's ``--quick`` help, :data:`modalab.app.cli.QUICK_HELP`,
says the same).
:func:`write_demo_files` regenerates the project files (maintainers only).
"""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from modalab.app.outputs import write_bytes, write_text
from updating.fe import LumpedMass, ParametricFEModel
from updating.fe.models.garteur import garteur_model, garteur_parameters
from modalab.core.dof import Dof
from modalab.core.structure import Structure
from updating.fe.bulk import to_bulk, write_bdf
from modalab.app.run import run_project

log = logging.getLogger(__name__)

__all__ = ["truth_structure", "truth_model", "nominal_model", "run_demo", "demo_project_dir",
           "write_demo_files", "DEMO_PARAMETERS"]

#: the updating parameters of the demo (names of :func:`updating.fe.models.garteur.garteur_parameters`)
DEMO_PARAMETERS = ("E_wing", "t_wing", "t_fin", "rho_fuselage")
_SUSPENSION_N_PER_M = 500.0
_LOSS_FACTOR = 0.02
_ERRORS = (1.04, 0.97, 1.05, 0.95)         # truth / nominal for DEMO_PARAMETERS


def demo_project_dir() -> Path:
    """The packaged demo project folder."""
    return Path(__file__).resolve().parent / "demo_data" / "demo_project"


def nominal_model():
    """The nominal FE model as the project's bulk data holds it (also the generator of ``nominal.bdf``)."""

    m = garteur_model(8, suspension=True, suspension_stiffness=_SUSPENSION_N_PER_M)
    m.global_ge = _LOSS_FACTOR
    return m


def truth_model():
    """The FE model of the structure on the bench (finer mesh, parameter errors, and one more thing)."""

    base = garteur_model(16, suspension=True, suspension_stiffness=_SUSPENSION_N_PER_M)
    pm = ParametricFEModel(base, garteur_parameters(base, DEMO_PARAMETERS))
    m = pm.model_at(np.array(_ERRORS, float))
    m.global_ge = _LOSS_FACTOR
    m.add_element(LumpedMass(9990, m.metadata["points"]["right_tip"], 0.2, group="bench"))
    return m


def truth_structure():
    """The truth as a :class:`modalab.core.structure.Structure` numbered like the nominal model.

    Nodes of the finer mesh that coincide with nominal nodes take the nominal ids (so the measured DOFs
    carry the labels the analyst's model uses); the others get ids above 10000.
    """

    truth, nom = truth_model(), nominal_model()
    nid = {tuple(np.round(n.xyz, 9)): n.nid for n in nom.nodes.values()}
    idmap = {n.nid: nid.get(tuple(np.round(n.xyz, 9)), 10000 + n.nid) for n in truth.nodes.values()}
    st = truth.structure()
    return Structure(M=st.M, K=st.K, C=st.C, D=st.D, dofs=[Dof(idmap[d.node], d.direction) for d in st.dofs],
                     coords={idmap[k]: v for k, v in st.coords.items()}, name="demo bench (simulated)")


# ----------------------------------------------------------------------------- project files
def _points(quick: bool):
    nom = nominal_model()
    truth = truth_model()
    P = nom.metadata["points"]
    common = {tuple(np.round(n.xyz, 9)) for n in truth.nodes.values()}
    dependents = {d for r in nom.rbe2s.values() for d in r.dependents}
    ok = [n for n in nom.nodes if tuple(np.round(nom.nodes[n].xyz, 9)) in common and n not in dependents]
    wing = [n for n in nom.metadata["members"]["wing"] if n in ok]
    fus = [n for n in nom.metadata["members"]["fuselage"] if n in ok]
    fin = [n for n in nom.metadata["members"]["fin"] if n in ok]
    tail = [n for n in nom.metadata["members"]["htail"] if n in ok]
    step = 4           # the diagnosis of this demo is tuned on this set (see run_demo); quick differs in averages
    pts = [f"{n}+Z" for n in wing[::step]] + [f"{wing[-1]}+Z"] + [f"{n}+Z" for n in fus[::step]]
    pts += [f"{P['right_drum_front']}+Z", f"{P['left_drum_front']}+Z", f"{P['fin_tip']}+Y", f"{tail[0]}+Z",
            f"{tail[-1]}+Z"]
    pts = list(dict.fromkeys(pts))
    refs = [f"{P['right_tip']}+Z", f"{P['left_tip']}+Z", f"{P['fin_tip']}+Y"]
    geometry = {int(d.split("+")[0]): [round(float(x), 6) for x in nom.nodes[int(d.split("+")[0])].xyz]
                for d in pts + refs}
    return pts, refs, geometry


def _plan_text(quick: bool) -> str:
    pts, refs, geo = _points(quick)
    lines = ["# Impact test of the GARTEUR-like frame: roving hammer, three fixed accelerometers.",
             "[acquisition]", "sample_rate_hz = 512.0", "bandwidth_hz = 200.0",
             "record_s = 4.0", "pretrigger_s = 0.03125",
             f"averages = {2 if quick else 3}", f"max_hits = {3 if quick else 4}", "timeout_s = 10.0", "",
             "[trigger]", 'channel = "hammer"', "level = 2.0", 'slope = "rising"', "",
             "[windows]", "force_fraction = 0.05", "force_taper = 0.25", "exp_end_level = 0.05", "",
             "[[channels]]", 'name = "hammer"', 'physical = "cDAQ1Mod1/ai0"', 'role = "force"', 'dof = "roving"',
             "sensitivity = 2.25", 'sensitivity_unit = "mV/N"', "range = 200.0", ""]
    for k, r in enumerate(refs, start=1):
        lines += ["[[channels]]", f'name = "acc{k}"', f'physical = "cDAQ1Mod1/ai{k}"', 'role = "response"',
                  f'dof = "{r}"', "sensitivity = 100.0", 'sensitivity_unit = "mV/g"', "range = 49.0", ""]
    lines += ["[roving]", 'pattern = "hammer"', "points = [" + ", ".join(f'"{p}"' for p in pts) + "]", "",
              "[geometry]"]
    lines += [f"{n} = [{x[0]}, {x[1]}, {x[2]}]" for n, x in sorted(geo.items())]
    lines += ["", "[sim]                       # the simulated bench of `modalab acquire --backend sim` (`modalab run` "
              "uses the",
              'structure = "nominal.bdf"   # project\'s truth builder instead); a relative path is read from this folder',
              "seed = 7", "force_n = 50.0", 'hammer_tip = "soft"', "hammer_mass_kg = 1.0", ""]
    return "\n".join(lines)


def _project_text(quick: bool) -> str:
    q = quick
    return "\n".join([
        "# modalab run project: the embedded demo (GARTEUR SM-AG19-like frame in the simulated lab).",
        "[project]", f'name = "GARTEUR-like frame{" (quick)" if q else ""}"', "",
        "[test]", f'plan = "{"plan_quick.toml" if q else "plan.toml"}"', 'backend = "sim"',
        'truth = "modalab.app.demo_project:truth_structure"   # the simulated bench (a Python builder)', "",
        "[frf]", 'estimator = "H1"', "reciprocity = true", "",
        "[identify]", "band_hz = [2.0, 80.0]", f"max_order = {24 if q else 40}", "",
        "[model]", 'bulk = "nominal.bdf"', "n_modes = 20", "",
        "[correlate]", "mac_min = 0.5", "",
        "[update]", 'parameters = "params.toml"', f"max_iter = {10 if q else 20}", "",
        "[diagnose]", "max_lines = 40", "band_hz = [2.0, 80.0]", "max_nfev = 10",
        "max_findings = 2", "",
        "[report]", f'frf_dofs = ["218+Z", "200+Z", "508+Y", "115+Z"]', ""])


_PARAMS_TEXT = """# Updating parameters of the demo: multipliers of the nominal values (1 = nominal).
[[parameter]]
name = "E_wing"
field = "E"
properties = ["wing"]
lower = 0.5
upper = 2.0

[[parameter]]
name = "t_wing"
field = "h"
properties = ["wing"]
lower = 0.5
upper = 2.0

[[parameter]]
name = "t_fin"
field = "h"
properties = ["fin"]
lower = 0.5
upper = 2.0

[[parameter]]
name = "rho_fuselage"
field = "rho"
properties = ["fuselage"]
lower = 0.5
upper = 2.0
"""


def write_demo_files(folder=None) -> Path:
    """(Re)generate the demo project files into ``folder`` (default: the packaged folder)."""

    d = Path(folder) if folder is not None else demo_project_dir()
    d.mkdir(parents=True, exist_ok=True)
    write_text(d / "nominal.bdf", "$ GARTEUR SM-AG19-like frame, nominal model (modalab demo)\n"
               + write_bdf(to_bulk(nominal_model())))
    write_text(d / "params.toml", _PARAMS_TEXT)
    write_text(d / "plan.toml", _plan_text(False))
    write_text(d / "plan_quick.toml", _plan_text(True))
    write_text(d / "project.toml", _project_text(False))
    write_text(d / "project_quick.toml", _project_text(True))
    return d


DEMO_FILES = ("project.toml", "project_quick.toml", "plan.toml", "plan_quick.toml", "nominal.bdf", "params.toml")


def run_demo(out_dir, quick: bool = False, *, progress=None, **kw):
    """Copy the demo project into ``OUT/project`` and run it into ``OUT``; returns the :class:`RunResult`.

    A rerun into the same folder skips what is up to date.  ``kw`` go to :func:`modalab.app.run.run_project`.
    """

    out = Path(out_dir)
    proj = out / "project"
    proj.mkdir(parents=True, exist_ok=True)
    for name in DEMO_FILES:
        src = demo_project_dir() / name
        dst = proj / name
        if not dst.is_file() or dst.read_bytes() != src.read_bytes():
            write_bytes(dst, src.read_bytes())
    return run_project(proj / ("project_quick.toml" if quick else "project.toml"), out, progress=progress, **kw)
