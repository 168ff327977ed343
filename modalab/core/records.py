"""Raw time records of hammer hits.

A :class:`TimeRecord` is one triggered record of all channels: one hit.  Data
are in engineering units (N for force, m/s² for acceleration) after the
sensor sensitivity has been applied; ``sensitivity`` keeps the V/unit value
the channel used so the raw voltage can be recovered.
"""
from __future__ import annotations

import copy
from typing import Sequence

import numpy as np

from .dof import Dof, parse_dofs
from .errors import ModalabValueError, ShapeError

__all__ = ["TimeRecord", "ROLES"]

ROLES = ("force", "response")


class TimeRecord:
    """One hit: ``data`` of shape ``(n_channels, n_samples)`` sampled at ``sample_rate_hz``.

    Parameters (keyword-only)
    ----------
    sample_rate_hz : sampling rate in Hz.
    data : (n_channels, n_samples) float array in engineering units.
    dofs : DOF label per channel (the hammer's DOF for the force channel).
    roles : 'force' or 'response' per channel.
    units : unit string per channel ('N', 'm/s^2').
    sensitivity : V per engineering unit per channel (default 1).
    trigger_index : sample index of the trigger (the number of pretrigger samples).
    overload : bool per channel, True when the channel clipped or the device flagged overload.
    hit_id : number of the hit in its session (UFF ``load_case_id``).
    metadata : free-form dict.  Keys used by modalab: ``range`` (per channel, the ± input range in
        engineering units, or ``(lo, hi)``), ``range_v`` (volts), ``point`` (the roving DOF),
        ``backend``, ``sim`` (the simulator's ground truth: pulse times, double hit...), ``highpass_hz`` (per
        channel, the AC-coupling corner in Hz, 0 = DC coupled: the force window keeps the coupling's
        undershoot with it, :func:`acquisition.windows.windowed_force`; kept in the UFF's ID line 4).
    """

    def __init__(self, *, sample_rate_hz, data, dofs, roles, units=None, sensitivity=None,
                 trigger_index: int = 0, overload=None, hit_id: int = 1, metadata: dict | None = None):
        fs = float(sample_rate_hz)
        if not np.isfinite(fs) or fs <= 0:
            raise ModalabValueError(f"sample_rate_hz={sample_rate_hz!r} must be a positive number of samples per second")
        x = np.asarray(data, dtype=float)
        if x.ndim == 1:
            x = x[None, :]
        if x.ndim != 2:
            raise ShapeError(f"data must be (n_channels, n_samples); got shape {x.shape}")
        n_ch = x.shape[0]
        d = parse_dofs(dofs)
        if len(d) != n_ch:
            raise ShapeError(f"{len(d)} DOF labels for {n_ch} channels; give one DOF per channel")
        r = [str(v).lower() for v in (roles if not isinstance(roles, str) else [roles])]
        if len(r) != n_ch or any(v not in ROLES for v in r):
            raise ModalabValueError(f"roles {roles!r} must give 'force' or 'response' for each of the {n_ch} channels")
        u = list(units) if units is not None else ["N" if v == "force" else "m/s^2" for v in r]
        if len(u) != n_ch:
            raise ShapeError(f"{len(u)} units for {n_ch} channels")
        s = np.ones(n_ch) if sensitivity is None else np.broadcast_to(np.asarray(sensitivity, float), (n_ch,)).copy()
        ov = np.zeros(n_ch, bool) if overload is None else np.broadcast_to(np.asarray(overload, bool), (n_ch,)).copy()
        ti = int(trigger_index)
        if ti < 0 or ti >= max(x.shape[1], 1):
            raise ModalabValueError(f"trigger_index={trigger_index} outside the record of {x.shape[1]} samples")
        self.sample_rate_hz = fs
        self.data = x
        self.dofs: list[Dof] = d
        self.roles: list[str] = r
        self.units: list[str] = u
        self.sensitivity = s
        self.trigger_index = ti
        self.overload = ov
        self.hit_id = int(hit_id)
        self.metadata = dict(metadata or {})

    @property
    def n_channels(self) -> int:
        return self.data.shape[0]

    @property
    def n_samples(self) -> int:
        return self.data.shape[1]

    @property
    def dt(self) -> float:
        return 1.0 / self.sample_rate_hz

    @property
    def duration(self) -> float:
        return self.n_samples / self.sample_rate_hz

    @property
    def t(self) -> np.ndarray:
        """Time of each sample in s, zero at the trigger."""
        return (np.arange(self.n_samples) - self.trigger_index) / self.sample_rate_hz

    @property
    def force_channels(self) -> list[int]:
        return [i for i, r in enumerate(self.roles) if r == "force"]

    @property
    def response_channels(self) -> list[int]:
        return [i for i, r in enumerate(self.roles) if r == "response"]

    @property
    def force(self) -> np.ndarray:
        """(n_force, n_samples) force signals."""
        return self.data[self.force_channels]

    @property
    def response(self) -> np.ndarray:
        """(n_response, n_samples) response signals."""
        return self.data[self.response_channels]

    @property
    def force_dofs(self) -> list[Dof]:
        return [self.dofs[i] for i in self.force_channels]

    @property
    def response_dofs(self) -> list[Dof]:
        return [self.dofs[i] for i in self.response_channels]

    @property
    def overloaded(self) -> bool:
        return bool(self.overload.any())

    def highpass_hz(self) -> list | None:
        """The channels' AC-coupling corners (Hz, 0 = DC coupled) from ``metadata['highpass_hz']``, one per
        channel; None when the record does not say.  A malformed entry is an error naming the hit."""
        hp = (self.metadata or {}).get("highpass_hz")
        if hp is None:
            return None
        try:
            v = [float(c) for c in hp]
        except (TypeError, ValueError):
            v = []
        if len(v) != self.n_channels or not all(np.isfinite(c) and c >= 0 for c in v):
            raise ModalabValueError(f"hit {self.hit_id}: metadata highpass_hz={hp!r}; expected one AC-coupling "
                                    f"corner >= 0 Hz per channel ({self.n_channels}), 0 for a DC-coupled channel")
        return v

    def copy(self) -> "TimeRecord":
        return copy.deepcopy(self)

    def __repr__(self) -> str:
        return (f"TimeRecord(hit {self.hit_id}: {self.n_channels} channels x {self.n_samples} samples at "
                f"{self.sample_rate_hz:g} Hz, force at {', '.join(map(str, self.force_dofs)) or '-'}"
                f"{', OVERLOAD' if self.overloaded else ''})")

    @classmethod
    def group_by_hit(cls, records: Sequence["TimeRecord"]) -> dict[int, "TimeRecord"]:
        """Index records by ``hit_id``; raises on duplicates."""
        out: dict[int, TimeRecord] = {}
        for r in records:
            if r.hit_id in out:
                raise ModalabValueError(f"hit id {r.hit_id} appears twice; hit ids must be unique in a session")
            out[r.hit_id] = r
        return out
