"""The by-task package docstrings (issue 15, "updating gets a face"): every name they point to exists."""
import importlib
import re

import pytest


def unresolved(doc: str, package: str = "") -> list:
    """The Sphinx references (``:func:``, ``:class:``, ``:mod:``, ``:data:``) in ``doc`` that do not import; a bare
    name or one starting with a dot is looked up in ``package``."""
    bad = []
    for ref in re.findall(r":(?:func|class|mod|data|meth):`~?([\w.]+)`", doc):
        rel = ref.startswith(".") or "." not in ref          # relative to the package, as Sphinx reads it there
        parts = (package.split(".") if rel and package else []) + ref.lstrip(".").split(".")
        obj, i = None, len(parts)
        while i > 0:
            try:
                obj = importlib.import_module(".".join(parts[:i]))
                break
            except ImportError:
                i -= 1
        try:
            for a in parts[i:]:
                obj = getattr(obj, a)
        except AttributeError:
            bad.append(ref)
        if obj is None:
            bad.append(ref)
    return bad


@pytest.mark.parametrize("name", ["updating", "updating.methods", "updating.correlation"])
def test_the_by_task_docstring_names_only_what_exists(name):
    doc = importlib.import_module(name).__doc__
    assert "By task" in doc or "by task" in doc
    assert unresolved(doc, name) == []


def test_updating_docstring_covers_each_subpackage_and_task():
    import updating
    for sub in ("updating.fe", "updating.correlation", "updating.methods", "updating.diagnosis"):
        assert f":mod:`{sub}`" in updating.__doc__
    for cls in ("InverseEigensensitivity", "MCIUpdater", "ResponseFunctionMethod", "diagnose"):
        assert cls in updating.__doc__


def test_the_check_sees_a_wrong_name():
    assert unresolved(":func:`~updating.methods.mci` :class:`updating.methods.NoSuchUpdater`") == [
        "updating.methods.NoSuchUpdater"]
    assert unresolved(":func:`mci` :func:`nothing`", "updating.methods") == ["nothing"]
