"""The JSON schemas ship with the package and each is checkable on its own: valid draft 2020-12, every $ref a
sibling file by relative name that resolves from the folder alone (issue 14)."""
import json
import tomllib
from pathlib import Path

import pytest

jsonschema = pytest.importorskip("jsonschema")
from referencing import Registry, Resource  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SCHEMA_DIR = ROOT / "modalab" / "app" / "schemas"
FILES = sorted(SCHEMA_DIR.glob("*.schema.json"))


def _from_disk(uri: str) -> Resource:
    """What a validator pointed at the folder does: read the referenced file next to the referencing one."""
    return Resource.from_contents(json.loads((SCHEMA_DIR / uri).read_text()))


def _refs(node):
    if isinstance(node, dict):
        if "$ref" in node:
            yield node["$ref"]
        for v in node.values():
            yield from _refs(v)
    elif isinstance(node, list):
        for v in node:
            yield from _refs(v)


@pytest.mark.parametrize("path", FILES, ids=[p.name for p in FILES])
def test_each_schema_is_valid_and_its_refs_resolve_from_the_folder(path):
    doc = json.loads(path.read_text())
    jsonschema.Draft202012Validator.check_schema(doc)
    assert doc["$id"] == path.name                               # its own name: relative refs resolve beside it
    resolver = Registry(retrieve=_from_disk).resolver(base_uri=doc["$id"])
    for ref in _refs(doc):
        assert resolver.lookup(ref).contents is not None, ref


def test_summary_validates_with_only_the_folder(tmp_path):
    summary = json.loads((SCHEMA_DIR / "summary.schema.json").read_text())
    v = jsonschema.Draft202012Validator(summary, registry=Registry(retrieve=_from_disk))
    good = {"title": "t", "frf": None, "reciprocity": {}, "modes": [{"mode": 1, "freq_hz": 5.0, "damping_pct": 1.0}],
            "identification": {}, "correlation_before": None, "update": None, "diagnosis": None, "stages": {},
            "backend": "sim", "simulated": True, "model_to_use": {"file": "update/updated.bdf", "why": "w"}}
    v.validate(good)
    bad = dict(good, modes=[{"mode": 0, "freq_hz": 5.0, "damping_pct": 1.0}])      # through modes.schema.json
    with pytest.raises(jsonschema.ValidationError):
        v.validate(bad)
    bad = dict(good, diagnosis={"findings": []})                                    # through diagnosis.schema.json
    with pytest.raises(jsonschema.ValidationError):
        v.validate(bad)


def test_package_data_patterns_match_the_shipped_files():
    """pyproject's package-data names the schemas and the demo project relative to the package that holds them
    (a pattern under the wrong package matches nothing and a non-editable install lacks the files)."""
    pd = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    matched = set()
    for pkg, patterns in pd.items():
        if pkg == "*":
            continue
        d = ROOT.joinpath(*pkg.split("."))
        assert (d / "__init__.py").is_file(), f"package-data key {pkg!r} is not a package"
        for pat in patterns:
            hits = list(d.glob(pat))
            assert hits, f"{pkg}: {pat} matches nothing"
            matched |= {p.resolve() for p in hits}
    for p in FILES + sorted((ROOT / "modalab" / "app" / "demo_data" / "demo_project").iterdir()):
        assert p.resolve() in matched, p
