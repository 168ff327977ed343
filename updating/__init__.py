"""updating — from an FE model and test data to an updated model and the physics it left out.

By task.  Four subpackages follow the flow, bottom up (an import-linter contract keeps the order):
:mod:`updating.fe` → :mod:`updating.correlation` → :mod:`updating.methods` → :mod:`updating.diagnosis`.

Read, build or write an FE model — :mod:`updating.fe`, :mod:`updating.fe.bulk`
    :func:`~updating.fe.bulk.read_bdf` → :func:`~updating.fe.bulk.build_model` → :class:`~updating.fe.FEModel`
    (elements one per module in :mod:`updating.fe.elements`, RBE2, SPC, damping); back to bulk data with
    :func:`~updating.fe.bulk.to_bulk` and :func:`~updating.fe.bulk.write_bdf`.  Reference models:
    :mod:`updating.fe.models` (beams, a GARTEUR-like frame).
Modes and FRFs of the model
    :func:`~updating.fe.normal_modes`, :func:`~updating.fe.modes_of`; :func:`~updating.fe.frf_direct`,
    :func:`~updating.fe.frf_modal` (at ``s = iω + β`` when compared with exponentially windowed data).  Dense below
    :data:`modalab.core.dense.EIGEN_LIMIT` DOFs, shift-invert Lanczos above: the one dense/sparse rule is
    :mod:`modalab.core.dense`.
Choose the updating parameters
    :class:`~updating.fe.Parameter`, :class:`~updating.fe.ParametricFEModel` (the
    :class:`~updating.fe.parametric.ParametricModel` protocol every method takes); a parameter file
    :func:`~updating.fe.parameter_file.read_parameter_file`; eigen-sensitivities
    (:mod:`updating.fe.sensitivity`: :func:`~updating.fe.sensitivity.frequency_sensitivities`,
    :func:`~updating.fe.sensitivity.eigenvector_sensitivities`, Nelson).
Compare test and model modes — :mod:`updating.correlation`
    :func:`~updating.correlation.mac`, :func:`~updating.correlation.automac`, :func:`~updating.correlation.comac`,
    :func:`~updating.correlation.ecomac`, :func:`~updating.correlation.msf`, orthogonality; pairing swapped and
    missing modes: :func:`~updating.correlation.pair_modes`, :func:`~updating.correlation.correlate`; test DOFs on
    model DOFs: :class:`~updating.correlation.DofMap`.
Compare FRFs, put measured FRFs on the model
    :func:`~updating.correlation.frac`, :func:`~updating.correlation.csac`, :func:`~updating.correlation.csf`;
    the one receptance adapter :mod:`updating.correlation.receptance` (``frf_data``, ``measured_columns``; it
    keeps an exponential window's β in ``s``) and the one dynamic expansion
    :mod:`updating.correlation.condensation` (``condensed_residual``), shared by MCI, RFM and diagnosis.
Reduce and expand
    :func:`~updating.correlation.guyan`, :func:`~updating.correlation.irs`, :func:`~updating.correlation.serep`;
    :func:`~updating.correlation.kidder`, :func:`~updating.correlation.serep_expand`,
    :func:`~updating.correlation.modal_expand`.
Update from identified modes — :mod:`updating.methods`
    :class:`~updating.methods.InverseEigensensitivity` (with :func:`~updating.methods.sensitivity_ranking`,
    :func:`~updating.methods.identifiability`, :func:`~updating.methods.choose_alpha`);
    :class:`~updating.methods.EigendynamicConstraint`.
Update from FRFs
    :class:`~updating.methods.MCIUpdater`, :func:`~updating.methods.mci`, :func:`~updating.methods.mci_update`;
    :class:`~updating.methods.ResponseFunctionMethod`.
Update the matrices directly
    :func:`~updating.methods.lagrange_stiffness`, :func:`~updating.methods.lagrange_mass`,
    :func:`~updating.methods.direct_matrix_updating`, :func:`~updating.methods.matrix_mixing`,
    :func:`~updating.methods.baruch_orthogonalise`.
Find the physics the model left out — :mod:`updating.diagnosis`
    :func:`~updating.diagnosis.diagnose` / :class:`~updating.diagnosis.Diagnoser` on measured FRFs,
    :func:`~updating.diagnosis.diagnose_modes` from identified modes alone (a GVT); the parts:
    :func:`~updating.diagnosis.build_library` (candidate physics), :func:`~updating.diagnosis.screen`
    (locate the residual), :func:`~updating.diagnosis.frf_screen` (exact screening by low-rank updates),
    :func:`~updating.diagnosis.fit_frf`.  The result, :class:`~updating.diagnosis.Diagnosis`, is the content of
    ``diagnosis.json`` (``Diagnosis.to_dict()``).

The command line reaches these through :mod:`modalab.app.stages` (``correlate``, ``update``, ``diagnose``).
"""
