"""Model-updating methods (thesis chapter 3), each on a :class:`~updating.fe.parametric.ParametricModel`.

By task:

From identified modes
    :class:`InverseEigensensitivity` (section 3.2.2, Eq. 3.40–3.53) with :func:`sensitivity_ranking`,
    :func:`identifiability`, :func:`choose_alpha`; :class:`EigendynamicConstraint` (3.2.1).
From FRFs
    :class:`MCIUpdater` and :func:`mci` (MisCorrelation Index, 3.2.4); :func:`mci_update` (the MCI on the
    condensed residual with noise-model line weights, which diagnosis uses); :class:`ResponseFunctionMethod`
    (3.2.3).  All read FRFs through :mod:`updating.correlation.receptance`, expand them with
    :mod:`updating.correlation.condensation` and iterate in :func:`updating.methods.iteration.iterate`.
Direct matrix updating (3.1)
    :func:`lagrange_stiffness`, :func:`lagrange_mass`, :func:`lagrange_mass_stiffness`, :func:`error_matrix`,
    :func:`direct_matrix_updating`, :func:`matrix_mixing`, :func:`baruch_orthogonalise`.
"""
from updating.methods.direct import (DirectUpdate, baruch_orthogonalise, direct_matrix_updating, error_matrix,
                                     lagrange_mass, lagrange_mass_stiffness, lagrange_stiffness, matrix_mixing)
from updating.methods.eigendynamic import EigendynamicConstraint
from updating.methods.eigensensitivity import (InverseEigensensitivity, choose_alpha, identifiability,
                                               sensitivity_ranking)
from updating.methods.mci import MCIUpdater, mci
from updating.methods.mci_condensed import mci_update
from updating.methods.rfm import ResponseFunctionMethod

__all__ = ["DirectUpdate", "baruch_orthogonalise", "direct_matrix_updating", "error_matrix", "lagrange_mass",
           "lagrange_mass_stiffness", "lagrange_stiffness", "matrix_mixing", "EigendynamicConstraint",
           "InverseEigensensitivity", "choose_alpha", "identifiability", "sensitivity_ranking", "MCIUpdater",
           "mci", "mci_update", "ResponseFunctionMethod"]
