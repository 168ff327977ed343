"""Issue 15, one function per stage: ``modalab run``, campaigns and the CLI verbs call the stage functions of
:mod:`modalab.app.stages` and never the engines those wrap (an acquisition session, FRF estimation,
identification, correlation, an updater, the diagnosis).  Before, ``run.stage_acquire`` built and ran its own
:class:`acquisition.session.AcquisitionSession` for a project's ``[test] truth`` bench."""
import ast
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[2]
APP = ROOT / "modalab" / "app"
ENGINE_PACKAGES = ("acquisition", "identification", "updating", "hardware_sim")
#: what each stage wraps: to be called through modalab.app.stages only
ENGINES = {"AcquisitionSession", "estimate_frf", "estimate_frf_roving", "identify", "PolyMAX", "correlate",
           "InverseEigensensitivity", "MCIUpdater", "ResponseFunctionMethod", "EigendynamicConstraint",
           "Diagnoser", "diagnose", "diagnose_modes", "lab_from_sim"}


def engine_imports(text: str) -> list:
    """``(line, module, name)`` of each import of a stage engine from the stage packages."""
    out = []
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] in ENGINE_PACKAGES:
            if node.module.startswith("updating.methods"):
                out.extend((node.lineno, node.module, a.name) for a in node.names)
            else:
                out.extend((node.lineno, node.module, a.name) for a in node.names if a.name in ENGINES)
        elif isinstance(node, ast.Import):
            out.extend((node.lineno, a.name, "*") for a in node.names
                       if a.name.split(".")[0] in ENGINE_PACKAGES)
    return out


def test_entry_points_call_the_stages_not_the_engines():
    found = [f"{p.relative_to(ROOT)}:{ln}: {mod}.{name}" for p in sorted(APP.glob("*.py"))
             for ln, mod, name in engine_imports(p.read_text(encoding="utf-8"))]
    assert found == [], found


def test_run_and_campaigns_call_each_stage_function():
    calls = {}
    for name in ("run.py", "campaign.py"):
        tree = ast.parse((APP / name).read_text(encoding="utf-8"))
        calls[name] = {n.func.attr for n in ast.walk(tree) if isinstance(n, ast.Call)
                       and isinstance(n.func, ast.Attribute) and isinstance(n.func.value, ast.Name)
                       and n.func.value.id == "stages"}
    assert {"acquire", "frf", "identify", "correlate", "update", "diagnose", "report"} <= calls["run.py"]
    assert {"identify", "diagnose"} <= calls["campaign.py"]


def test_the_check_sees_an_engine_import():
    text = ("from acquisition.session import AcquisitionSession\nfrom acquisition.plan import load_plan\n"
            "from updating.methods.rfm import rfm_system\n")
    assert engine_imports(text) == [(1, "acquisition.session", "AcquisitionSession"),
                                    (3, "updating.methods.rfm", "rfm_system")]
