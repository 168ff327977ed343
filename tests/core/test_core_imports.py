"""The core imports its own modules at module top: no function hides an import loop (e.g. FRF ↔ UFF)."""
import ast
import pathlib
import subprocess
import sys

import modalab.core

CORE = pathlib.Path(modalab.core.__file__).parent


def _function_imports(path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = []
    for fn in ast.walk(tree):
        if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for node in ast.walk(fn):
                if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").startswith("modalab")):
                    out.append((path.name, fn.name, node.module))
                elif isinstance(node, ast.Import) and any(a.name.startswith("modalab") for a in node.names):
                    out.append((path.name, fn.name, node.names[0].name))
    return out


def test_no_project_import_inside_a_core_function():
    found = [hit for p in sorted(CORE.glob("*.py")) for hit in _function_imports(p)]
    assert found == []


def test_containers_do_not_import_the_file_format():
    """FRF and ModeSet know nothing of UFF; the UFF modules attach from_uff/to_uff to them."""
    for name in ("frf.py", "modes.py"):
        tree = ast.parse((CORE / name).read_text(encoding="utf-8"))
        mods = [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
        assert not [m for m in mods if "uff" in m], name


def test_from_uff_is_there_whichever_module_is_imported_first():
    code = ("from modalab.core.frf import FRF; from modalab.core.modes import ModeSet; "
            "assert callable(FRF.from_uff) and callable(ModeSet.from_uff); "
            "assert callable(FRF.to_uff) and callable(ModeSet.to_uff)")
    subprocess.run([sys.executable, "-c", code], check=True)
