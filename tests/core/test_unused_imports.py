"""No module-level import that the module never uses (issue 15: modalab/app/pipeline.py kept numpy, Path and two
private names nobody imported from it).

A package's ``__init__.py`` re-exports by design and is not checked; elsewhere a name imported for others to
import from the module is listed in ``__all__`` or its import line says ``noqa``.
"""
import ast
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[2]
PACKAGES = ("modalab", "acquisition", "identification", "updating", "hardware_sim")


def unused_imports(text: str) -> list:
    """``(line, name)`` of each module-level import whose name the module never reads."""
    tree = ast.parse(text)
    lines = text.splitlines()
    exported = set()
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets):
            exported |= set(ast.literal_eval(node.value))
    used = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
    out = []
    for node in tree.body:
        if not isinstance(node, (ast.Import, ast.ImportFrom)) or getattr(node, "module", None) == "__future__":
            continue
        if any("noqa" in lines[i - 1] for i in range(node.lineno, node.end_lineno + 1)):
            continue
        for alias in node.names:
            name = (alias.asname or alias.name).split(".")[0]
            if name not in used and name not in exported:
                out.append((node.lineno, name))
    return out


def test_no_unused_module_level_imports():
    found = [f"{p.relative_to(ROOT)}:{ln}: {name}" for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))
             if p.name != "__init__.py" for ln, name in unused_imports(p.read_text(encoding="utf-8"))]
    assert found == [], found


def test_the_check_sees_an_unused_import():
    text = "import numpy as np\nfrom pathlib import Path\nimport os  # noqa: F401\n__all__ = ['Path']\n"
    assert unused_imports(text) == [(1, "np")]
    assert unused_imports("import numpy as np\nx = np.pi\n") == []
