"""The GARTEUR case study of the thesis' section 5.3 (Tables 10 and 11) on the beam model of :mod:`.garteur`.

The thesis updated its Nastran model of the welded GARTEUR replica against
measured modes: the wing-torsion pair came out *below* the fin/tail mode
(Table 10: test mode 3 pairs with FE mode 5, test modes 4 and 5 with FE modes 3
and 4), and torsional springs at the wing tips (about Y), a fin torsion spring
(about Z) and the fin thickness were updated by inverse eigensensitivity until
the order was restored (Table 11).  No measured data of the replica are
available here, so the case is rebuilt with a pseudo-experimental "truth"
(choices, documented):

* **nominal** (:func:`nominal_model`): ``garteur_model(mesh, torsion_springs=True)``
  with the fin 5 % thicker than drawn (h = 10.5 mm — the modelling error to be
  found), wing torsion springs almost absent (25 N·m/rad each: the free wing
  torsion) and the fin spring at the thesis' 1000 N·m/rad.
* **truth** (:func:`truth_model`): the nominal with the updating parameters at
  :data:`TRUE_VALUES` — wing springs 100 N·m/rad (the welded wing/drum joints
  stiffer in torsion), fin spring 1500 N·m/rad, fin thickness × 0.95 (h = 9.975 mm) —
  plus two small errors that are *not* updated (:data:`TRUE_NUISANCE`: wing E
  + 0.3 %, fuselage density − 0.3 %), so the updated model cannot be exact.

With the default mesh the nominal's elastic modes 3–4 (wing torsion pair,
37.9 Hz) lie below mode 5 (wing bending with tail-plane motion, 38.7 Hz) while
in the truth that mode drops to 37.4 Hz and the torsion pair rises to 39.4/39.5 Hz:
test mode 3 pairs with nominal mode 5 and test modes 4, 5 with nominal 3, 4 —
the Table 10 pattern for modes 3–5.  The Table 10 swap of modes 9 and 10 is
*not* reproduced.  Here modes 8–10 are fuselage lateral/roll (61.5 Hz), tail-plane
roll with fin bending (65.3 Hz) and fin torsion (tail plane fore-aft, 85.4 Hz with the
1000 N·m/rad spring).  Bringing fin torsion below mode 9 in a truth takes removing most
of the fin spring and thinning the fin by 10–20 %; on the way it mixes with modes 8 and 9
(MAC 0.5–0.7 at the test DOFs), and the truths we scanned (fin spring 1–3000 N·m/rad, fin
thickness × 0.8–1.0, tail-plane density and tail mass changed) gave three-mode cycles or
unpaired modes, never a clean 9↔10 swap.

:func:`accelerometer_dofs` lists test DOFs like a real test: Z at wing,
drum, fuselage and tail-plane points, Y at the fuselage ends and the fin
tip, X at the drum ends, the tail-plane tips and the fin tip.
"""
from __future__ import annotations

import numpy as np

from modalab.core.dof import Dof
from modalab.core.modes import ModeSet
from updating.fe import FEModel, ParametricFEModel

from updating.fe.models.garteur import garteur_model, garteur_parameters

__all__ = ["UPDATING_PARAMETERS", "NOMINAL_VALUES", "TRUE_VALUES", "TRUE_NUISANCE", "nominal_model",
           "truth_model", "accelerometer_dofs", "modal_test", "updating_model"]

#: the thesis' updating parameters (garteur_parameters names)
UPDATING_PARAMETERS = ("k_wing_torsion", "k_fin_torsion", "t_fin")
#: their values in the nominal model (physical springs N·m/rad; fin thickness factor on the drawn 10 mm)
NOMINAL_VALUES = {"k_wing_torsion": 25.0, "k_fin_torsion": 1000.0, "t_fin": 1.05}
#: their values in the truth, relative to the nominal model (springs physical, t_fin a factor on 10.5 mm)
TRUE_VALUES = {"k_wing_torsion": 100.0, "k_fin_torsion": 1500.0, "t_fin": 0.95}
#: small errors of the truth that are not updated (factors)
TRUE_NUISANCE = {"E_wing": 1.003, "rho_fuselage": 0.997}


def nominal_model(mesh: int = 8) -> FEModel:
    """The nominal FE model (see the module docstring)."""
    base = garteur_model(mesh, torsion_springs=True)
    pm = ParametricFEModel(base, garteur_parameters(base, names=UPDATING_PARAMETERS))
    m = pm.model_at(np.array([NOMINAL_VALUES[n] for n in UPDATING_PARAMETERS]))
    m.name = "GARTEUR-like nominal (thesis 5.3 case)"
    m.metadata.update(base.metadata)
    return m


def truth_model(mesh: int = 8) -> FEModel:
    """The pseudo-experimental structure: the nominal with :data:`TRUE_VALUES` and :data:`TRUE_NUISANCE`."""
    nom = nominal_model(mesh)
    names = UPDATING_PARAMETERS + tuple(TRUE_NUISANCE)
    pm = ParametricFEModel(nom, garteur_parameters(nom, names=names))
    p = np.array([TRUE_VALUES.get(n, TRUE_NUISANCE.get(n)) for n in names], float)
    m = pm.model_at(p)
    m.name = "GARTEUR-like pseudo-experimental truth"
    m.metadata.update(nom.metadata)
    return m


def updating_model(model: FEModel) -> ParametricFEModel:
    """``model`` with the thesis' three updating parameters (springs as values, fin thickness as a factor)."""
    return ParametricFEModel(model, garteur_parameters(model, names=UPDATING_PARAMETERS))


def accelerometer_dofs(model: FEModel) -> list:
    """Test DOFs at accelerometer points (independent nodes of ``model``), as a real modal test would measure."""
    pts = model.metadata["points"]
    mem = model.metadata["members"]
    wing = mem["wing"]
    out = []
    for nid in wing[::2] + [wing[-1]]:
        out.append(Dof(nid, 3))
    for side in ("right_drum", "left_drum"):
        d = mem[side]
        out += [Dof(d[0], 3), Dof(d[-1], 3), Dof(d[0], 1)]
    for nid in (pts["nose"], pts["tail_end"]):
        out += [Dof(nid, 3), Dof(nid, 2)]
    out += [Dof(pts["fuselage_fin"], 3)]
    fin = mem["fin"]
    out += [Dof(fin[len(fin) // 2], 2), Dof(pts["fin_tip"], 2), Dof(pts["fin_tip"], 1)]
    ht = mem["htail"]
    out += [Dof(ht[0], 3), Dof(ht[-1], 3), Dof(ht[0], 1), Dof(ht[-1], 1)]
    seen, uniq = set(), []
    for d in out:
        if (d.node, d.direction) not in seen:
            seen.add((d.node, d.direction))
            uniq.append(d)
    return uniq


def modal_test(model: FEModel, dofs=None, n_modes: int = 10, n_rigid: int = 6) -> ModeSet:
    """The first ``n_modes`` elastic modes of ``model`` at ``dofs`` (default :func:`accelerometer_dofs`).

    Mass-normalised shapes; the ``n_rigid`` rigid-body modes of the free-free model are skipped.
    """
    dofs = accelerometer_dofs(model) if dofs is None else dofs
    ms = model.modes(n_rigid + n_modes)
    ms = ms.select_modes(np.arange(n_rigid, n_rigid + n_modes)).select_dofs(dofs)
    ms.metadata["source"] = f"pseudo-experimental modes of {model.name}"
    return ms
