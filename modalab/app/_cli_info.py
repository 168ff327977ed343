"""``modalab info``: what a universal file holds (datasets, DOFs, units, frequency range, modes)."""
from __future__ import annotations

import json
from pathlib import Path

from modalab.app._cli_console import _print
from modalab.app.stages._common import sniff_kind
from modalab.core import uff
from modalab.core.frf import ROVING_RATIO, roving_hammer_layout
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


def _dof_rows(f: dict, h: dict, limit: int = 30) -> list[tuple[str, str]]:
    """One row per DOF of a file holding raw hits and FRFs (an acquisition session's export): where the hammer
    hit, where a response channel measured, and what the DOF is in the FRFs; each DOF once, the few fixed DOFs
    (the shorter of the hammer and response lists) first."""
    hammer, sensors = h["hits_per_point"], h["responses"]
    resp, refs = set(f["responses"]), set(f["references"])
    fixed, roving = (sensors, list(hammer)) if len(sensors) <= len(hammer) else (list(hammer), sensors)
    dofs = list(dict.fromkeys([*fixed, *roving, *f["responses"], *f["references"]]))
    w = max(len("DOF"), *(len(d) for d in dofs))
    rows = [("DOFs", f"{'DOF':<{w}}  {'hammer hits':>11}  {'response channel':<16}  in the FRFs as")]
    for d in dofs[:limit]:
        role = ", ".join(r for r, s in (("response", resp), ("reference", refs)) if d in s) or "-"
        rows.append(("", f"{d:<{w}}  {hammer.get(d, '-'):>11}  {'yes' if d in sensors else '-':<16}  {role}"))
    if len(dofs) > limit:
        rows.append(("", f"... {len(dofs) - limit} more DOFs ({len(dofs)} in all; --json lists every one)"))
    if set(hammer) == resp and set(sensors) == refs and resp != refs:
        rows.append(("", "(FRFs ordered by reciprocity: the hammer points are their responses, the response "
                         "channels their references)"))
    return rows


def _count(n: int, noun: str) -> str:
    """``1 response``, ``3 responses``."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def info_table(info: dict) -> list[str]:
    """The lines ``modalab info`` prints for a :func:`modalab.core.uff.info` dict (``session``: the line saying
    which acquisition session the file was exported by, when ``info`` was given the session)."""
    rows = [("session", info["session"])] if info.get("session") else []
    rows += [("file", info["path"]),
            ("datasets", ", ".join(f"{k} x{v}" for k, v in info["datasets"].items())),
            ("functions", ", ".join(f"{k} x{v}" for k, v in info["functions"].items()))]
    if not info["functions"]:
        rows.pop()
    f = info.get("frf")
    h = info.get("hits")
    if f:
        roving = (f"at least {ROVING_RATIO} x more references than responses: a roving-hammer export; "
                  "identify transposes it by reciprocity so that the accelerometers are the references"
                  if roving_hammer_layout(len(f["references"]), len(f["responses"]))
                  else "")
        rows.append(("FRFs", f"{_count(len(f['responses']), 'response')} x {_count(len(f['references']), 'reference')}, "
                             f"{f['quantity']} "
                             f"[{f['units']}], {'with' if f['coherence'] else 'without'} coherence"))
        if not h:
            rows += [("responses", _join(f["responses"])),
                     ("references", _join(f["references"]) + (f"  ({roving})" if roving else ""))]
        elif roving:
            rows.append(("", f"({roving})"))
        rows += [("frequency", f"{_g(f['freq_range_hz'][0])} - {_g(f['freq_range_hz'][1])} Hz, {f['lines']} lines"
                               + (f", df {_g(f['df_hz'])} Hz" if f["df_hz"] else " (uneven)"))]
        meta = f.get("metadata") or {}
        if meta:
            rows.append(("processing", ", ".join(f"{k.replace('_', ' ')} {_value(v)}" for k, v in meta.items())))
    if h:
        rows.append(("hits", f"{h['hits']} hits, {_join(h['channels_per_hit'])} channels each"))
        if not f:
            rows += [("hammer points", _join(f"{d} ({_count(n, 'hit')})"
                                             for d, n in h["hits_per_point"].items())),
                     ("responses", _join(h["responses"]))]
        rows += [("sampling", f"{_join(_g(v) for v in h['sample_rate_hz'])} Hz, {_join(h['samples'])} samples, "
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
    if f and h:
        rows += _dof_rows(f, h)
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


def _read_json(path: Path) -> dict:
    try:
        d = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise PlanError(f"{path}: cannot read it as JSON ({e})") from None
    if not isinstance(d, dict):
        raise PlanError(f"{path}: expected a JSON object, found {type(d).__name__}")
    return d


def _session(path: Path) -> tuple[Path, str] | None:
    """An acquisition session folder (``modalab acquire -o DIR``), or its ``session.json``: the session's exported
    UFF and a line saying what the session is; None when ``path`` is not a session."""
    if path.is_dir():
        folder = path
    elif path.name == "session.json" and (path.parent / "journal.jsonl").is_file():
        folder = path.parent
    else:
        return None
    if not ((folder / "session.json").is_file() or (folder / "journal.jsonl").is_file()):
        return None
    backend = (_read_json(folder / "session.json").get("backend") if (folder / "session.json").is_file()
               else None)
    state = "not ended yet (no summary.json)"
    if (folder / "summary.json").is_file():
        summ = _read_json(folder / "summary.json")
        pts = summ.get("points") or []
        done = sum(1 for q in pts if isinstance(q, dict) and q.get("done"))
        state = ("complete" if summ.get("complete") else
                 f"stopped ({summ['stopped']})" if summ.get("stopped") else "not complete")
        state += f", {done} of {len(pts)} points done"
    line = f"{folder}: {state}" + (f", backend {backend}" if backend else "")
    uff_path = folder / "session.uff"
    if not uff_path.is_file():
        raise PlanError(f"{path} is an acquisition session, {state}, with no session.uff yet (a session exports it "
                        f"when every point is done): finish it with modalab acquire PLAN --resume -o {folder}")
    return uff_path, line


def cmd_info(a):

    path, session = a.file, None
    sess = _session(Path(path))
    if sess is not None:
        path, session = str(sess[0]), sess[1]
    kind = sniff_kind(path) if Path(path).is_file() else None
    if kind in ("bulk", "toml", "json"):
        what = {"bulk": "Nastran bulk data (an FE model): correlate, update, diagnose and sim --structure read it, "
                        f"e.g. modalab correlate {path} modes.uff",
                "toml": "a TOML file (a plan, project or parameter file): acquire, run and --params read it",
                "json": "a JSON file (e.g. modes.json: correlate and update read it)"}[kind]
        raise PlanError(f"{path} is {what}; info reads universal files (UFF: raw hits, FRFs, modes) and "
                        "acquisition session folders")
    info = uff.info(path, quantity=getattr(a, "quantity", None))
    if session:
        info = {"session": session, **info}
    if a.json:
        _print(json.dumps(info, indent=1, default=str))
    else:
        for line in info_table(info):
            _print(line)
    return 0


def register(sub):
    s = sub.add_parser("info", help="what a UFF file (or an acquisition session) holds: datasets, DOFs, units, "
                                         "frequency range")
    s.add_argument("file", help="a universal file (.uff/.unv), or an acquisition session folder "
                                          "(modalab acquire -o DIR) or its session.json: its session.uff")
    s.add_argument("--json", action="store_true", help="print JSON")
    s.set_defaults(func=cmd_info)
