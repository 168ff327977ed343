"""The :class:`ModeSet` container: identified or computed modes on DOF labels.

Identification produces it, correlation and updating consume it.  Shapes are
stored per DOF label (rows) and mode (columns).  Complex shapes are kept as
identified; :attr:`ModeSet.real_shapes` gives the real (normal-mode)
approximation.  A mode set is *mass-normalised* when ``scaling ==
'unit_modal_mass'``.
"""
from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np

from ._output import write_json
from .dof import Dof, locate, parse_dofs
from .errors import ModalabError, ModalabValueError, ShapeError

__all__ = ["ModeSet", "real_mode_approximation"]


def real_mode_approximation(shapes: np.ndarray) -> np.ndarray:
    """Best real approximation of complex shapes: rotate each column so that the
    imaginary part is least-squares minimal, keep the real part.

    The rotation angle θ minimises ‖Im(e^{-iθ}φ)‖², which is half the angle of
    Σφ² (closed form); the sign is chosen so that the largest entry is positive.
    """
    phi = np.atleast_2d(np.asarray(shapes))
    if phi.ndim != 2:
        raise ShapeError(f"shapes must be (n_dof, n_modes); got {phi.shape}")
    if not np.iscomplexobj(phi):
        return phi.astype(float).copy()
    theta = 0.5 * np.angle(np.sum(phi * phi, axis=0))
    real = np.real(phi * np.exp(-1j * theta)[None, :])
    k = np.argmax(np.abs(real), axis=0)
    sgn = np.sign(real[k, np.arange(real.shape[1])])
    sgn[sgn == 0] = 1
    return real * sgn[None, :]


class ModeSet:
    """Modes: natural frequencies (Hz), damping ratios, shapes on DOF labels.

    Parameters (keyword-only)
    ----------
    freq_hz : (n_modes,) undamped natural frequencies in Hz.
    damping : (n_modes,) viscous damping ratios ζ (fraction of critical).
    shapes : (n_dof, n_modes) real or complex shapes, or None for a *frequency-only* set
        (no DOFs: ``has_shapes`` is False, correlation pairs such a set by frequency order).
    dofs : DOF labels of the rows (empty or None without shapes).
    freq_cov : optional (n_modes, n_modes) covariance of ``freq_hz`` in Hz² (per-mode σ on the
        diagonal, correlations between modes off it); see :meth:`from_repeats` and :attr:`freq_std_hz`.
    coordinates : optional {node: (x, y, z)} in m of the test nodes (for mapping onto a model by geometry).
    participation : optional (n_ref, n_modes) modal participation factors.
    references : DOF labels of the participation rows.
    scaling : 'unit_modal_mass', 'unit_max' or 'arbitrary'.
    indicators : dict of per-mode arrays (MPC, MPD, MCF, ...).
    metadata : free-form dict.
    """

    def __init__(self, *, freq_hz, damping=None, shapes=None, dofs=None, participation=None, references=None,
                 scaling: str = "arbitrary", indicators: dict | None = None, metadata: dict | None = None,
                 freq_cov=None, coordinates: dict | None = None):
        f = np.atleast_1d(np.asarray(freq_hz, dtype=float))
        if f.ndim != 1:
            raise ShapeError(f"freq_hz must be 1-D; got {f.shape}")
        z = np.zeros_like(f) if damping is None else np.atleast_1d(np.asarray(damping, dtype=float))
        if z.shape != f.shape:
            raise ShapeError(f"damping has shape {z.shape}; expected {f.shape} like freq_hz")
        d = parse_dofs(dofs) if dofs is not None else []
        if shapes is None or (np.size(shapes) == 0 and not d):
            if d:
                raise ShapeError(f"{len(d)} DOF labels but no shapes; give shapes of shape ({len(d)}, {f.size}) or "
                                 "no DOFs for a frequency-only mode set")
            phi = np.zeros((0, f.size))
        else:
            phi = np.asarray(shapes)
            if phi.ndim == 1:
                phi = phi[:, None]
            if phi.shape != (len(d), f.size):
                raise ShapeError(f"shapes have shape {phi.shape}; expected ({len(d)}, {f.size}) = (n_dof, n_modes) "
                                 f"for {f.size} frequencies on {len(d)} DOF labels (a frequency-only set has no "
                                 "shapes and no DOFs: shapes=None)")
        if participation is not None:
            participation = np.asarray(participation)
            if participation.ndim != 2 or participation.shape[1] != f.size:
                raise ShapeError(f"participation must be (n_ref, {f.size}); got {participation.shape}")
        self.freq_hz = f
        self.damping = z
        self.shapes = phi
        self.dofs: list[Dof] = d
        self.participation = participation
        self.references = parse_dofs(references) if references is not None else None
        if scaling not in ("unit_modal_mass", "unit_max", "arbitrary"):
            raise ModalabValueError(f"scaling {scaling!r}; expected 'unit_modal_mass', 'unit_max' or 'arbitrary'")
        self.scaling = scaling
        self.indicators = {k: np.asarray(v) for k, v in (indicators or {}).items()}
        self.metadata = dict(metadata or {})
        self.freq_cov = None
        if freq_cov is not None:
            c = np.atleast_2d(np.asarray(freq_cov, dtype=float))
            if c.shape == (1, f.size) or c.shape == (f.size, 1):
                c = np.diag(c.ravel())
            if c.shape != (f.size, f.size):
                raise ShapeError(f"freq_cov has shape {c.shape}; expected ({f.size}, {f.size}) (Hz²) or {f.size} "
                                 "variances")
            if not np.all(np.isfinite(c)) or not np.allclose(c, c.T, rtol=1e-10, atol=0):
                raise ModalabValueError("freq_cov must be a finite symmetric covariance matrix (Hz²)")
            ev = np.linalg.eigvalsh(c)
            if ev.min(initial=0) < -1e-12 * max(ev.max(initial=0), 1e-300):
                raise ModalabValueError("freq_cov is not positive semi-definite; give a covariance matrix")
            self.freq_cov = c
        self.coordinates = {int(k): tuple(float(x) for x in v) for k, v in (coordinates or {}).items()}

    @classmethod
    def from_repeats(cls, freqs_hz, **kw) -> "ModeSet":
        """A frequency-only set from repeated identifications ``(n_repeats, n_modes)`` (Hz).

        ``freq_hz`` is the mean and ``freq_cov`` the covariance *of the mean*
        (sample covariance / n_repeats, correlations between modes kept).
        """
        F = np.asarray(freqs_hz, dtype=float)
        if F.ndim != 2 or F.shape[0] < 2:
            raise ShapeError(f"repeats have shape {F.shape}; expected (n_repeats >= 2, n_modes)")
        if not np.all(np.isfinite(F)):
            raise ModalabValueError("repeated frequencies contain NaN or inf")
        cov = np.atleast_2d(np.cov(F, rowvar=False)) / F.shape[0]
        md = dict(kw.pop("metadata", None) or {})
        md.setdefault("n_repeats", int(F.shape[0]))
        return cls(freq_hz=F.mean(axis=0), freq_cov=cov, metadata=md, **kw)

    # ----------------------------------------------------------- properties
    @property
    def has_shapes(self) -> bool:
        """False for a frequency-only set (no DOFs)."""
        return self.n_dof > 0

    @property
    def freq_std_hz(self) -> np.ndarray | None:
        """Per-mode standard deviation of the frequencies (Hz), from ``freq_cov``, or None."""
        return None if self.freq_cov is None else np.sqrt(np.clip(np.diag(self.freq_cov), 0, None))
    @property
    def n_modes(self) -> int:
        return self.freq_hz.size

    @property
    def n_dof(self) -> int:
        return len(self.dofs)

    @property
    def omega(self) -> np.ndarray:
        return 2 * np.pi * self.freq_hz

    @property
    def poles(self) -> np.ndarray:
        """Upper-half-plane poles λ = −ζω_n + iω_n√(1−ζ²) in rad/s."""
        w, z = self.omega, self.damping
        return -z * w + 1j * w * np.sqrt(np.clip(1 - z ** 2, 0, None))

    @property
    def real_shapes(self) -> np.ndarray:
        return real_mode_approximation(self.shapes)

    def __len__(self) -> int:
        return self.n_modes

    def __repr__(self) -> str:
        fr = ", ".join(f"{v:.4g}" for v in self.freq_hz[:8]) + (" ..." if self.n_modes > 8 else "")
        return f"ModeSet({self.n_modes} modes on {self.n_dof} DOFs: {fr} Hz)"

    def copy(self) -> "ModeSet":
        return copy.deepcopy(self)

    # ------------------------------------------------------------ selection
    def select_dofs(self, dofs) -> "ModeSet":
        """Rows for the given labels in that order; opposite sign negates."""
        idx, sgn = locate(self.dofs, dofs, "mode-shape DOF")
        out = self.copy()
        out.shapes = self.shapes[idx].reshape(len(idx), self.n_modes) * np.asarray(sgn, float).reshape(-1, 1)
        out.dofs = parse_dofs(dofs)
        return out

    def select_modes(self, index) -> "ModeSet":
        """Modes by integer index or boolean mask."""
        idx = np.arange(self.n_modes)[index]
        idx = np.atleast_1d(idx)
        out = self.copy()
        out.freq_hz, out.damping = self.freq_hz[idx], self.damping[idx]
        if self.freq_cov is not None:
            out.freq_cov = self.freq_cov[np.ix_(idx, idx)]
        out.shapes = self.shapes[:, idx]
        if self.participation is not None:
            out.participation = self.participation[:, idx]
        out.indicators = {k: (v[idx] if np.ndim(v) >= 1 and len(v) == self.n_modes else v)
                          for k, v in self.indicators.items()}
        return out

    # ------------------------------------------------------------------ I/O
    def to_dict(self) -> dict:
        """JSON-ready summary (complex shapes as [re, im] pairs)."""
        def enc(a):
            a = np.asarray(a)
            if np.iscomplexobj(a):
                return {"re": a.real.tolist(), "im": a.imag.tolist()}
            return a.tolist()
        return {
            "freq_hz": self.freq_hz.tolist(), "damping": self.damping.tolist(),
            "dofs": [str(d) for d in self.dofs], "shapes": enc(self.shapes),
            "participation": None if self.participation is None else enc(self.participation),
            "references": None if self.references is None else [str(d) for d in self.references],
            "scaling": self.scaling, "indicators": {k: enc(v) for k, v in self.indicators.items()},
            "metadata": self.metadata,
            "freq_cov_hz2": None if self.freq_cov is None else self.freq_cov.tolist(),
            "coordinates": {str(k): list(v) for k, v in self.coordinates.items()} or None,
        }

    @classmethod
    def from_dict(cls, d: dict) -> "ModeSet":
        def dec(a):
            if a is None:
                return None
            if isinstance(a, dict) and "re" in a:
                return np.asarray(a["re"]) + 1j * np.asarray(a["im"])
            return np.asarray(a)
        if not isinstance(d, dict) or ("freq_hz" not in d and "freq_repeats_hz" not in d):
            raise ModalabValueError("a mode set needs at least 'freq_hz' (list of Hz); optional 'shapes' and 'dofs' "
                                    "(omit both for a frequency-only set), 'freq_std_hz' or 'freq_cov_hz2', "
                                    "'freq_repeats_hz'")
        cov = d.get("freq_cov_hz2")
        if cov is None and d.get("freq_std_hz") is not None:
            cov = np.diag(np.asarray(d["freq_std_hz"], float) ** 2)
        if d.get("freq_repeats_hz") is not None:
            rep = cls.from_repeats(d["freq_repeats_hz"])
            if cov is None:
                cov = rep.freq_cov
            freq = d["freq_hz"] if d.get("freq_hz") is not None else rep.freq_hz
        else:
            freq = d["freq_hz"]
        return cls(freq_hz=freq, damping=d.get("damping"), shapes=dec(d.get("shapes")), dofs=d.get("dofs"),
                   participation=dec(d.get("participation")), references=d.get("references"),
                   scaling=d.get("scaling", "arbitrary"),
                   indicators={k: dec(v) for k, v in (d.get("indicators") or {}).items()},
                   metadata=d.get("metadata"), freq_cov=cov, coordinates=d.get("coordinates"))

    def table(self) -> list:
        """One row per mode: ``mode`` (from 1), ``freq_hz``, ``damping_pct`` and every scalar indicator (the
        ``table`` of ``modes.json`` and of the report)."""
        rows = []
        for k in range(self.n_modes):
            r = {"mode": k + 1, "freq_hz": float(self.freq_hz[k]),
                 "damping_pct": 100 * float(self.damping[k]) if self.damping is not None else None}
            for name, v in self.indicators.items():
                try:
                    r[name] = float(np.asarray(v)[k])
                except (TypeError, ValueError, IndexError):
                    pass
            rows.append(r)
        return rows

    def to_json(self, path, *, input=None, extra: dict | None = None) -> Path:
        """Write ``modes.json``, the one writer of that layout (schema ``modalab/app/schemas/modes.schema.json``):
        ``input`` (the file the modes came from, or None), ``table`` (:meth:`table`), the :meth:`to_dict` keys and
        the keys of ``extra`` (e.g. the identification's settings).  Atomic, never over an input
        (:mod:`modalab.core._output`); :meth:`from_json` reads it back.  Returns the path."""
        doc = {"input": None if input is None else str(input), "table": self.table(), **self.to_dict()}
        clash = set(doc) & set(extra or {})
        if clash:
            raise ModalabValueError(f"extra keys {sorted(clash)} would replace the mode set's own; use other names")
        return write_json(path, {**doc, **(extra or {})})

    @classmethod
    def from_json(cls, path) -> "ModeSet":
        """A mode set from JSON: :meth:`to_json` output (``modes.json``; ``modalab identify --json`` writes it) or
        a document holding such a set under ``modes``.  A file that is not such JSON raises :class:`~modalab.core.errors.ModalabValueError`
        naming it."""

        try:
            with open(path, "rb") as fh:
                d = json.loads(fh.read().decode("utf-8"))
        except OSError as e:
            raise ModalabValueError(f"cannot read modes file '{path}': {e.strerror or e}; check the path") from None
        except (UnicodeDecodeError, ValueError) as e:
            raise ModalabValueError(f"'{path}' is not valid JSON ({e}); the file is truncated or not JSON. Expected "
                                    "the modes JSON 'modalab identify --json' writes") from None
        if isinstance(d, dict) and "freq_hz" not in d and isinstance(d.get("modes"), dict):
            d = d["modes"]
        if isinstance(d, dict) and "freq_hz" not in d:
            other = ("a correlation (the JSON 'modalab correlate --json' writes)" if {"mac", "pairing"} <= set(d)
                     else "a diagnosis (the JSON 'modalab diagnose --json' writes)" if {"findings", "fit"} <= set(d)
                     else None)
            if other:
                raise ModalabValueError(f"'{path}' does not hold a mode set: it is {other}. Expected the modes JSON "
                                        "'modalab identify --json' writes (run identify again if it was overwritten)")
        try:
            return cls.from_dict(d)
        except (ModalabError, KeyError, TypeError, ValueError, AttributeError) as e:
            what = f"lacks the key {e.args[0]!r}" if isinstance(e, KeyError) else f"is inconsistent ({e})"
            raise ModalabValueError(f"'{path}' does not hold a mode set: it {what}. Expected the modes JSON "
                                    "'modalab identify --json' writes") from None

    # ``ModeSet.from_uff`` and ``ModeSet.to_uff`` are defined with the reader in :mod:`modalab.core._uff_modes`
    # and attached there (the file format depends on the container, not the reverse); importing
    # :mod:`modalab.core` always attaches them.
