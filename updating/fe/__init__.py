"""Sparse finite-element models for correlation and updating.

Laid out like an FE code: element types (one per module in
:mod:`updating.fe.elements`), properties, the model container, assembly,
constraints, solvers, parameters and damping.  SI units throughout.

Building a model (Python code or the Nastran bulk-data reader)
---------------------------------------------------------------
``m = FEModel(name, coupled_mass=True, global_ge=0.0, rayleigh=None, modal_damping=None)``
    ``coupled_mass`` False = Nastran lumped mass (PARAM COUPMASS ≤ 0, Nastran's default);
    ``global_ge`` = PARAM G (D += G·K); ``rayleigh=(α, β)`` adds C = αM + βK;
    ``modal_damping`` = :class:`ModalDampingTable` (TABDMP1) for modal FRFs.
``m.add_node(nid, xyz, cd=None)``
    ``cd``: 3×3 rotation, columns = displacement (CD) axes in basic; node DOFs are in CD.
``m.add_material(Material(mid, E, nu=0.3, rho=0.0, G=None, ge=0.0))``           MAT1
``m.add_property(BeamProperty(pid, mid, section, nsm=0.0, name="", ge=None))``  PBAR/PBEAM(L)
    sections: ``GeneralSection(A, Iy, Iz, J, ky=None, kz=None)`` (Iz = Nastran I1, Iy = I2),
    ``RectangularSection(b, h)`` (b along local y, h along local z), ``TubeSection(do, di)``,
    ``CircularSection(d)``.
``m.add_property(RodProperty(pid, mid, A, J=0.0, nsm=0.0))``                     PROD
``m.add_element(Beam3D(eid, n1, n2, pid, orientation=(vx, vy, vz) or G0 node id, offset_a=None, offset_b=None))``
    CBAR; offsets are rigid end offsets WA/WB in the basic system (m)
``m.add_element(Timoshenko3D(eid, n1, n2, pid, orientation))``                  CBEAM-like, shear + rotary inertia
``m.add_element(Beam2D(eid, n1, n2, pid, plane="xy"|"xz", axial=False))``       planar beam (w, θ)
``m.add_element(Rod(eid, n1, n2, pid))``                                         CROD
``m.add_property(ShellProperty(pid, mid, t, nsm=0.0, name="", ge=None))``          PSHELL (MID2 = MID3 = MID1)
``m.add_element(Quad4(eid, n1, n2, n3, n4, pid))``                                CQUAD4 (MITC4 flat shell)
``m.add_element(Tria3(eid, n1, n2, n3, pid))``                                    CTRIA3 (DKT flat shell)
``m.add_element(Spring(eid, a=(node, comp), b=(node, comp) or None, k, ge=0.0, group=""))``   CELAS1/2
``m.add_element(Damper(eid, a=(node, comp), b=(node, comp) or None, c, group=""))``           CDAMP1/2
``m.add_element(LumpedMass(eid, node, mass, inertia=3×3 tensor|3 values, offset=(dx,dy,dz), axes=None, group=""))``
    CONM2; pass the inertia *tensor* (Nastran's I21 enters as −I21).
``m.add_rbe2(eid, independent, dependents, components="123456")``              RBE2 (by transformation)
``m.add_spc(node, components="123456")``                                        SPC/SPC1

Using a model
-------------
``m.dofs`` → list of :class:`~modalab.core.dof.Dof` (sorted node, axis; before constraints)
``m.assemble()`` → :class:`Matrices` (K, M, C, D sparse CSR on ``m.dofs``)
``m.reduction()`` → :class:`Reduction` (``T``, ``dofs`` = independent DOFs, ``expand(x) = T x``)
``m.system()`` → :class:`FESystem` (constrained K, M, C, D, ``dofs``, ``reduction``, ``.structure()``)
``m.structure()`` → :class:`~modalab.core.structure.Structure` on the constrained DOFs
``m.modes(n_modes=None, full=True, method="auto", shift=None, solver="auto")`` → :class:`~modalab.core.modes.ModeSet`
``m.frf(freq_hz, responses, references, quantity="accelerance", method="direct"|"modal", n_modes=None)`` → FRF

Solvers (:mod:`updating.fe.solvers`)
------------------------------------
``eigen_dense(K, M, n_modes=None)``, ``eigen_sparse(K, M, n_modes, shift=None, shift_hz=None,
solver="auto"|"splu"|"cholmod", permc_spec="MMD_AT_PLUS_A", info=None)``,
``normal_modes(K, M, n_modes, method="auto")`` → (ω rad/s, mass-normalised Φ);
``modes_of(system, n_modes, full=True, modal_damping=None)`` → ModeSet;
``frf_direct(system, freq_hz, responses, references, quantity, beta=0)`` and
``frf_modal(system, freq_hz, responses, references, n_modes=, residual=True, modal_damping=None,
window_beta_per_s=0)`` → FRF, at ``s = iω + β`` for data taken with an exponential window (β on the result).

Damping (:mod:`updating.fe.damping`)
------------------------------------
``ModalDampingTable(freq_hz, values, kind="CRIT"|"G"|"Q").zeta(f)``, ``rayleigh_coefficients(f1, z1, f2, z2)``,
``rayleigh(M, K, α, β)``, ``modal_damping_matrix(M, Φ, ω, ζ)``.

Parameters (:mod:`updating.fe.parameters`)
------------------------------------------
``Parameter(name, field, materials=(), properties=(pid or group name, ...), elements=(), groups=(),
mode="factor"|"value")`` — factor: p multiplies the nominal (p0 = 1); value: p is the SI value.
``ParametricFEModel(model, parameters, p0=None)`` implements
:class:`updating.fe.parametric.ParametricModel`: ``dofs``, ``parameter_names``, ``p0``,
``structure(p)``, ``derivatives(p)`` (exact, complex-step, on the constrained DOFs),
plus ``model_at(p)`` and ``system(p)``.
"""
from updating.fe.assembly import Matrices, assemble
from updating.fe.constraints import RBE2, SPC, Reduction, build_reduction
from updating.fe.damping import ModalDampingTable, modal_damping_matrix, rayleigh, rayleigh_coefficients
from updating.fe.elements import (Beam2D, Beam3D, Damper, Element, ElementMatrices, LumpedMass, Quad4, Rod, Spring,
                       Timoshenko3D, Tria3)
from updating.fe.model import FEModel, FESystem, Node
from updating.fe.parameters import Parameter, ParametricFEModel
from updating.fe.properties import (BeamProperty, CircularSection, GeneralSection, Material, RectangularSection,
                         RodProperty, ShellProperty, TubeSection)
from updating.fe.solvers import eigen_dense, eigen_sparse, frf_direct, frf_modal, modes_of, normal_modes

__all__ = [
    "FEModel", "FESystem", "Node", "Matrices", "assemble", "RBE2", "SPC", "Reduction", "build_reduction",
    "Material", "GeneralSection", "RectangularSection", "TubeSection", "CircularSection", "BeamProperty",
    "RodProperty", "ShellProperty", "Quad4", "Tria3",
    "Element", "ElementMatrices", "Beam3D", "Timoshenko3D", "Beam2D", "Rod", "Spring", "Damper",
    "LumpedMass", "eigen_dense", "eigen_sparse", "normal_modes", "modes_of", "frf_direct", "frf_modal",
    "ModalDampingTable", "rayleigh", "rayleigh_coefficients", "modal_damping_matrix", "Parameter",
    "ParametricFEModel",
]
