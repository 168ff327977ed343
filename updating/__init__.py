"""updating — from an FE model and test data to an updated model and the physics it left out.

The subpackages follow the flow, bottom up (an import-linter contract keeps the order):

The FE model — :mod:`updating.fe`
    Elements (beams, rods, springs, masses, dampers, shells), sparse assembly, constraints (SPC, RBE2),
    damping, eigen-solvers (dense below :data:`modalab.core.dense.EIGEN_LIMIT` DOFs, shift-invert Lanczos
    above: the one dense/sparse rule is :mod:`modalab.core.dense`), parameters and their derivatives (:mod:`~updating.fe.parametric`, :mod:`~updating.fe.parameters`),
    eigen-sensitivities (:mod:`~updating.fe.sensitivity`); Nastran bulk data in and out
    (:mod:`updating.fe.bulk`: ``read_bulk``, ``build_model``, ``write_bulk``); reference models
    (:mod:`updating.fe.models`: beams, a GARTEUR-like frame).
Correlation — :mod:`updating.correlation`
    MAC, AutoMAC, MSF, COMAC, ECOMAC, orthogonality, FRAC/CSAC/CSF and mode pairing
    (:mod:`~updating.correlation.metrics`); mapping test DOFs onto model DOFs
    (:mod:`~updating.correlation.dofmap`); reduction (Guyan, IRS, SEREP) and expansion (Kidder, SEREP, modal);
    figures (:mod:`~updating.correlation.plots`).
Updating methods — :mod:`updating.methods`
    Inverse eigensensitivity (thesis 3.2.2), MCI minimisation (3.2.4), the response-function method (3.2.3),
    the eigendynamic constraint (3.2.1) and the direct methods (3.1).
Missing-physics discovery — :mod:`updating.diagnosis`
    Locate the residual, screen a library of candidate physics exactly by low-rank updates, name it, add it
    to the bulk data and prove it on held-out data; from FRFs or from modes alone.
"""
