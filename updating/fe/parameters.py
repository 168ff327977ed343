"""Updating parameters of an FE model and their exact derivative matrices.

A :class:`Parameter` names one physical quantity over a group of objects:

==============================  ==========================================================
selector                        fields
==============================  ==========================================================
``materials=(mid, ...)``        ``E``, ``G``, ``nu``, ``rho``, ``ge``
``properties=(pid|name, ...)``  material fields as seen by those properties only (the
                                material is cloned for the group), ``ge``, ``nsm``, and the
                                section's dimensions or properties: ``b``, ``h`` (rectangle,
                                I ∝ h³), ``do``, ``di`` (tube), ``A``, ``Iy``, ``Iz``, ``J``
                                (general section or rod), ``t`` (shell thickness: membrane ∝ t,
                                bending ∝ t³, mass ∝ t, rotary inertia ∝ t³)
``elements=(eid, ...)``,        ``k``, ``ge`` (springs), ``c`` (dampers), ``mass``,
``groups=(label, ...)``         ``inertia`` (lumped masses; factor mode only)
(no selector)                   ``global_ge`` (PARAM G), ``rayleigh_alpha``, ``rayleigh_beta``
==============================  ==========================================================

Changing ``E`` changes G too when the material's G is derived from ν
(G = E/2(1+ν)), not when G was given explicitly.  Parameters compose: material-wide parameters are applied before property
ones, so ``E`` of material 1 (factor p₁) and ``E`` of the 'wing' group using
it (factor p₂) give the wing E·p₁·p₂.

``mode="factor"`` (default): p multiplies the nominal value of every selected
object, so p = 1 is the nominal model and p0 = 1.  ``mode="value"``: p *is*
the physical value (SI) set on every selected object; p0 is the nominal value,
which must then be the same for all of them.

Derivatives.  The matrices depend on p through non-linear relations (I = b h³/12,
G = E/2(1+ν), the Timoshenko shear parameter φ = 12EI/(κGAL²) ...).  The
derivative of each element matrix is computed by the *complex step*:
``∂A/∂p = Im A(p + i h) / h`` with h = 10⁻³⁰·max(1, |p|).  For analytic
functions this is the exact derivative up to rounding (there is no
subtraction, hence no truncation or cancellation error), so the chain rule
through section properties is applied exactly without hand-coding each relation.
Only the elements a parameter touches are re-assembled.  The derivatives are
reduced with the same constraint transformation, ``∂K_a/∂p = Tᵀ (∂K/∂p) T``.

:class:`ParametricFEModel` wraps a model and a parameter list and implements
the :class:`updating.fe.parametric.ParametricModel` protocol on the constrained DOFs.
"""
from __future__ import annotations

import dataclasses
import difflib
import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from modalab.core.errors import ModalabValueError, ShapeError
from modalab.core.structure import Structure
from updating.fe.parametric import Derivative

from updating.fe.assembly import assemble
from updating.fe.elements.damper import Damper
from updating.fe.elements.mass import LumpedMass
from updating.fe.elements.spring import Spring
from updating.fe.model import FEModel, FESystem
from updating.fe.properties import BeamProperty, RodProperty, ShellProperty

log = logging.getLogger(__name__)

__all__ = ["Parameter", "ParametricFEModel", "MATERIAL_FIELDS", "ELEMENT_FIELDS", "GLOBAL_FIELDS"]

MATERIAL_FIELDS = ("E", "G", "nu", "rho", "ge")
ELEMENT_FIELDS = {Spring: ("k", "ge"), Damper: ("c",), LumpedMass: ("mass", "inertia")}
GLOBAL_FIELDS = ("global_ge", "rayleigh_alpha", "rayleigh_beta")


@dataclass(frozen=True)
class Parameter:
    """A named updating parameter (see the module docstring for selectors and fields)."""

    name: str
    field: str
    materials: tuple = ()
    properties: tuple = ()
    elements: tuple = ()
    groups: tuple = ()
    mode: str = "factor"

    def __post_init__(self):
        for attr in ("materials", "properties", "elements", "groups"):
            v = getattr(self, attr)
            if isinstance(v, (str, int, np.integer)):
                object.__setattr__(self, attr, (v,))
            else:
                object.__setattr__(self, attr, tuple(v))
        if self.mode not in ("factor", "value"):
            raise ModalabValueError(f"parameter {self.name!r}: mode {self.mode!r}; expected 'factor' (p multiplies "
                                    "the nominal value) or 'value' (p is the physical value)")
        n_sel = sum(bool(x) for x in (self.materials, self.properties, self.elements or self.groups))
        if self.field in GLOBAL_FIELDS:
            if n_sel:
                raise ModalabValueError(f"parameter {self.name!r}: {self.field} is model-wide; give no selector")
        elif n_sel != 1:
            raise ModalabValueError(f"parameter {self.name!r}: give exactly one selector among materials=, "
                                    "properties=, elements=/groups= (got "
                                    f"{n_sel}); or a model-wide field {GLOBAL_FIELDS}")

    def model_value(self, value, model: FEModel):
        """The value set on the selected objects for the parameter value ``value`` (``mode='value'``), on
        ``model`` with the model-wide parameters already applied: ``value`` itself.  A subclass may define its
        value relative to a model-wide quantity (the inverse is :meth:`parameter_value`)."""
        return value

    def parameter_value(self, model_value, model: FEModel):
        """The parameter value of the objects' value ``model_value`` on ``model`` (inverse of :meth:`model_value`)."""
        return model_value


# ------------------------------------------------------------------ targets
def _section_has(section, field):
    return field in {f.name for f in dataclasses.fields(section)}


def _closest_field(name: str, valid) -> str | None:
    """The valid field a misspelt ``name`` most likely means ('Emod' -> 'E', 'rh0' -> 'rho'), or None."""
    close = difflib.get_close_matches(name, valid, n=1, cutoff=0.6)
    if close:
        return close[0]
    starts = [v for v in valid if name.lower().startswith(v.lower())]
    return max(starts, key=len) if starts else None


def _targets(model: FEModel, par: Parameter):
    """List of (kind, key) that the parameter modifies, plus affected element list (None = all)."""
    f = par.field
    if f in GLOBAL_FIELDS:
        return [("global", f)], None
    if par.materials:
        if f not in MATERIAL_FIELDS:
            raise ModalabValueError(f"parameter {par.name!r}: field {f!r} is not a material field {MATERIAL_FIELDS}")
        mids = [int(m) for m in par.materials]
        for m in mids:
            model.material(m)
        pids = [p.pid for p in model.properties.values() if p.mid in mids]
        return [("material", m) for m in mids], model.elements_with_property(pids)
    if par.properties:
        try:
            pids = model.property_ids(par.properties)
        except ModalabValueError as e:
            names = {getattr(p, "name", "") for p in model.properties.values()} - {""}
            items = [par.properties] if isinstance(par.properties, str) else list(par.properties)
            near = any(difflib.get_close_matches(str(it), names, n=1) for it in items)
            springs = [] if near else sorted(k for k, el in model.elements.items() if isinstance(el, Spring))
            hint = (f"; a spring (CELAS/PELAS) is no property group: update it as an element field, field = 'k' "
                    f"with elements = [{springs[0]}] (the spring elements: {springs[:8]})") if springs else ""
            raise ModalabValueError(f"parameter {par.name!r}: {e}{hint}") from None
        for pid in pids:
            prop = model.prop(pid)
            ok = f in MATERIAL_FIELDS or f == "nsm"
            if isinstance(prop, BeamProperty):
                ok = ok or _section_has(prop.section, f)
            elif isinstance(prop, RodProperty):
                ok = ok or f in ("A", "J")
            elif isinstance(prop, ShellProperty):
                ok = ok or f == "t"
            if not ok:
                sec = type(getattr(prop, "section", prop)).__name__
                near = _closest_field(f, MATERIAL_FIELDS + ("nsm", "t"))
                raise ModalabValueError(f"parameter {par.name!r}: property {pid} ({sec}) has no field {f!r}"
                                        + (f" (did you mean {near!r}?)" if near else "") +
                                        f"; use a material field {MATERIAL_FIELDS}, 'nsm', a dimension of its "
                                        "section, or 't' for a shell")
            if f in ("inertia", "k", "c", "mass"):
                raise ModalabValueError(f"parameter {par.name!r}: {f!r} is an element field; select elements=")
        return [("property", p) for p in pids], model.elements_with_property(pids)
    els = []
    if par.elements:
        for e in par.elements:
            if int(e) not in model.elements:
                raise ModalabValueError(f"parameter {par.name!r}: element {e} is not in the model")
            els.append(model.elements[int(e)])
    if par.groups:
        hits = [e for e in model.elements.values() if getattr(e, "group", "") in par.groups]
        if not hits:
            raise ModalabValueError(f"parameter {par.name!r}: no element has group label in {par.groups}")
        els.extend(hits)
    for e in els:
        allowed = ELEMENT_FIELDS.get(type(e), ())
        if f not in allowed:
            raise ModalabValueError(f"parameter {par.name!r}: element {e.eid} ({type(e).__name__}) has no updatable "
                                    f"field {f!r}; allowed: {allowed}")
        if f == "inertia" and par.mode == "value":
            raise ModalabValueError(f"parameter {par.name!r}: inertia is a tensor; use mode='factor'")
    uniq = {e.eid: e for e in els}
    return [("element", eid) for eid in uniq], list(uniq.values())


def _get(model, kind, key, field):
    if kind == "global":
        if field == "global_ge":
            return model.global_ge or 0.0
        a, b = model.rayleigh or (0.0, 0.0)
        return a if field == "rayleigh_alpha" else b
    if kind == "material":
        m = model.material(key)
        return m.shear_modulus if field == "G" else getattr(m, field)
    if kind == "element":
        return getattr(model.elements[key], field)
    prop = model.prop(key)
    mat = model.material(prop.mid)
    if field == "ge":
        return prop.ge if prop.ge is not None else mat.ge
    if field == "nsm":
        return prop.nsm
    if isinstance(prop, RodProperty) and field in ("A", "J"):
        return getattr(prop, field)
    if isinstance(prop, ShellProperty) and field == "t":
        return prop.t
    if isinstance(prop, BeamProperty) and _section_has(prop.section, field):
        return getattr(prop.section, field)
    return mat.shear_modulus if field == "G" else getattr(mat, field)


def _set(model, kind, key, field, value, fresh_mid):
    if kind == "global":
        if field == "global_ge":
            model.global_ge = value
        else:
            a, b = model.rayleigh or (0.0, 0.0)
            model.rayleigh = (value, b) if field == "rayleigh_alpha" else (a, value)
        return
    if kind == "material":
        model.materials[key] = dataclasses.replace(model.materials[key], **{field: value})
        return
    if kind == "element":
        model.elements[key] = dataclasses.replace(model.elements[key], **{field: value})
        return
    prop = model.properties[key]
    if field in ("ge", "nsm") or (isinstance(prop, RodProperty) and field in ("A", "J")) or \
            (isinstance(prop, ShellProperty) and field == "t"):
        model.properties[key] = dataclasses.replace(prop, **{field: value})
    elif isinstance(prop, BeamProperty) and field not in MATERIAL_FIELDS:
        sec = prop.section
        if field in {f.name for f in dataclasses.fields(sec)}:
            new = dataclasses.replace(sec, **{field: value})
        else:
            raise ModalabValueError(f"section {type(sec).__name__} field {field!r} is derived from its dimensions; "
                                    "parameterise the dimensions (b, h, do, di) or use a GeneralSection")
        model.properties[key] = dataclasses.replace(prop, section=new)
    else:  # material field seen by this property only: clone the material
        mat = model.material(prop.mid)
        mid = fresh_mid()
        model.materials[mid] = dataclasses.replace(mat, mid=mid, **{field: value})
        model.properties[key] = dataclasses.replace(prop, mid=mid)


class ParametricFEModel:
    """An FE model with named parameters; implements :class:`updating.fe.parametric.ParametricModel`.

    Parameters
    ----------
    model : the nominal :class:`~updating.fe.model.FEModel` (not modified).
    parameters : list of :class:`Parameter`.
    p0 : optional starting values (default: 1 for factor parameters, the nominal value for value parameters).

    ``dofs`` are the constrained (independent) DOFs; ``structure(p)`` and
    ``derivatives(p)`` work on them.  ``system(p)`` and ``model_at(p)`` give
    access to full-DOF results.
    """

    def __init__(self, model: FEModel, parameters, p0=None):
        self.model = model
        self.parameters = list(parameters)
        names = [p.name for p in self.parameters]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise ModalabValueError(f"duplicate parameter names {sorted(dup)}; names must be unique")
        self.parameter_names = names
        self._targets = [_targets(model, p) for p in self.parameters]
        nominal = []
        for par, (tg, _) in zip(self.parameters, self._targets):
            if par.mode == "factor":
                nominal.append(1.0)
                continue
            vals = [_get(model, k, key, par.field) for k, key in tg]
            if not np.allclose(vals, vals[0], rtol=1e-12, atol=0):
                raise ModalabValueError(f"parameter {par.name!r} (mode='value') selects objects with different "
                                        f"nominal {par.field} values {vals[:5]}; use mode='factor' or split it")
            nominal.append(float(np.real(par.parameter_value(vals[0], model))))
        self.nominal = np.asarray(nominal, float)
        self.p0 = self.nominal.copy() if p0 is None else np.asarray(p0, float)
        if self.p0.shape != (len(self.parameters),):
            raise ShapeError(f"p0 has {self.p0.size} values for {len(self.parameters)} parameters {names}")
        self._reduction = model.reduction()
        self.dofs = list(self._reduction.dofs)

    @property
    def n_params(self) -> int:
        return len(self.parameters)

    @property
    def reduction(self):
        return self._reduction

    def _check(self, p):
        p = self.p0 if p is None else np.asarray(p)
        if p.shape != (self.n_params,):
            raise ShapeError(f"parameter vector has shape {p.shape}; expected ({self.n_params},) for "
                             f"{self.parameter_names}")
        return p

    def model_at(self, p=None) -> FEModel:
        """A copy of the model with the parameter values ``p`` applied (complex values allowed)."""
        p = self._check(p)
        m = self.model.copy()
        counter = [max(list(m.materials) + [0])]

        def fresh():
            counter[0] += 1
            return counter[0]

        # material parameters first, so that property-level clones inherit their changes
        rank = {"global": 0, "material": 1, "property": 2, "element": 3}
        order = sorted(range(self.n_params), key=lambda i: rank[self._targets[i][0][0][0]])
        for i in order:
            par, (tg, _), v = self.parameters[i], self._targets[i], p[i]
            for kind, key in tg:
                if par.mode == "factor":
                    old = _get(m, kind, key, par.field)
                    new = old * v
                else:
                    new = par.model_value(v, m)
                _set(m, kind, key, par.field, new, fresh)
        return m

    def system(self, p=None) -> FESystem:
        m = self.model_at(np.asarray(self._check(p), float))
        mats = self._reduction.reduce_matrices(assemble(m))
        return FESystem(K=mats.K, M=mats.M, C=mats.C, D=mats.D, dofs=mats.dofs, reduction=self._reduction)

    def structure(self, p=None) -> Structure:
        """Structure (M, K, C, D) at ``p`` on the constrained DOFs."""
        return self.system(p).structure(coords=self.model.coords(), name=self.model.name)

    def derivatives(self, p=None, only=None) -> list:
        """Exact ∂K/∂p_i, ∂M/∂p_i, ∂C/∂p_i, ∂D/∂p_i on the constrained DOFs (None where zero); with ``only``
        (parameter indices) those alone are assembled and the others are None."""
        p = np.asarray(self._check(p), float)
        out = []
        for i, (par, (tg, els)) in enumerate(zip(self.parameters, self._targets)):
            if only is not None and i not in only:
                out.append(None)
                continue
            h = 1e-30 * max(1.0, abs(p[i]))
            pc = p.astype(complex)
            pc[i] += 1j * h
            m = self.model_at(pc)
            subset = None if els is None else [m.elements[e.eid] for e in els]
            mats = assemble(m, elements=subset, dtype=complex)

            def d(A):
                if A is None:
                    return None
                B = sp.csr_matrix(A.imag / h) if np.iscomplexobj(A.data) else None
                if B is None:
                    return None
                B.eliminate_zeros()
                if B.nnz == 0:
                    return None
                return self._reduction.reduce(B)

            out.append(Derivative(dK=d(mats.K), dM=d(mats.M), dC=d(mats.C), dD=d(mats.D)))
        return out

    def __repr__(self) -> str:
        return f"ParametricFEModel({self.model.name or 'unnamed'}: {self.n_params} parameters {self.parameter_names})"
