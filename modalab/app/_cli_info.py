"""``modalab info``: what a universal file holds (datasets, DOFs, units, frequency range, modes)."""
from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

from identification.api import ROVING_RATIO, roving_hammer_layout
from modalab.app._cli_console import _print
from modalab.app.stages._common import sniff_kind
from modalab.core import uff
from modalab.core.errors import PlanError


def _join(items, limit: int = 16) -> str:
    items = [str(x) for x in items]
    more = f" ... ({len(items)} in all)" if len(items) > limit else ""
    return ", ".join(items[:limit]) + more if items else "none"


def _g(v) -> str:
    return "-" if v is None else f"{v:g}"


def _value(v) -> str:
    """A metadata value as text (no Python reprs: no None, no brackets or quotes)."""
    if v is None:
        return "none"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, (list, tuple)):
        return _join([_value(x) for x in v], 8)
    if isinstance(v, dict):
        return "(" + ", ".join(f"{k} {_value(x)}" for k, x in v.items()) + ")"
    return str(v)


def info_table(info: dict) -> list[str]:
    """The lines ``modalab info`` prints for a :func:`modalab.core.uff.info` dict."""
    rows = [("file", info["path"]),
            ("datasets", ", ".join(f"{k} x{v}" for k, v in info["datasets"].items())),
            ("functions", ", ".join(f"{k} x{v}" for k, v in info["functions"].items()))]
    if not info["functions"]:
        rows.pop()
    f = info.get("frf")
    if f:
        rows += [("FRFs", f"{len(f['responses'])} responses x {len(f['references'])} references, {f['quantity']} "
                          f"[{f['units']}], {'with' if f['coherence'] else 'without'} coherence"),
                 ("responses", _join(f["responses"])),
                 ("references", _join(f["references"]) + (
                     f"  (at least {ROVING_RATIO} x more references than responses: a roving-hammer export; "
                     "identify transposes it by reciprocity so that the accelerometers are the references)"
                     if roving_hammer_layout(SimpleNamespace(n_in=len(f["references"]), n_out=len(f["responses"])))
                     else "")),
                 ("frequency", f"{_g(f['freq_range_hz'][0])} - {_g(f['freq_range_hz'][1])} Hz, {f['lines']} lines"
                               + (f", df {_g(f['df_hz'])} Hz" if f["df_hz"] else " (uneven)"))]
        meta = f.get("metadata") or {}
        if meta:
            rows.append(("processing", ", ".join(f"{k.replace('_', ' ')} {_value(v)}" for k, v in meta.items())))
    h = info.get("hits")
    if h:
        rows += [("hits", f"{h['hits']} hits, {_join(h['channels_per_hit'])} channels each"),
                 ("hammer points", _join(f"{d} ({n} hit{'s' if n != 1 else ''})"
                                         for d, n in h["hits_per_point"].items())),
                 ("responses", _join(h["responses"])),
                 ("sampling", f"{_join(_g(v) for v in h['sample_rate_hz'])} Hz, {_join(h['samples'])} samples, "
                              f"{_g(h['time_range_s'][0])} to {_g(h['time_range_s'][1])} s"),
                 ("units", ", ".join(f"{k}: {_join(v)}" for k, v in h["units"].items()))]
    if info.get("other_functions"):
        rows.append(("other functions", _join(info["other_functions"])))
    if "nodes" in info:
        rows.append(("geometry", f"{info['nodes']} nodes"))
    if info.get("coordinate_systems"):
        rows.append(("frames", ", ".join(f"{k}: {v}" for k, v in info["coordinate_systems"].items())
                     + " (dataset 2420; modes and FRF triads measured in rotated frames are read in the global "
                       "frame, raw time records in them are refused)"))
    u = info.get("units")
    if u:
        rows.append(("unit system", f"{u['description'] or 'code ' + str(u['code'])}: length x{_g(u['length'])}, "
                                    f"force x{_g(u['force'])} (dataset 164)"))
    w = max(len(k) for k, _ in rows)
    lines = [f"{k:<{w}}  {v}" for k, v in rows]
    m = info.get("modes")
    if m:
        lines.append(f"{'modes':<{w}}  {m['n_modes']} modes "
                     + (f"on {m['dofs']} DOFs, scaling {m['scaling']}" if m["dofs"] else
                        "(frequencies and damping only, no shapes)"))
        cplx = any(r["complex"] for r in m["table"])
        if cplx:
            lines.append(f"{'':<{w}}  f_n: undamped natural frequency |lambda|/2pi; f_d: damped, Im(lambda)/2pi")
            stated = any("header_hz" in r for r in m["table"])
            lines.append(f"{'':<{w}}  {'mode':>4} {'f_n [Hz]':>11} {'f_d [Hz]':>11} {'zeta [%]':>9}"
                         + ("  the file's header" if stated else ""))
        else:
            lines.append(f"{'':<{w}}  {'mode':>4} {'f [Hz]':>11} {'zeta [%]':>9}")
        for r in m["table"]:
            if cplx:
                fd = r.get("freq_damped_hz", r["freq_hz"])
                hdr = (f"states {r['header_hz']:g} Hz ({r['header_states']})" if "header_hz" in r else "")
                lines.append(f"{'':<{w}}  {r['mode']:>4} {r['freq_hz']:>11.4f} {fd:>11.4f} "
                             f"{100 * r['damping']:>9.3f}  {hdr}".rstrip())
            else:
                lines.append(f"{'':<{w}}  {r['mode']:>4} {r['freq_hz']:>11.4f} {100 * r['damping']:>9.3f}")
    return lines


def cmd_info(a):

    kind = sniff_kind(a.file) if Path(a.file).is_file() else None
    if kind in ("bulk", "toml", "json"):
        what = {"bulk": "Nastran bulk data (an FE model): correlate, update, diagnose and sim --structure read it, "
                        f"e.g. modalab correlate {a.file} modes.uff",
                "toml": "a TOML file (a plan, project or parameter file): acquire, run and --params read it",
                "json": "a JSON file (e.g. modes.json: correlate and update read it)"}[kind]
        raise PlanError(f"{a.file} is {what}; info reads universal files (UFF: raw hits, FRFs, modes)")
    info = uff.info(a.file, quantity=getattr(a, "quantity", None))
    if a.json:
        _print(json.dumps(info, indent=1, default=str))
    else:
        for line in info_table(info):
            _print(line)
    return 0


def register(sub):
    s = sub.add_parser("info", help="what a UFF file holds: datasets, DOFs, units, frequency range")
    s.add_argument("file", help="a universal file (.uff/.unv)")
    s.add_argument("--json", action="store_true", help="print JSON")
    s.set_defaults(func=cmd_info)
