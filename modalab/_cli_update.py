"""``modalab update``: update an FE model to test modes or FRFs.

Methods: ``eigensensitivity`` (thesis 3.2.2, modes), ``eigendynamic`` (3.2.1, modes), ``mci`` (3.2.4, FRFs),
``rfm`` (3.2.3, FRFs) and the direct methods (3.1, modes; they change the matrices, not parameters):
``direct-lagrange``, ``direct-error-matrix``, ``direct-matrix``, ``direct-mixing``.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

MODAL = ("eigensensitivity", "eigendynamic")
FRF_METHODS = ("mci", "rfm")
DIRECT = ("direct-lagrange", "direct-error-matrix", "direct-matrix", "direct-mixing")


def _figure_convergence(history, names, path):
    from matplotlib.figure import Figure

    ps = np.array([h["p"] for h in history if "p" in h])
    if ps.size == 0:
        return None
    fig = Figure(figsize=(7, 4.5), layout="constrained")
    ax = fig.add_subplot()
    base = np.where(np.abs(ps[0]) > 0, ps[0], 1.0)
    for k in range(ps.shape[1]):
        ax.plot(np.arange(len(ps)), ps[:, k] / base[k], marker=".", label=names[k] if k < len(names) else str(k))
    ax.set_xlabel("iteration")
    ax.set_ylabel("parameter / initial value")
    ax.grid(alpha=0.3)
    if ps.shape[1] <= 12:
        ax.legend(fontsize=7, ncol=2)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path


def update_model(model_path, *, modes=None, frf=None, method="eigensensitivity", params=None, out_dir="updated",
                 dofmap=None, bands=None, max_iter=30, geometry=None, same_ids=False, freq_window=0.35,
                 freq_sigma=None):
    """Run one updating method and write the updated model, JSON summary and figures; returns the summary.

    Test DOFs go onto model DOFs as in ``modalab correlate`` (``dofmap``, ``geometry``, ``same_ids``,
    else the modes file's own geometry; see :func:`modalab._cli_correlate.resolve_dof_map`).  Every
    method pairs modes by the one rule of :func:`updating.correlation.pair_modes` with the frequency
    window ``freq_window``.  Frequency-only test sets use the frequencies alone; their ``freq_cov`` (or
    ``freq_sigma``: relative σ per mode, scalar or list) weights the residuals.
    """
    from updating.bulk import to_bulk, write_bdf
    from updating.correlation import correlate
    from updating.correlation_plots import plot_mac
    from updating.fe import ParametricFEModel

    from .errors import PlanError
    from .pipeline import load_model, load_modes, load_params

    out = Path(out_dir)
    model = load_model(model_path)
    summary: dict = {"model": str(model_path), "method": method}
    test = load_modes(modes) if modes else None
    if method in MODAL + DIRECT and test is None:
        raise PlanError(f"method {method!r} needs test modes: pass --modes MODES.uff")
    if method in FRF_METHODS and frf is None:
        raise PlanError(f"method {method!r} needs measured FRFs: pass --frf FRF.uff")
    n_an = max(2 * test.n_modes + 6, 12) if test is not None else 20
    how = geo = None
    if test is not None:
        from ._cli_correlate import resolve_dof_map

        dofmap, how, geo = resolve_dof_map(model, test, map_path=dofmap, geometry_path=geometry, same_ids=same_ids,
                                           modes_path=modes)
        summary["dof_mapping"] = how
        if not test.has_shapes:
            if method != "eigensensitivity":
                raise PlanError(f"{modes} holds frequencies only (no mode shapes); method {method!r} needs shapes: "
                                "use --method eigensensitivity")
            summary["note"] = "frequency-only test set: frequencies only, modes paired by frequency order"
    pairing_kw = {"max_freq_error": freq_window}
    bounds = parsed = None
    if params is not None and method not in DIRECT:
        from updating.parameter_file import read_parameter_file

        parsed = read_parameter_file(params)          # a bad file fails before anything is written
        bounds = (np.array([-np.inf if v is None else v for v in parsed[1]], float),
                  np.array([np.inf if v is None else v for v in parsed[2]], float))
    fsig = None
    if freq_sigma is not None and test is not None:
        fs = np.atleast_1d(np.asarray(freq_sigma, float))
        if fs.size not in (1, test.n_modes) or not np.all(np.isfinite(fs)) or np.any(fs <= 0):
            raise PlanError(f"--freq-sigma: got {fs.size} value(s); expected one positive relative sigma "
                            f"(e.g. 0.002) or one per test mode ({test.n_modes}) of {modes}")
        fsig = fs if fs.size > 1 else float(fs[0])
    out.mkdir(parents=True, exist_ok=True)

    def corr(structure_or_model):
        """Correlation on all test DOFs: FE models give their modes on every DOF (rigid links filled in)."""
        if test is None:
            return None
        from ._cli_correlate import analysis_modes_covering

        an = analysis_modes_covering(structure_or_model, test, n_an, freq_window) \
            if hasattr(structure_or_model, "modes") else structure_or_model
        return correlate(an, test, dofmap=dofmap, n_analysis_modes=n_an, max_freq_error=freq_window,
                         dof_mapping=how, geometry=geo)

    def on_model_dofs(modes, dofs):
        """Test modes restricted to DOFs the updater can see (independent DOFs of the constrained model)."""
        from updating.dofmap import as_dofmap

        if not modes.has_shapes:
            return modes
        dm = as_dofmap(dofmap)
        have = {(m.node, m.axis) for m in dofs}
        keep = [d for d in modes.dofs if all((t.node, t.axis) in have for t, _ in dm.terms(d))]
        if len(keep) < len(modes.dofs):
            import logging

            logging.getLogger(__name__).warning(
                "%d test DOF(s) lie on dependent or constrained model DOFs and are left out of the updating "
                "(kept in the correlation): %s", len(modes.dofs) - len(keep),
                ", ".join(str(d) for d in modes.dofs if d not in keep))
        return modes.select_dofs(keep)

    if method in DIRECT:
        from updating import direct as dm

        st = model.structure()
        if all(any(d.same_axis(m) for m in test.dofs) for d in st.dofs):
            phi_x = test.select_dofs(st.dofs).real_shapes
        else:
            from updating.expansion import kidder

            phi_x = kidder(st, on_model_dofs(test, st.dofs), dofmap=dofmap).real_shapes
        K, M = st.K.toarray(), st.M.toarray()
        w_x = test.omega
        w_a, phi_a = st.normal_modes(test.n_modes)
        fn = {"direct-lagrange": lambda: dm.lagrange_mass_stiffness(K, M, phi_x, w_x),
              "direct-error-matrix": lambda: dm.error_matrix(K, M, phi_a, w_a, phi_x, w_x),
              "direct-matrix": lambda: dm.direct_matrix_updating(K, M, phi_x, w_x),
              "direct-mixing": lambda: dm.matrix_mixing(K, M, phi_a, w_a, phi_x, w_x)}[method]
        res = fn()
        np.savez(out / "updated_matrices.npz", K=res.K, M=res.M, dK=res.dK, dM=res.dM,
                 dofs=np.array([str(d) for d in st.dofs]))
        from modalab.structure import Structure

        before = corr(model)
        after = correlate(Structure(M=res.M, K=res.K, dofs=st.dofs), on_model_dofs(test, st.dofs),
                          n_analysis_modes=n_an)
        summary.update({"equations": res.equations, "matrices": str(out / "updated_matrices.npz")})
    else:
        plist = load_params(None, model) if params is None else parsed[0]
        pm = ParametricFEModel(model, plist)
        before = corr(model)
        test_u = on_model_dofs(test, pm.dofs) if test is not None else None
        if method == "eigensensitivity":
            from updating.eigensensitivity import InverseEigensensitivity

            kw = {} if fsig is None else {"freq_sigma": fsig, "freq_cov": None}
            up = InverseEigensensitivity(max_iter=max_iter, pairing=pairing_kw, use_shapes=test.has_shapes,
                                         bounds=bounds, **kw).fit(pm, test_u, dofmap=dofmap)
            summary["identifiability"] = {
                "condition_number": float(up.condition_), "identifiable": up.identifiable_,
                "std_unregularised": {n: (float(v) if np.isfinite(v) else None)
                                      for n, v in zip([pm.parameter_names[i] for i in up.params_],
                                                      up.std_unregularised_)},
                "frequency_weights": ("covariance of the test frequencies" if test.freq_cov is not None
                                      and freq_sigma is None else
                                      f"relative sigma {fsig if fsig is not None else 0.01}")}
        elif method == "eigendynamic":
            from updating.eigendynamic import EigendynamicConstraint

            up = EigendynamicConstraint(pairing=pairing_kw).fit(pm, test_u, dofmap=dofmap)
        else:
            from modalab.frf import FRF

            measured = FRF.from_uff(frf)
            if method == "mci":
                from updating.mci import MCIUpdater

                up = MCIUpdater(bands=bands, max_iter=max_iter).fit(pm, measured)
            else:
                from updating.rfm import ResponseFunctionMethod

                up = ResponseFunctionMethod(bands=bands, max_iter=max_iter).fit(pm, measured)
        p = np.asarray(up.p_, float)
        std = np.full(p.size, np.nan)
        cov = getattr(up, "covariance_", None)
        idx = np.atleast_1d(getattr(up, "params_", np.arange(p.size)))
        if cov is not None and np.size(cov):
            std[idx] = np.sqrt(np.clip(np.diag(np.atleast_2d(cov)), 0, None))
        summary["parameters"] = {name: {"initial": float(p0), "updated": float(v),
                                        "std": None if not np.isfinite(s) else float(s)}
                                 for name, p0, v, s in zip(pm.parameter_names, pm.p0, p, std)}
        summary["converged"] = bool(getattr(up, "converged_", True))
        summary["iterations"] = int(getattr(up, "n_iter_", 0) or 0)
        hist = getattr(up, "history_", []) or []
        fig = _figure_convergence(hist, pm.parameter_names, out / "parameter_convergence.png")
        if fig:
            summary["parameter_convergence_figure"] = str(fig)
        updated_model = pm.model_at(p)
        bdf = out / "updated.bdf"
        write_bdf(to_bulk(updated_model), bdf)
        summary["updated_model"] = str(bdf)
        after = corr(updated_model)
    if before is not None:
        summary["correlation_before"] = before.to_dict()
        summary["correlation_after"] = after.to_dict()
        if test.has_shapes:
            plot_mac(before.mac, out / "mac_before.png", title="MAC before updating")
            plot_mac(after.mac, out / "mac_after.png", title="MAC after updating")
        summary["table_before"] = before.table()
        summary["table_after"] = after.table()
    (out / "update.json").write_text(json.dumps(summary, indent=1, default=str))
    return summary


def cmd_update(a):
    from .cli import _print

    bands = [tuple(b) for b in a.band] if a.band else None
    s = update_model(a.model, modes=a.modes, frf=a.frf, method=a.method, params=a.params, out_dir=a.output,
                     dofmap=a.map, bands=bands, max_iter=a.max_iter, geometry=a.geometry, same_ids=a.same_ids,
                     freq_window=a.freq_window, freq_sigma=a.freq_sigma)
    if s.get("note"):
        _print(s["note"])
    if "table_before" in s:
        _print("before:\n" + s["table_before"])
        _print("after:\n" + s["table_after"])
    for name, v in (s.get("parameters") or {}).items():
        sd = "" if v["std"] is None else f" ± {v['std']:.3g}"
        _print(f"{name:>20}: {v['initial']:.4g} -> {v['updated']:.4g}{sd}")
    idf = s.get("identifiability")
    if idf:
        un = ", ".join(f"{k} ± {v:.3g}" if v is not None else f"{k} ± inf"
                       for k, v in idf["std_unregularised"].items())
        _print(f"condition number {idf['condition_number']:.3g}; unregularised std: {un}; frequency weights: "
               f"{idf['frequency_weights']}")
        if not idf["identifiable"]:
            _print("WARNING: the parameters are not identifiable from these data (condition number above 1e3): the "
                   "regularised ± above reflect the regularisation, not the data")
    _print(f"results in {a.output}")
    return 0


def register(sub):
    s = sub.add_parser("update", help="update an FE model to test modes or FRFs")
    s.add_argument("model", help="FE model as Nastran bulk data (.bdf)")
    g = s.add_mutually_exclusive_group(required=True)
    g.add_argument("--modes", help="test modes (UFF dataset 55 or JSON from 'modalab identify')")
    g.add_argument("--frf", help="measured FRFs (UFF dataset 58) for mci / rfm")
    s.add_argument("--method", default="eigensensitivity", choices=MODAL + FRF_METHODS + DIRECT,
                   help="updating method (default eigensensitivity)")
    s.add_argument("--params", help="TOML file of [[parameter]] entries (default: E and rho multipliers per "
                                    "property group)")
    from ._cli_correlate import add_map_arguments

    add_map_arguments(s)
    s.add_argument("--freq-sigma", type=float, nargs="+",
                   help="relative standard deviation of each test frequency (one value, or one per mode); default: "
                        "the covariance stored with the modes, else 1 %%")
    s.add_argument("--band", nargs=2, type=float, action="append", metavar=("LO", "HI"),
                   help="updating band in Hz for mci/rfm (repeatable)")
    s.add_argument("--max-iter", type=int, default=30, help="iteration limit (default 30)")
    s.add_argument("-o", "--output", required=True, help="output folder (updated.bdf, update.json, figures)")
    s.set_defaults(func=cmd_update)
