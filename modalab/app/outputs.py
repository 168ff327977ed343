"""Where the application writes its text and JSON files, and the schemas of its JSON products.

Every text or JSON file the stages (:mod:`modalab.app.stages`), ``modalab run`` and the report write goes through
:func:`write_text` / :func:`write_json`, which use the one atomic writer of :mod:`modalab.core._output`: the file is
written next to its destination under a temporary name and moved into place with ``os.replace`` (a reader
never sees half a file; an interrupted write leaves the old file), with the permissions the user's umask
gives a new file, and never over an input of the command.

The four JSON products other programs read have a JSON schema shipped with the package
(``modalab/app/schemas/*.schema.json``; :func:`schema` loads one):

* ``modes.json`` — identified modes, written only by :meth:`modalab.core.modes.ModeSet.to_json`: a
  :meth:`~modalab.core.modes.ModeSet.to_dict` (so :meth:`ModeSet.from_json <modalab.core.modes.ModeSet.from_json>`
  reads it back) plus ``input`` (the FRF file) and ``table`` (:meth:`~modalab.core.modes.ModeSet.table`: one row per
  mode, ``mode``, ``freq_hz``, ``damping_pct`` and the indicators);
* ``diagnosis.json`` — :meth:`updating.diagnosis.Diagnosis.to_dict` (findings, parameters, fit, statement,
  ranking, timings);
* ``summary.json`` — the numbers of a ``modalab run`` report;
* a session folder's ``summary.json`` (``'session_summary'``) — what an acquisition session did at each point,
  written only by :meth:`acquisition.session.AcquisitionSession.run` (a
  :meth:`~acquisition.session_summary.SessionSummary.to_dict`; through the same atomic writer) at the end of each
  run of the session that ends: complete, stopped by the operator or a lost device, resumed.

The tests check every writer's output against these schemas (``jsonschema``, a test dependency).
"""
from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

from modalab.core._output import write_bytes, write_json, write_text  # the one atomic writer (umask, never over an input)

__all__ = ["write_text", "write_bytes", "write_json", "schema", "validate", "SCHEMAS"]

#: the JSON products with a schema: name -> schema file in ``modalab/app/schemas``
SCHEMAS = {"modes": "modes.schema.json", "diagnosis": "diagnosis.schema.json", "summary": "summary.schema.json",
           "session_summary": "session_summary.schema.json"}


def schema(name: str) -> dict:
    """The JSON schema of a product: ``'modes'``, ``'diagnosis'``, ``'summary'`` or ``'session_summary'``."""
    if name not in SCHEMAS:
        raise KeyError(f"no schema {name!r}; expected one of {sorted(SCHEMAS)}")
    return json.loads(resources.files("modalab.app").joinpath("schemas", SCHEMAS[name]).read_text())


def validate(doc, name: str) -> None:
    """Check a JSON document (or a path to one) against the schema ``name``; raises
    ``jsonschema.ValidationError`` naming the first violation.  Needs ``jsonschema`` (the test extra)."""
    import jsonschema  # lazy: optional jsonschema (test extra)
    from referencing import Registry, Resource  # lazy: optional, comes with jsonschema

    if isinstance(doc, (str, Path)):
        doc = json.loads(Path(doc).read_text())
    # each schema's $id is its file name and its $refs name sibling files: the registry holds them by file name
    # (a validator reading the folder from disk resolves the same references)
    registry = Registry().with_resources((SCHEMAS[n], Resource.from_contents(schema(n))) for n in SCHEMAS)
    jsonschema.Draft202012Validator(schema(name), registry=registry).validate(doc)
