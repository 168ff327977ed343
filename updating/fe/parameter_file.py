"""The one reader of updating-parameter files (``--params``, ``[update] params`` of a project).

Format (TOML)::

    [[parameter]]
    name = "E_wing"
    field = "E"                    # E, G, nu, rho, ge, b, h, do, di, A, Iy, Iz, J, nsm, k, c, mass, ...
    properties = ["wing"]          # property names or ids (or materials = [...], elements = [...], groups = [...])
    mode = "factor"                # factor (p multiplies the nominal; default) or value (p is the SI value)
    lower = 0.5                    # optional bounds, in the units of p
    upper = 2.0
    prior = 0.05                   # diagnosis: prior relative standard deviation, or "free" (default: E, G
                                   # ±5 %, density ±3 %, sections ±5 %, damping free)

A misspelt key is an error naming the file, the parameter, the key and the closest valid key.
"""
from __future__ import annotations

import difflib
import tomllib
from pathlib import Path

from modalab.core.errors import PlanError
from updating.fe import Parameter

__all__ = ["PARAMETER_KEYS", "read_parameter_file", "read_priors"]

PARAMETER_KEYS = ("name", "field", "mode", "properties", "materials", "groups", "elements", "lower", "upper",
                  "prior")
_TOP_KEYS = ("parameter",)


def _suggest(key: str, valid) -> str:
    close = difflib.get_close_matches(key, list(valid), n=1, cutoff=0.5)
    return f"; did you mean {close[0]!r}?" if close else f"; valid keys: {', '.join(valid)}"


def read_parameter_file(path) -> tuple[list, list, list]:
    """A parameter file → (parameters, lower bounds, upper bounds); a bound is None where not given."""

    p = Path(path)
    try:
        raw = tomllib.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise PlanError(f"parameter file {str(p)!r} does not exist; give a TOML file of [[parameter]] tables") from None
    except IsADirectoryError:
        raise PlanError(f"parameter file {str(p)!r} is a directory; give a TOML file of [[parameter]] tables") from None
    except UnicodeDecodeError:
        raise PlanError(f"parameter file {str(p)!r} is not a text file; give a TOML file of [[parameter]] tables") \
            from None
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise PlanError(f"cannot read parameter file {str(p)!r}: {e}") from None
    for k in raw:
        if k not in _TOP_KEYS:
            hint = " (write [[parameter]], one table per parameter)" if k == "parameters" else _suggest(k, _TOP_KEYS)
            raise PlanError(f"{p}: unknown top-level key {k!r}{hint}")
    items = raw.get("parameter")
    if not isinstance(items, list) or not items:
        raise PlanError(f"{p}: no [[parameter]] tables; add at least one, e.g. [[parameter]] name = 'E_wing' "
                        "field = 'E' properties = ['wing']")
    params, lo, hi = [], [], []
    seen = set()
    for k, it in enumerate(items, start=1):
        label = f"parameter #{k}" + (f" ({it['name']!r})" if isinstance(it, dict) and "name" in it else "")
        if not isinstance(it, dict):
            raise PlanError(f"{p}: {label} is not a table; write [[parameter]] followed by key = value lines")
        for key in it:
            if key not in PARAMETER_KEYS:
                raise PlanError(f"{p}: {label}: unknown key {key!r}{_suggest(key, PARAMETER_KEYS)}")
        if "name" not in it or "field" not in it:
            raise PlanError(f"{p}: {label} needs name and field (got keys {sorted(it)})")
        if it["name"] in seen:
            raise PlanError(f"{p}: parameter name {it['name']!r} is used twice; names must be unique")
        seen.add(it["name"])
        kw = {s: tuple(it[s]) if isinstance(it[s], list) else (it[s],)
              for s in ("properties", "materials", "groups", "elements") if s in it}
        try:
            params.append(Parameter(str(it["name"]), str(it["field"]), mode=str(it.get("mode", "factor")), **kw))
        except Exception as e:  # noqa: BLE001 - Parameter's own message names the problem; re-raised with the file
            msg = str(e).removeprefix(f"parameter {str(it['name'])!r}: ")     # the label names it already
            raise PlanError(f"{p}: {label}: {msg}") from None
        bounds = []
        for b in ("lower", "upper"):
            v = it.get(b)
            if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float))):
                raise PlanError(f"{p}: {label}: {b} = {v!r}; expected a number")
            bounds.append(None if v is None else float(v))
        if bounds[0] is not None and bounds[1] is not None and bounds[0] > bounds[1]:
            raise PlanError(f"{p}: {label}: lower {bounds[0]} exceeds upper {bounds[1]}")
        lo.append(bounds[0])
        hi.append(bounds[1])
    return params, lo, hi


def read_priors(path) -> dict:
    """``prior`` of each ``[[parameter]]`` that gives one: a relative standard deviation (0.05 = ±5 %) or
    ``"free"``; the file is checked by :func:`read_parameter_file` first."""
    read_parameter_file(path)
    p = Path(path)
    out = {}
    for it in tomllib.loads(p.read_text()).get("parameter", []):
        if "prior" in it:
            v = it["prior"]
            if not (v == "free" or (isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0)):
                raise PlanError(f"{p}: parameter {it['name']!r}: prior = {v!r}; expected a relative standard "
                                "deviation > 0 (0.05 = ±5 %) or \"free\"")
            out[str(it["name"])] = v
    return out
