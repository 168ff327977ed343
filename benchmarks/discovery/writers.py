"""What the diagnosis receives, written as a Nastran user and a test lab would write it.

* ``nominal.bdf``: a SOL 103 input file typed card by card in small-field format (GRID, MAT1, PBARL/PBEAML
  TUBE or BOX, CBAR/CBEAM with an orientation vector, SPC1 123456, CELAS2 or CELAS1/PELAS mounts, CONM2, EIGRL, TABDMP1 with
  SDAMPING in case control) by this module's own text writer (not the project's bulk writer).
* ``measured.uff``: geometry (2411) and, per (response, reference), an H1 accelerance (58, func 4,
  m/s^2/N) followed by its coherence (58, func 6), written with pyuff in mode='add' to a new file, ASCII or
  binary 58b.
* ``params.toml``: the updating parameters a user declares (E and density of each property, by name).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .truthsim import box, tube

__all__ = ["nas8", "write_bdf", "write_uff", "write_params", "write_truth"]


def nas8(x) -> str:
    """A real number in at most 8 characters, Nastran style (1.5+11, -.0125, 7850.)."""
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    x = float(x)
    if x == 0.0:
        return "0."
    for p in range(7, 0, -1):
        s = f"{x:.{p}g}"
        if "e" in s:
            m, e = s.split("e")
            if "." not in m:
                m += "."
            s = f"{m}{'+' if int(e) >= 0 else '-'}{abs(int(e))}"
        elif "." not in s:
            s += "."
        if s.startswith("0."):
            s = s[1:]
        elif s.startswith("-0."):
            s = "-" + s[2:]
        if len(s) <= 8:
            return s
    raise ValueError(f"{x} does not fit 8 characters")


def _card(name, fields):
    """Small-field card: 8 fields per line, continuation lines start with '+'."""
    out = []
    vals = ["" if v is None else (v if isinstance(v, str) else nas8(v)) for v in fields]
    first, rest = vals[:8], vals[8:]
    out.append(f"{name:<8}" + "".join(f"{v:>8}" for v in first))
    while rest:
        chunk, rest = rest[:8], rest[8:]
        out.append(f"{'+':<8}" + "".join(f"{v:>8}" for v in chunk))
    return [line.rstrip() for line in out]


def write_bdf(case, path) -> None:
    fr = case.frame
    mat = fr.material
    L = [f"$ {case.name}: {fr.description}",
         "$ nominal model (SI units: m, kg, s, N); hand-written SOL 103 deck",
         "SOL 103", "CEND", f"TITLE = {case.name}", "ECHO = NONE", "SUBCASE 1"]
    if fr.clamps:
        L.append("  SPC = 1")
    L.append("  METHOD = 10")
    if case.nominal_damping == "TABDMP1":
        L.append("  SDAMPING = 20")
    L += ["  DISPLACEMENT(PLOT) = ALL", "BEGIN BULK", "PARAM,POST,-1", "PARAM,COUPMASS,1"]
    L += _card("EIGRL", [10, None, float(round(1.5 * case.band_hz[1])), None])
    if case.nominal_damping == "TABDMP1":
        L += _card("TABDMP1", [20, "CRIT", None, None, None, None, None, None, 0.0, 0.005, 2000.0, 0.005, "ENDT"])
    L.append("$ grids")
    for nid in sorted(fr.nodes):
        x, y, z = fr.nodes[nid]
        L += _card("GRID", [nid, None, float(x), float(y), float(z)])
    L.append(f"$ {mat['name']}")
    L += _card("MAT1", [1, mat["E"], None, mat["nu"], mat["rho"]])
    pids = {}
    for i, (name, s) in enumerate(sorted(fr.sections.items()), start=1):
        pids[name] = i
        L.append(f"$ name: {name}")
        if case.element_card == "CBEAM":                      # the section library: PBEAML TUBE / BOX
            if s["kind"] == "TUBE":
                dims = list(s["dims"])                        # DIM1 = outer radius, DIM2 = inner radius
            else:
                b, h, t = s["dims"]                           # b along element y (DIM2), h along z (DIM1)
                dims = [h, b, t, t]
            L += _card("PBEAML", [i, 1, None, s["kind"], None, None, None, None, *dims])
        else:                                                 # hand-computed PBAR with shear factors K1 K2
            c = tube(*s["dims"]) if s["kind"] == "TUBE" else box(*s["dims"])
            L.append(f"$ {s['kind'].lower()} {' x '.join(f'{1000 * v:g}' for v in s['dims'])} mm")
            L += _card("PBAR", [i, 1, c.A, c.Iz, c.Iy, c.J, None, None, *([None] * 8), c.ky, c.kz])
    L.append("$ members")
    for eid, a, b, mi in fr.elements():
        mem = fr.members[mi]
        v = mem["vref"]
        L += _card(case.element_card, [eid, pids[mem["section"]], a, b, float(v[0]), float(v[1]), float(v[2])])
    eid = 10000
    if fr.mounts:
        L.append("$ elastomer mounts to ground")
        if (case.seed // 16) % 2:              # CELAS1 + PELAS (one property per stiffness) in half the decks
            pel = {}
            for n, c, k, ge in fr.mounts:
                pel.setdefault((k, ge), 100 + len(pel) + 1)
            for (k, ge), pid in pel.items():
                L.append(f"$ name: mount_{pid - 100}")
                L += _card("PELAS", [pid, k, ge])
            for n, c, k, ge in fr.mounts:
                eid += 1
                L += _card("CELAS1", [eid, pel[(k, ge)], n, c])
        else:
            for n, c, k, ge in fr.mounts:
                eid += 1
                L += _card("CELAS2", [eid, k, n, c, None, None, ge])
    if fr.masses:
        L.append("$ lumped masses")
        for n, m in fr.masses:
            eid += 1
            L += _card("CONM2", [eid, n, 0, m])
    if fr.clamps:
        L.append("$ clamps")
        L += _card("SPC1", [1, "123456", *fr.clamps])
    L.append("ENDDATA")
    Path(path).write_text("\n".join(L) + "\n")


def write_params(case, path) -> None:
    out = ["# updating parameters of the nominal model (E and density of every property, as factors)"]
    for name in sorted(case.frame.sections):
        for field, q in (("E", "E"), ("rho", "rho")):
            out += ["[[parameter]]", f'name = "{q}_{name}"', f'field = "{field}"', f'properties = ["{name}"]',
                    'mode = "factor"', ""]
    Path(path).write_text("\n".join(out))


def write_uff(case, freq_hz, H, coh, path) -> None:
    """H, coh: (n_hits, n_sensors, n_lines), rows = hit DOFs (responses by reciprocity), columns = sensors."""
    import pyuff

    path = Path(path)
    if path.exists():
        path.unlink()
    uff = pyuff.UFF(str(path))
    nodes = sorted({n for n, _ in case.hits} | {n for n, _ in case.sensors})
    xyz = np.array([case.frame.nodes[n] for n in nodes])
    uff.write_sets(pyuff.prepare_2411(node_nums=np.array(nodes), def_cs=np.zeros(len(nodes), int),
                                      disp_cs=np.zeros(len(nodes), int), color=np.ones(len(nodes), int),
                                      x=xyz[:, 0], y=xyz[:, 1], z=xyz[:, 2]), mode="add")
    b = 1 if case.binary else 0
    df = float(freq_hz[1] - freq_hz[0])
    date = "25-NOV-26 10:00:00"
    sets = []
    for i, (hn, hd) in enumerate(case.hits):
        for j, (sn, sd) in enumerate(case.sensors):
            common = dict(binary=b, id2=f"{case.name}", id3=date, id4="roving hammer, H1, 5 averages",
                          id5="reciprocal: response = hit point", rsp_ent_name="pt", rsp_node=hn, rsp_dir=hd,
                          ref_ent_name="acc", ref_node=sn, ref_dir=sd, num_pts=len(freq_hz), abscissa_spacing=1,
                          abscissa_min=float(freq_hz[0]), abscissa_inc=df, abscissa_spec_data_type=18,
                          abscissa_axis_units_lab="Hz", x=np.asarray(freq_hz, float), load_case_id=0)
            sets.append(pyuff.prepare_58(id1="FRF", func_type=4, ver_num=0, ord_data_type=6,
                                         ordinate_spec_data_type=12, ordinate_axis_units_lab="m/s^2",
                                         orddenom_spec_data_type=13, orddenom_axis_units_lab="N",
                                         data=np.asarray(H[i, j], complex), **common))
            sets.append(pyuff.prepare_58(id1="Coherence", func_type=6, ver_num=0, ord_data_type=4,
                                         ordinate_spec_data_type=0, ordinate_axis_units_lab="NONE",
                                         orddenom_spec_data_type=0, orddenom_axis_units_lab="NONE",
                                         data=np.asarray(coh[i, j], float), **common))
    uff.write_sets(sets, mode="add")


def write_truth(case, path, extra: dict) -> None:
    fr = case.frame
    ph = None
    if case.physics is not None:
        ph = {k: v for k, v in case.physics.items()}
    doc = {"case": case.name, "seed": case.seed, "split": "tuning" if case.seed % 2 == 0 else "held_out",
           "topology": fr.topology, "structure": fr.description, "material": fr.material,
           "control": case.physics is None, "concealed": [] if ph is None else [ph],
           "environment": [{"physics": "ground_spring", "nodes": [n], "what": "suspension cord",
                            "k_vertical": kv, "k_horizontal": kh} for n, kv, kh in fr.cords],
           "background_errors": case.errors, "truth_loss_factor_per_section": case.eta,
           "truth_mesh": f"{case.refine}x finer than the nominal (Timoshenko 3-D, interior grids from 1001)",
           "nominal": {"element": case.element_card, "damping": case.nominal_damping,
                       "edges": [[a, b] for a, b in fr.edges()],
                       "elements": {str(e): [a, b] for e, a, b, _ in fr.elements()}},
           "measurement": {"band_hz": list(case.band_hz), "n_lines": case.n_lines,
                           "hits": [f"{n}{'+' if d > 0 else '-'}{'XYZ'[abs(d) - 1]}" for n, d in case.hits],
                           "sensors": [f"{n}{'+' if d > 0 else '-'}{'XYZ'[abs(d) - 1]}" for n, d in case.sensors],
                           "noise_fraction_of_rms": case.noise, "averages": case.n_avg,
                           "format": "58b binary" if case.binary else "58 ascii"},
           **case.info, **extra}
    Path(path).write_text(json.dumps(doc, indent=1, sort_keys=False, default=_plain) + "\n")


def _plain(o):
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.floating):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))
