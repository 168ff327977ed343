"""Imports sit at module top in every package (issue 15): an import inside a function is allowed only
for an optional dependency (or one imported under ``try: ... except ImportError``), and for matplotlib, which every
figure function imports when it draws so that the command line and the library start without it.  Each import left
inside a function says why in a trailing ``# lazy: <reason>`` comment."""
import ast
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[2]
#: where the rule is checked: every package
CHECKED = ("modalab", "acquisition", "identification", "updating", "hardware_sim")
#: optional extras and test/benchmark dependencies (pyproject.toml), matplotlib (see the module docstring) and rich
#: (the command line's console, loaded when it draws); tomllib is standard library (requires-python >= 3.11) and is
#: imported at module top like the rest
LAZY = {"nidaqmx", "pyNastran", "dask", "distributed", "sdypy", "sksparse", "jsonschema", "referencing", "rich",
        "matplotlib"}
#: project imports inside a function, each with its reason (none today)
ALLOWED: dict = {}


def function_imports(path: pathlib.Path) -> list:
    """``(line, module)`` of every import inside a function of ``path`` that is not of a :data:`LAZY` module
    and not under ``try: ... except ImportError``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = []

    def visit(node, in_func):
        for ch in ast.iter_child_nodes(node):
            if isinstance(ch, (ast.Import, ast.ImportFrom)):
                mod = ch.module if isinstance(ch, ast.ImportFrom) else ch.names[0].name
                if in_func and (getattr(ch, "level", 0) or (mod or "").split(".")[0] not in LAZY):
                    out.append((ch.lineno, "." * getattr(ch, "level", 0) + (mod or "")))
            elif isinstance(ch, ast.Try) and any(h.type is not None and "ImportError" in ast.unparse(h.type)
                                                 for h in ch.handlers):
                continue
            else:
                visit(ch, in_func or isinstance(ch, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)))

    visit(tree, False)
    return out


def test_no_import_inside_a_function():
    found = []
    for pkg in CHECKED:
        for p in sorted((ROOT / pkg).rglob("*.py")):
            rel = p.relative_to(ROOT).as_posix()
            found += [f"{rel}:{ln} {mod}" for ln, mod in function_imports(p) if mod not in ALLOWED.get(rel, ())]
    assert found == [], "imports inside functions (move them to the module top): " + "; ".join(found)


def unexplained(path: pathlib.Path) -> list:
    """Line numbers of the imports inside functions of ``path`` (whatever the module) without a ``# lazy:``
    comment on one of their lines."""
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines()
    out = []

    def visit(node, in_func):
        for ch in ast.iter_child_nodes(node):
            if isinstance(ch, (ast.Import, ast.ImportFrom)):
                if in_func and not any("# lazy:" in s for s in lines[ch.lineno - 1:ch.end_lineno]):
                    out.append(ch.lineno)
            else:
                visit(ch, in_func or isinstance(ch, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)))

    visit(ast.parse(text), False)
    return out


def test_every_import_inside_a_function_says_why():
    found = [f"{p.relative_to(ROOT).as_posix()}:{ln}" for pkg in CHECKED for p in sorted((ROOT / pkg).rglob("*.py"))
             for ln in unexplained(p)]
    assert found == [], "imports inside functions without a '# lazy: <reason>' comment: " + "; ".join(found)


def test_the_check_sees_an_import_in_a_function(tmp_path):
    p = tmp_path / "m.py"
    p.write_text("import os\n\ndef f():\n    import json\n    try:\n        import sksparse\n"
                 "    except ImportError:\n        pass\n    import matplotlib.pyplot as plt\n    return json\n")
    assert function_imports(p) == [(4, "json")]
    assert unexplained(p) == [4, 6, 9]
    p.write_text("def f():\n    import sksparse  # lazy: optional\n    from rich import (  # lazy: drawing\n"
                 "        print)\n    import json\n")
    assert unexplained(p) == [5]


def late_imports(text: str) -> list:
    """Line numbers of module-level imports placed after the module's first function or class (an import moved
    down to dodge a loop: modalab/app/report.py imported the report stage last, 'the stages import the figure
    helpers above')."""
    first, out = None, []
    for node in ast.parse(text).body:
        if first is None and isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            first = node.lineno
        elif first is not None:
            out += [n.lineno for n in ast.walk(node) if isinstance(n, (ast.Import, ast.ImportFrom))
                    and not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))]
    return out


def test_module_imports_come_before_the_code():
    found = [f"{p.relative_to(ROOT).as_posix()}:{ln}" for pkg in CHECKED for p in sorted((ROOT / pkg).rglob("*.py"))
             for ln in late_imports(p.read_text(encoding="utf-8"))]
    assert found == [], "module-level imports after the first def/class (move them to the top): " + "; ".join(found)


def test_the_check_sees_a_late_import():
    assert late_imports("import os\n\ndef f():\n    import json\n\nfrom x import y  # noqa: E402\n") == [6]
