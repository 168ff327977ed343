"""Materials, beam cross-sections and element properties.

Every value is SI (Pa, kg/m³, m, m², m⁴).  Objects are frozen dataclasses:
updating parameters change them with :func:`dataclasses.replace` on a copy
of the model, never in place.  Section properties are computed from the
section dimensions by plain arithmetic so that they can be evaluated with
complex numbers (complex-step differentiation, see :mod:`updating.fe.parameters`).

Local beam axes follow Nastran's CBAR convention: local x runs from end A to
end B, local y lies in the plane of x and the orientation vector, local z
completes the right-handed triad.  ``Iz`` (Nastran I1) resists bending in the
local x–y plane, ``Iy`` (Nastran I2) bending in the local x–z plane.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from modalab.core.errors import ModalabValueError

__all__ = ["Material", "GeneralSection", "RectangularSection", "TubeSection", "CircularSection",
           "BeamProperty", "RodProperty", "ShellProperty", "SECTION_FIELDS"]


def _re(x) -> float:
    return float(np.real(x))


@dataclass(frozen=True)
class Material:
    """Isotropic linear-elastic material (Nastran MAT1).

    mid : material id.  E : Young's modulus (Pa).  nu : Poisson's ratio.
    G : shear modulus (Pa); when None it is ``E / (2 (1 + nu))``.
    rho : density (kg/m³).  ge : structural damping coefficient (loss factor),
    giving the element hysteretic matrix ``D_e = ge · K_e``.
    """

    mid: int
    E: float
    nu: float | None = 0.3
    rho: float = 0.0
    G: float | None = None
    ge: float = 0.0
    name: str = ""

    def __post_init__(self):
        if not _re(self.E) > 0:
            raise ModalabValueError(f"material {self.mid}: E = {self.E!r}; expected a positive modulus in Pa")
        if _re(self.rho) < 0:
            raise ModalabValueError(f"material {self.mid}: rho = {self.rho!r}; expected a density >= 0 in kg/m^3")
        if self.G is None and self.nu is None:
            raise ModalabValueError(f"material {self.mid}: neither G nor nu given; give one of them")

    @property
    def shear_modulus(self):
        """G, or E/(2(1+ν)) when G was not given."""
        if self.G is not None:
            return self.G
        return self.E / (2.0 * (1.0 + self.nu))


@dataclass(frozen=True)
class GeneralSection:
    """Section given by its properties (Nastran PBAR/PBEAM style).

    A : area (m²).  Iy, Iz : second moments about local y and z (m⁴; Iz is Nastran I1).
    J : torsion constant (m⁴).  ky, kz : shear area factors for Timoshenko elements
    (shear area ky·A resists shear along local y); None means shear-rigid
    (as a blank K1/K2 on PBAR).  Ip : polar moment used for torsional mass (default Iy + Iz).
    """

    A: float
    Iy: float
    Iz: float
    J: float
    ky: float | None = None
    kz: float | None = None
    Ip: float | None = None

    @property
    def polar(self):
        return self.Iy + self.Iz if self.Ip is None else self.Ip


@dataclass(frozen=True)
class RectangularSection:
    """Solid rectangle: ``b`` along local y, ``h`` along local z (m).

    ``Iy = b h³/12`` (so I ∝ t³ for the thickness t = h), ``Iz = h b³/12``,
    Saint-Venant torsion constant ``J = a c³ [1/3 − 0.21 (c/a)(1 − (c/a)⁴/12)]``
    with a ≥ c the longer and shorter sides (Roark), shear factors 5/6.
    """

    b: float
    h: float

    def __post_init__(self):
        if not (_re(self.b) > 0 and _re(self.h) > 0):
            raise ModalabValueError(f"rectangular section {self.b!r} x {self.h!r}; both sides must be > 0 m")

    @property
    def A(self):
        return self.b * self.h

    @property
    def Iy(self):
        return self.b * self.h ** 3 / 12.0

    @property
    def Iz(self):
        return self.h * self.b ** 3 / 12.0

    @property
    def J(self):
        a, c = (self.b, self.h) if _re(self.b) >= _re(self.h) else (self.h, self.b)
        r = c / a
        return a * c ** 3 * (1.0 / 3.0 - 0.21 * r * (1.0 - r ** 4 / 12.0))

    ky = 5.0 / 6.0
    kz = 5.0 / 6.0

    @property
    def polar(self):
        return self.Iy + self.Iz


@dataclass(frozen=True)
class TubeSection:
    """Circular tube of outer and inner diameters ``do``, ``di`` (m); ``di = 0`` for a solid bar."""

    do: float
    di: float = 0.0

    def __post_init__(self):
        if not (_re(self.do) > _re(self.di) >= 0):
            raise ModalabValueError(f"tube section do={self.do!r}, di={self.di!r}; expected do > di >= 0 (m)")

    @property
    def A(self):
        return np.pi / 4.0 * (self.do ** 2 - self.di ** 2)

    @property
    def Iy(self):
        return np.pi / 64.0 * (self.do ** 4 - self.di ** 4)

    Iz = Iy

    @property
    def J(self):
        return np.pi / 32.0 * (self.do ** 4 - self.di ** 4)

    polar = J

    @property
    def ky(self):
        # Cowper's shear coefficient of a hollow circular section (ν = 0.3)
        m = self.di / self.do
        nu = 0.3
        m2 = m * m
        return 6 * (1 + nu) * (1 + m2) ** 2 / ((7 + 6 * nu) * (1 + m2) ** 2 + (20 + 12 * nu) * m2)

    kz = ky


def CircularSection(d: float) -> TubeSection:
    """Solid circular bar of diameter ``d`` (a :class:`TubeSection` with ``di = 0``)."""
    return TubeSection(do=d, di=0.0)


#: section dimension/property names that parameters may address
SECTION_FIELDS = {
    GeneralSection: ("A", "Iy", "Iz", "J", "ky", "kz", "Ip"),
    RectangularSection: ("b", "h"),
    TubeSection: ("do", "di"),
}


@dataclass(frozen=True)
class BeamProperty:
    """Beam property (PBAR/PBEAM/PBARL): material, section, non-structural mass.

    pid : property id.  mid : material id.  section : a section object.
    nsm : non-structural mass per length (kg/m).  name : group name used by
    parameters ('wing', 'fuselage' ...).  ge : structural damping of this
    group; None uses the material's ``ge``.
    """

    pid: int
    mid: int
    section: object
    nsm: float = 0.0
    name: str = ""
    ge: float | None = None


@dataclass(frozen=True)
class RodProperty:
    """Rod property (PROD): material, area ``A``, torsion constant ``J``, nsm (kg/m)."""

    pid: int
    mid: int
    A: float
    J: float = 0.0
    nsm: float = 0.0
    name: str = ""
    ge: float | None = None


@dataclass(frozen=True)
class ShellProperty:
    """Shell property (Nastran PSHELL) of :class:`~updating.fe.elements.shell.Quad4` / ``Tria3``.

    pid : property id.  mid : material id (MID1; the bending material MID2 and
    the transverse-shear material MID3 are taken equal to MID1, i.e. a
    homogeneous isotropic plate — the bulk reader rejects a PSHELL whose MID2 or
    MID3 differ).  t : thickness (m); bending stiffness ∝ t³, so a thickness
    parameter is non-linear (exact complex-step derivatives).  nsm :
    non-structural mass per area (kg/m²).  name : group name for parameters.
    ge : structural damping of this group; None uses the material's ``ge``.
    bending : 12I/T³ (bending inertia ratio, Nastran default 1.0).
    shear : TS/T (transverse-shear thickness ratio, Nastran default 0.833333).
    """

    pid: int
    mid: int
    t: float
    nsm: float = 0.0
    name: str = ""
    ge: float | None = None
    bending: float = 1.0
    shear: float = 0.833333

    def __post_init__(self):
        if not _re(self.t) > 0:
            raise ModalabValueError(f"shell property {self.pid}: thickness t = {self.t!r}; expected t > 0 (m)")
        if not (_re(self.bending) > 0 and _re(self.shear) > 0):
            raise ModalabValueError(f"shell property {self.pid}: 12I/T^3 = {self.bending!r}, TS/T = {self.shear!r};"
                                    " expected both > 0")
