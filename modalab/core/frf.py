"""The labelled FRF container.

``H`` has shape ``(n_out, n_in, n_freq)``: responses along axis 0, references
(inputs, forces) along axis 1, frequency lines along axis 2.  The container
carries the frequency axis in Hz, the DOF labels of both axes, optional
ordinary coherence of the same shape, the physical quantity and free-form
metadata that later stages read.

Typed fields besides the data
    ``window_beta_per_s`` — the decay rate β (1/s) of an exponential window
    ``e^{−βt}`` applied to the records (0 = none).  A windowed FRF is the
    transfer function evaluated at ``s = iω + β`` (:attr:`FRF.s`), so the
    quantity conversion (:meth:`FRF.to`) and every model FRF compared with it
    use ``s``; identification moves the poles back by β
    (:func:`acquisition.windows.correct_poles`).
    ``variance`` — the variance of the estimate on every line, ``E|Ĥ − H|²``
    (real, H's shape, e.g. across averages) or None; :meth:`FRF.select`,
    :meth:`FRF.band`, :meth:`FRF.transpose`, :meth:`FRF.to` and :func:`concat`
    carry it with the data.

``metadata`` keys used by modalab
    ``estimator`` ('H1', 'H2', 'Hv', 'exact'), ``n_averages`` (int),
    ``force_window`` (dict), ``source`` (free text).  The former keys
    ``exp_window_beta`` and ``H_variance`` are read and written through to the
    typed fields (with a DeprecationWarning): they are never stored twice.
"""
from __future__ import annotations

import copy
import warnings
from typing import Sequence

import numpy as np

from .dof import Dof, locate, parse_dofs
from .errors import ShapeError, ModalabValueError
from .units import QUANTITY_UNITS, check_quantity

__all__ = ["FRF", "concat", "check_window_beta", "ROVING_RATIO", "roving_hammer_layout"]

#: an FRF with at least this many times more references than responses (and at least 2 references)
#: is a roving-hammer export: fixed accelerometers as responses, the hammer points as references
ROVING_RATIO = 2


def roving_hammer_layout(n_references: int, n_responses: int) -> bool:
    """True when ``n_references`` references (inputs) and ``n_responses`` responses (outputs) are a roving-hammer
    export's layout: ``n_references >= ROVING_RATIO · n_responses`` and ``n_references >= 2`` (3 hit points x 1
    accelerometer is a roving-hammer test too).  The one rule of ``identify`` (which transposes such a file by
    reciprocity), ``info`` and ``correlate`` (modes identified from such a file without transposing it)."""
    return n_references >= ROVING_RATIO * n_responses and n_references >= 2

_ORDER = {"receptance": 0, "mobility": 1, "accelerance": 2}
#: former metadata keys -> typed FRF attributes
_LEGACY = {"exp_window_beta": "window_beta_per_s", "H_variance": "variance"}


def _legacy_warning(key):
    warnings.warn(f"FRF.metadata[{key!r}] is deprecated: use FRF.{_LEGACY[key]}", DeprecationWarning, stacklevel=3)


class _Metadata(dict):
    """``FRF.metadata``: a dict whose former keys ``exp_window_beta``/``H_variance`` are the typed fields.

    Reading or writing one of them reads or sets the FRF's attribute (with a DeprecationWarning);
    the dict itself never holds them, so there is one value, typed, and no stale copy.
    """

    def __init__(self, owner, items=()):
        super().__init__()
        self._owner = owner
        self.update(items)

    def __setitem__(self, key, value):
        if key in _LEGACY:
            _legacy_warning(key)
            self._owner._set_legacy(key, value)
        else:
            super().__setitem__(key, value)

    def __getitem__(self, key):
        if key in _LEGACY:
            _legacy_warning(key)
            v = getattr(self._owner, _LEGACY[key])
            if v is None:
                raise KeyError(key)
            return v
        return super().__getitem__(key)

    def __contains__(self, key):
        if key in _LEGACY:
            return getattr(self._owner, _LEGACY[key]) is not None
        return super().__contains__(key)

    def get(self, key, default=None):
        return self[key] if key in self else default

    def setdefault(self, key, default=None):
        if key in _LEGACY:
            if key not in self or (key == "exp_window_beta" and self._owner.window_beta_per_s == 0.0):
                if default is not None:
                    self[key] = default
            return self.get(key)
        return super().setdefault(key, default)

    def pop(self, key, *default):
        if key in _LEGACY:
            v = self.get(key, *default[:1])
            self._owner._set_legacy(key, None)
            return v
        return super().pop(key, *default)

    def update(self, *args, **kw):
        for k, v in dict(*args, **kw).items():
            self[k] = v

    def copy(self):
        return dict(self)

    def __deepcopy__(self, memo):
        return copy.deepcopy(dict(self), memo)

    def __reduce__(self):
        return (dict, (dict(self),))


def check_window_beta(beta) -> float:
    """The exponential window's decay rate β (1/s) as a float: a finite number >= 0 (0 = no window).  The one
    check of β, for an FRF's ``window_beta_per_s`` and for every model FRF evaluated at ``s = iω + β``."""
    try:
        if isinstance(beta, (bool, str, bytes)):      # float() would take True and "2"
            raise TypeError
        b = float(beta)
    except (TypeError, ValueError):
        raise ModalabValueError(f"window_beta_per_s={beta!r} must be a number: the exponential window's decay "
                                "rate in 1/s (0 = no window)") from None
    if not np.isfinite(b) or b < 0:
        raise ModalabValueError(f"window_beta_per_s={beta!r} must be finite and >= 0 (the exponential window's "
                                "decay rate in 1/s; 0 = no window)")
    return b


class FRF:
    """Frequency-response functions with labels.

    Build with keywords or :meth:`from_arrays`; read files with :meth:`from_uff`.

    >>> import numpy as np
    >>> f = FRF(freq_hz=np.arange(4.0), H=np.ones((2, 1, 4)), responses=["1+Z", "2+Z"], references=["1+Z"])
    >>> f.select(responses=["2-Z"]).H[0, 0, 0]
    (-1+0j)
    """

    def __init__(self, *, freq_hz, H, responses, references, coherence=None,
                 quantity: str = "accelerance", units: str | None = None, metadata: dict | None = None,
                 window_beta_per_s: float | None = None, variance=None):
        freq = np.asarray(freq_hz, dtype=float)
        if freq.ndim != 1:
            raise ShapeError(f"freq_hz must be 1-D; got shape {freq.shape}. Pass the frequency lines in Hz")
        if freq.size > 1 and np.any(np.diff(freq) <= 0):
            raise ModalabValueError("freq_hz must increase strictly; sort the lines (np.argsort) before building an FRF")
        Hc = np.asarray(H)
        if not np.iscomplexobj(Hc):
            Hc = Hc.astype(complex)
        if Hc.ndim != 3:
            raise ShapeError(f"H must have shape (n_out, n_in, n_freq); got {Hc.shape}. "
                             "Use H[:, None, :] for a single reference")
        resp, ref = parse_dofs(responses), parse_dofs(references)
        want = (len(resp), len(ref), freq.size)
        if Hc.shape != want:
            raise ShapeError(f"H has shape {Hc.shape} but the labels and freq_hz call for {want} "
                             "(n_responses, n_references, n_freq)")
        coh = None
        if coherence is not None:
            coh = np.asarray(coherence, dtype=float)
            if coh.shape != want:
                raise ShapeError(f"coherence has shape {coh.shape}; expected {want} like H")
        for name, labels in (("responses", resp), ("references", ref)):
            if len({(d.node, d.axis) for d in labels}) != len(labels):
                raise ModalabValueError(f"duplicate DOF labels in {name}: {[str(d) for d in labels]}; "
                                        "each DOF may appear once per axis")
        self.freq_hz = freq
        self.H = Hc
        self.responses: list[Dof] = resp
        self.references: list[Dof] = ref
        self.coherence = coh
        self.quantity = check_quantity(quantity)
        self.units = units or QUANTITY_UNITS[self.quantity]
        meta = dict(metadata or {})
        # the former metadata keys fill the typed fields when those are not given
        legacy_beta = meta.pop("exp_window_beta", None)
        legacy_var = meta.pop("H_variance", None)
        if window_beta_per_s is None:
            window_beta_per_s = 0.0 if legacy_beta is None else legacy_beta
        if variance is None:
            variance = legacy_var
        self.window_beta_per_s = window_beta_per_s
        self.variance = variance
        self.metadata = meta

    # ------------------------------------------------------------ typed fields
    @property
    def metadata(self) -> dict:
        """Free-form metadata (``estimator``, ``n_averages``, ``force_window``, ``source``...)."""
        return self._metadata

    @metadata.setter
    def metadata(self, value):
        self._metadata = _Metadata(self, value or {})

    @property
    def window_beta_per_s(self) -> float:
        """Decay rate β (1/s) of the exponential window the data were taken with; 0 = none (checked: finite, >= 0)."""
        return self._beta

    @window_beta_per_s.setter
    def window_beta_per_s(self, value):
        self._beta = check_window_beta(value)

    @property
    def variance(self):
        """``E|Ĥ − H|²`` per line (real, H's shape, >= 0) or None (checked on assignment)."""
        return self._variance

    @variance.setter
    def variance(self, value):
        self._variance = self._check_variance(value)

    def _set_legacy(self, key, value):
        if key == "exp_window_beta":
            self.window_beta_per_s = 0.0 if value is None else value
        else:
            self.variance = value

    def _check_variance(self, variance):
        if variance is None:
            return None
        try:
            v = np.asarray(variance, dtype=float)
        except (TypeError, ValueError):
            raise ModalabValueError(f"FRF variance must be a real array of shape {self.H.shape} like H; got "
                                    f"{type(variance).__name__}. Store E|H_k - mean H|^2 over the averages") from None
        if v.shape != self.H.shape:
            raise ShapeError(f"FRF variance has shape {v.shape}; expected {self.H.shape} (n_out, n_in, n_freq) "
                             "like H. Store one variance per FRF line (or none)")
        bad = ~np.isfinite(v) | (v < 0)
        if bad.any():
            idx = tuple(int(k) for k in np.argwhere(bad)[0])
            raise ModalabValueError(
                f"FRF variance holds {int(bad.sum())} negative or non-finite value(s), the first "
                f"{float(v[idx])!r} at (response, reference, line) {idx}; expected variances >= 0. "
                "Store E|H_k - mean H|^2 over the averages")
        return v

    @property
    def s(self) -> np.ndarray:
        """The Laplace variable of every line, ``s = iω + β`` (β = :attr:`window_beta_per_s`).

        An exponential window ``e^{−βt}`` turns the transform of a response into the transfer
        function at ``iω + β``; a model FRF compared with windowed data is evaluated there.
        """
        return 1j * self.omega + self.window_beta_per_s

    # ------------------------------------------------------------ construction
    @classmethod
    def from_arrays(cls, freq_hz, H, responses, references, coherence=None, **kw) -> "FRF":
        """Build from arrays; a 2-D ``H`` (n_out, n_freq) is taken as a single reference."""
        Ha = np.asarray(H)
        if Ha.ndim == 2:
            Ha = Ha[:, None, :]
            if coherence is not None and np.ndim(coherence) == 2:
                coherence = np.asarray(coherence)[:, None, :]
        elif Ha.ndim == 1:
            Ha = Ha[None, None, :]
            if coherence is not None and np.ndim(coherence) == 1:
                coherence = np.asarray(coherence)[None, None, :]
        return cls(freq_hz=freq_hz, H=Ha, responses=responses, references=references,
                   coherence=coherence, **kw)

    # ``FRF.from_uff`` and ``FRF.to_uff`` are defined with the reader in :mod:`modalab.core._uff_frf` and
    # attached there (the file format depends on the container, not the reverse); importing
    # :mod:`modalab.core` always attaches them.

    def copy(self) -> "FRF":
        return copy.deepcopy(self)

    def __deepcopy__(self, memo):
        new = FRF.__new__(FRF)
        memo[id(self)] = new
        for k, v in self.__dict__.items():
            if k != "_metadata":
                new.__dict__[k] = copy.deepcopy(v, memo)
        new.metadata = copy.deepcopy(dict(self._metadata), memo)
        return new

    def __getstate__(self):
        state = dict(self.__dict__)
        state["_metadata"] = dict(self._metadata)
        return state

    def __setstate__(self, state):
        meta = state.pop("_metadata", {})
        self.__dict__.update(state)
        self.metadata = meta

    def _replace(self, **kw) -> "FRF":
        """A new FRF with some fields replaced.  New ``H`` or ``freq_hz`` without a ``variance`` drops the
        variance (it described the old data)."""
        args = dict(freq_hz=self.freq_hz, H=self.H, responses=self.responses, references=self.references,
                    coherence=self.coherence, quantity=self.quantity, units=self.units,
                    metadata=copy.deepcopy(dict(self.metadata)), window_beta_per_s=self.window_beta_per_s,
                    variance=None if ("H" in kw or "freq_hz" in kw) else self.variance)
        args.update(kw)
        return FRF(**args)

    # ------------------------------------------------------------ properties
    @property
    def shape(self) -> tuple[int, int, int]:
        return self.H.shape

    @property
    def n_out(self) -> int:
        return self.H.shape[0]

    @property
    def n_in(self) -> int:
        return self.H.shape[1]

    @property
    def n_freq(self) -> int:
        return self.H.shape[2]

    @property
    def omega(self) -> np.ndarray:
        """Frequency lines in rad/s."""
        return 2 * np.pi * self.freq_hz

    def __repr__(self) -> str:
        fr = f"{self.freq_hz[0]:.4g}-{self.freq_hz[-1]:.4g} Hz" if self.n_freq else "empty"
        return (f"FRF({self.n_out} responses x {self.n_in} references x {self.n_freq} lines, {fr}, "
                f"{self.quantity} [{self.units}], coherence={'yes' if self.coherence is not None else 'no'})")

    # ------------------------------------------------------------ selection
    def get(self, response, reference) -> np.ndarray:
        """One FRF as a 1-D complex array; a label of opposite sign negates it."""
        (i,), (si,) = locate(self.responses, [response], "response DOF")
        (j,), (sj,) = locate(self.references, [reference], "reference DOF")
        return si * sj * self.H[i, j]

    def select(self, responses=None, references=None) -> "FRF":
        """Sub-set by DOF labels, in the order given; opposite signs negate the data."""
        ii, si = (list(range(self.n_out)), [1] * self.n_out) if responses is None else \
            locate(self.responses, responses, "response DOF")
        jj, sj = (list(range(self.n_in)), [1] * self.n_in) if references is None else \
            locate(self.references, references, "reference DOF")
        sign = np.outer(si, sj)[:, :, None]
        H = self.H[np.ix_(ii, jj)] * sign
        coh = None if self.coherence is None else self.coherence[np.ix_(ii, jj)]
        rl = list(self.responses) if responses is None else parse_dofs(responses)
        rf = list(self.references) if references is None else parse_dofs(references)
        var = None if self.variance is None else self.variance[np.ix_(ii, jj)]
        return self._replace(H=H, coherence=coh, responses=rl, references=rf, variance=var)

    def band(self, lo_hz: float | None = None, hi_hz: float | None = None) -> "FRF":
        """Lines with ``lo_hz <= f <= hi_hz``."""
        lo = -np.inf if lo_hz is None else float(lo_hz)
        hi = np.inf if hi_hz is None else float(hi_hz)
        if lo >= hi:
            raise ModalabValueError(f"band {lo_hz}..{hi_hz} Hz is empty; give LO < HI")
        m = (self.freq_hz >= lo) & (self.freq_hz <= hi)
        if not m.any():
            raise ModalabValueError(f"no frequency lines in {lo_hz}..{hi_hz} Hz; the data spans "
                                    f"{self.freq_hz[0]:.4g}..{self.freq_hz[-1]:.4g} Hz")
        return self.lines(m)

    def lines(self, mask) -> "FRF":
        """The lines where the boolean ``mask`` (n_freq,) is True, with coherence and variance."""
        m = np.asarray(mask, bool)
        if m.shape != self.freq_hz.shape:
            raise ShapeError(f"line mask has shape {m.shape}; expected ({self.n_freq},) like freq_hz")
        coh = None if self.coherence is None else self.coherence[..., m]
        var = None if self.variance is None else self.variance[..., m]
        return self._replace(freq_hz=self.freq_hz[m], H=self.H[..., m], coherence=coh, variance=var)

    def transpose(self) -> "FRF":
        """Swap responses and references: H_ij -> H_ji (Maxwell reciprocity)."""
        coh = None if self.coherence is None else self.coherence.transpose(1, 0, 2)
        var = None if self.variance is None else self.variance.transpose(1, 0, 2)
        return self._replace(H=self.H.transpose(1, 0, 2), coherence=coh, variance=var,
                             responses=self.references, references=self.responses)

    def to(self, quantity: str) -> "FRF":
        """Convert to receptance, mobility or accelerance exactly: ``H·s^k`` with ``s = iω + β`` (:attr:`s`).

        With an exponential window (β > 0) the data are transfer functions at ``iω + β``, so the
        factor is ``(iω + β)^k``, not ``(iω)^k`` (which would leave an error of order ``kβ/ω``).
        NaN where undefined (s = 0).  The variance scales by ``|s^k|²``.
        """
        q = check_quantity(quantity)
        if q == self.quantity:
            return self.copy()
        n = _ORDER[q] - _ORDER[self.quantity]
        s = self.s
        with np.errstate(divide="ignore", invalid="ignore"):
            fac = s ** n if n >= 0 else 1.0 / s ** (-n)
        fac = np.where(np.isfinite(fac), fac, np.nan + 0j)
        var = None if self.variance is None else self.variance * np.abs(fac) ** 2
        return self._replace(H=self.H * fac, quantity=q, units=QUANTITY_UNITS[q], variance=var)

    def real_part_sum(self) -> np.ndarray:
        """Sum of |H| over all FRFs (a quick mode indicator)."""
        return np.abs(self.H).reshape(-1, self.n_freq).sum(axis=0)

    def cmif(self, k: int | None = None) -> np.ndarray:
        """Complex mode indicator function: singular values of H(ω), shape (min(n_out, n_in), n_freq)."""
        s = np.linalg.svd(self.H.transpose(2, 0, 1), compute_uv=False)
        return s.T if k is None else s.T[:k]


def concat(frfs: Sequence[FRF], axis: str = "responses") -> FRF:
    """Concatenate FRFs along ``'responses'`` or ``'references'``; frequency axes must agree."""
    if not frfs:
        raise ModalabValueError("concat needs at least one FRF")
    first = frfs[0]
    ax = {"responses": 0, "references": 1}.get(axis)
    if ax is None:
        raise ModalabValueError(f"axis {axis!r} unknown; use 'responses' or 'references'")
    for f in frfs[1:]:
        if f.freq_hz.shape != first.freq_hz.shape or not np.allclose(f.freq_hz, first.freq_hz, rtol=1e-9, atol=1e-12):
            raise ShapeError("frequency axes differ; resample or band-select to common lines before concatenating")
        if f.quantity != first.quantity:
            f = f.to(first.quantity)
        other = f.references if ax == 0 else f.responses
        mine = first.references if ax == 0 else first.responses
        if [(d.node, d.axis) for d in other] != [(d.node, d.axis) for d in mine]:
            raise ShapeError(f"the {'references' if ax == 0 else 'responses'} differ between the FRFs; "
                             "select common DOFs first")
        if not np.isclose(f.window_beta_per_s, first.window_beta_per_s, rtol=1e-9, atol=0.0):
            raise ModalabValueError(f"the FRFs were measured with different exponential windows (beta "
                                    f"{first.window_beta_per_s:g} and {f.window_beta_per_s:g} 1/s); they are "
                                    "transfer functions at different s = i*omega + beta and cannot be joined. "
                                    "Use one window for the whole set")
    conv = [f if f.quantity == first.quantity else f.to(first.quantity) for f in frfs]
    # align signs of the shared axis with the first FRF
    aligned = []
    for f in conv:
        if ax == 0:
            aligned.append(f.select(references=first.references))
        else:
            aligned.append(f.select(responses=first.responses))
    H = np.concatenate([f.H for f in aligned], axis=ax)
    coh = None
    if all(f.coherence is not None for f in aligned):
        coh = np.concatenate([f.coherence for f in aligned], axis=ax)
    var = None
    if all(f.variance is not None for f in aligned):
        var = np.concatenate([f.variance for f in aligned], axis=ax)
    labels = sum([(f.responses if ax == 0 else f.references) for f in aligned], [])
    kw = {"responses": labels} if ax == 0 else {"references": labels}
    return first._replace(H=H, coherence=coh, variance=var, **kw)
