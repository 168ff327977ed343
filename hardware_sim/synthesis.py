"""How the simulated lab synthesises a hit: the synthesis grid, the hammer's draw, the exact FRF columns and the
record a triggered DAQ delivers.  :class:`_HitSynthesis` is a base of :class:`hardware_sim.lab.SimulatedLab`
(it uses the lab's ``setup``, ``channels``, ``hammer``, ``model``, ``coords`` and random generator).

How a hit is synthesised (exact for a linear structure)
-------------------------------------------------------
1. The hammer draws its pulses (:meth:`Hammer.draw_pulses`): half-sines whose
   width is ``π√(m/k_tip)``, with force, width and placement scatter and an
   optional rebound.  A hit that misses its point by ``δ`` (a vector across the
   hit direction, of random bearing) is the force at the node plus the moment
   ``δ × F`` on the node's rotational DOFs: exact to first order in ``δ`` for
   beams and shells, whose nodal rotations are the slopes (:meth:`_eccentric`).
   It needs node coordinates; where the model has no rotational DOF at the
   point (springs and masses, solids) the hit lands on the node.  Linear
   interpolation of the force to the neighbouring node, used before, averaged
   the FRF across the element (a 3 mm scatter read a 0.2 m beam mesh 1.35 %
   low everywhere, which E and ρ of an exact model then absorbed).
2. The continuous spectrum of the force (:func:`half_sine_spectrum`, exact)
   is multiplied by the structure's exact accelerance, ``structure.modal_model().frf``
   (viscous or hysteretic damping alike), on a long grid sampled at
   ``oversample × fs``.  The grid is long enough that every pole, and the
   AC-coupling pole, has decayed to ``tail_tolerance`` before the periodic
   inverse transform wraps around; the record is cut from its start.  So there
   is no wrap-around beyond ``tail_tolerance`` (≈ the 24-bit step).
3. Per channel: sensitivity (V/unit), IEPE AC-coupling high-pass, anti-alias
   filter; the oversampled signal is decimated to fs (content between fs/2 and
   ``0.8·oversample·fs/2`` aliases as it would; the simulated front end's analog
   bandwidth rolls off above that, :func:`synthesis_taper`).
4. Noise (sensor + converter), optional overload-storm transients, clipping to
   the ADC range (overload flag; the analog input before the anti-alias filter
   is checked too, as a delta-sigma modulator overloads on it), 24-bit
   quantisation, division by the sensitivity.
5. The trigger is the first sample of the digitised force crossing
   ``trigger_level`` with the set slope; the record keeps
   ``pretrigger_samples`` before it.  A hit too weak to cross the level gives
   no record (``DaqTimeoutError``), like a real DAQ.
"""
from __future__ import annotations

import logging
import math

import numpy as np
import scipy.fft as sfft

from modalab.core.dof import Dof, locate, parse_dofs
from modalab.core.records import TimeRecord

from .signal_chain import (antialias_response, half_sine_spectrum, iepe_highpass, quantization_step, quantize,
                           synthesis_taper)

__all__: list[str] = []

log = logging.getLogger("hardware_sim.lab")     # the lab's logger, as before the split

_GUARD = 32          # samples between the pretrigger and the nominal hit (room for pre-ringing)
_PREPARE_BYTES = 512 * 2 ** 20      # FRF columns computed in one pass over the synthesis grid (prepare)


class _HitSynthesis:
    """Hit synthesis of :class:`~hardware_sim.lab.SimulatedLab`."""

    def _build_grid(self) -> None:
        acq = self.setup
        fs = acq.sample_rate_hz
        poles = np.asarray(self.model.poles)
        sig = []                                    # (decay 1/s, what decays, where its ringing shows)
        if poles.size:
            k = int(np.argmin(abs(poles.real)))
            f_k = f"{abs(poles[k].imag) / (2 * np.pi):.3g} Hz"
            sig.append((abs(poles[k].real), f"the mode at {f_k}", f"lines near {f_k}"))
        sig += [(2 * np.pi * c.coupling_corner_hz, f"the IEPE coupling's {c.coupling_corner_hz:.3g} Hz high-pass",
                 "the lowest lines") for c in self.channels if c.coupling_corner_hz > 0]
        if acq.aa_filter == "butterworth":
            sig.append((2 * np.pi * acq.aa_cutoff * fs * math.sin(math.pi / (2 * acq.aa_order)),
                        "the anti-alias filter", "the lines near its cut-off"))
        sigma, slowest, near = min(sig, key=lambda t: t[0]) if sig else (np.inf, "", "")
        tail_s = math.log(1 / self.tail_tolerance) / sigma if sigma > 0 else np.inf
        self._lead = acq.pretrigger_samples + _GUARD
        self._search = int(math.ceil(self.hammer.max_width_s * fs)) + 2
        self._window = self._lead + self._search + acq.n_samples
        need = self._window + (int(math.ceil(tail_s * fs)) if np.isfinite(tail_s) else 0)
        cap = int(self.max_synthesis_s * fs)
        if not np.isfinite(tail_s) or need > cap:
            need = max(cap, self._window + acq.n_samples)
            left = math.exp(-sigma * need / fs) if sigma > 0 else 1.0
            log.warning("simulated lab: the slowest decay (%.3g 1/s, %s) needs %.3g s of synthesis to fall to %.1e; "
                        "capped at %.3g s, where it is still %.2g of its start: its ringing wraps around into the "
                        "record (the synthesis is periodic) and shows mostly at %s", sigma, slowest, tail_s,
                        self.tail_tolerance, need / fs, left, near)
        os_ = self.oversample_used
        ns = sfft.next_fast_len(need, real=True)
        self._ns = ns
        self._nos = ns * os_
        self._fs_os = fs * os_
        self._freq = sfft.rfftfreq(self._nos, 1.0 / self._fs_os)
        aa = antialias_response(self._freq, fs, acq.aa_filter, acq.aa_cutoff, acq.aa_order)
        taper = synthesis_taper(self._freq, self._fs_os / 2)
        self._pre_chain = [c.sensitivity * taper * iepe_highpass(self._freq, c.coupling_corner_hz)
                           for c in self.channels]
        self._chain = [p * aa for p in self._pre_chain]
        log.debug("synthesis grid: %d samples at %g Hz (%.3g s, slowest decay %.3g 1/s)",
                  self._nos, self._fs_os, self._nos / self._fs_os, sigma)

    @property
    def oversample_used(self) -> int:
        """Synthesis rate / fs: ``oversample`` if given, else 2 behind a delta-sigma filter and 4 otherwise."""
        if self.oversample is not None:
            return self.oversample
        return 2 if self.setup is not None and self.setup.aa_filter == "delta-sigma" else 4

    @property
    def synthesis_duration_s(self) -> float:
        """Length of the synthesis grid (s): record + the time for every decay to reach ``tail_tolerance``."""
        self._need_config()
        return self._nos / self._fs_os

    # ------------------------------------------------------------------ synthesis
    def _draw_hit(self, force_n, double) -> dict:
        pulses = self.hammer.draw_pulses(self._rng, force_n, force_double=double)
        miss, u_dir = self.hammer.draw_placement(self._rng)
        u_sub = float(self._rng.random())
        arm, moment = self._eccentric(self._point, miss, u_dir)
        return dict(pulses=pulses, point=self._point, arm=arm, moment=moment, miss_m=miss, u_sub=u_sub)

    def _eccentric(self, point: Dof, miss: float, u_dir: float):
        """Where a hit that misses ``point`` by ``miss`` m lands, and what it adds to the force at the node.

        The miss is a vector ``r`` across the hit direction at the bearing ``2π·u_dir`` (for a Z hit, in the
        X-Y plane from +X towards +Y); per newton of the hit's force ``f`` (the unit vector of the signed
        point DOF) it adds the moment ``r × f`` at the node.  Returns ``(r, [(rotation DOF, moment per N),
        ...])``: ``r`` in metres (3 numbers, or None when the hit lands on the node) and the moment's
        components on the rotational DOFs the model has at the node (the others are held, so they do no
        work)."""
        if miss <= 0 or not 1 <= point.axis <= 3 or point.node not in self.coords:
            return None, []
        a = point.axis - 1
        b, c = (k for k in range(3) if k != a)
        r = np.zeros(3)
        r[b], r[c] = miss * math.cos(2 * math.pi * u_dir), miss * math.sin(2 * math.pi * u_dir)
        f = np.zeros(3)
        f[a] = point.sign
        m = np.cross(r, f)
        m[np.abs(m) <= 1e-12 * miss] = 0.0        # cos(π/2) is 6e-17, not 0
        return r.tolist(), [(d, float(m[d.axis - 4])) for d in self._rotations(point) if m[d.axis - 4] != 0]

    def _rotations(self, point: Dof) -> list[Dof]:
        """The rotational DOFs of the model at ``point``'s node about the axes across the hit direction (what an
        eccentric hit there loads); none without coordinates, placement scatter or for an automatic hammer."""
        if point.node not in self.coords or self.hammer.placement_scatter_m == 0 or self.hammer.automatic \
                or not 1 <= point.axis <= 3:
            return []
        have = {(d.node, d.axis) for d in self.model.dofs}
        return [Dof(point.node, k) for k in (4, 5, 6) if k - 3 != point.axis and (point.node, k) in have]

    def prepare(self, points) -> None:
        """Compute the exact FRF columns of ``points`` (and of the rotations a miss loads) in batches.

        Optional: hits compute what they need on first use, but one batched call is much
        faster than one per point.  Costs ``n_response × n_lines × 16`` bytes per DOF.
        """
        self._need_config()
        want = []
        for p in parse_dofs(points):
            locate(self.model.dofs, [p], "point DOF", "the model")
            for d in [p] + self._rotations(p):
                if d not in self._cache and d not in want:
                    want.append(d)
        # batches of at most _PREPARE_BYTES of FRF columns: every batch is one pass over the grid's lines
        per = max(1, int(_PREPARE_BYTES // (16 * max(len(self.response_dofs), 1) * self._freq.size)))
        for a in range(0, len(want), per):
            batch = want[a:a + per]
            H = self.model.frf(self._freq, responses=self.response_dofs, references=batch,
                               quantity="accelerance", chunk=8192).H
            for j, d in enumerate(batch):
                self._cache[d] = np.ascontiguousarray(H[:, j, :])

    def _column(self, dof: Dof) -> np.ndarray:
        """Exact accelerance from ``dof`` to every response channel on the synthesis grid (cached)."""
        if dof not in self._cache:
            # with the points the hammer will visit (SimulatedLab's hammer_points): one pass over the grid
            self.prepare([dof] + [p for p in self.hammer_points if p not in self._cache])
        return self._cache[dof]

    def _synthesise(self, p: dict) -> TimeRecord | None:
        acq = self.setup
        h = p["hit"]
        fs, os_ = acq.sample_rate_hz, self.oversample_used
        n, pre, W = acq.n_samples, acq.pretrigger_samples, self._window
        t0 = (self._lead + h["u_sub"]) / fs
        F = np.zeros(self._freq.size, complex)
        for q in h["pulses"]:
            F += half_sine_spectrum(self._freq, q.amplitude_n, q.width_s, t0 + q.delay_s)
        col = self._column(h["point"])
        for d, m in h["moment"]:
            col = col + m * self._column(d)
        n_ch = len(self.channels)
        v = np.zeros((n_ch, W))
        analog = [None] * n_ch
        check_analog = acq.aa_filter != "none"
        for c, ch in enumerate(self.channels):
            if ch.dead:
                continue
            X = F if c == self._force else col[self._resp.index(c)] * F
            v[c] = sfft.irfft(X * self._chain[c], n=self._nos)[: W * os_: os_] * self._fs_os
            if check_analog:
                analog[c] = sfft.irfft(X * self._pre_chain[c], n=self._nos)[: W * os_] * self._fs_os
        sigma = np.array([acq.adc_noise_v_rms if ch.dead else
                          math.sqrt(ch.noise_v_rms ** 2 + ch.extra_noise_v_rms ** 2 + acq.adc_noise_v_rms ** 2)
                          for ch in self.channels])
        v += self._rng.standard_normal((n_ch, W)) * sigma[:, None]
        if p["storm"]:
            self._add_storm(v)
        rng_v = np.array([ch.range_v for ch in self.channels])
        sens = np.array([ch.sensitivity for ch in self.channels])
        vq = np.empty_like(v)
        for c, ch in enumerate(self.channels):
            vq[c], _ = quantize(v[c], ch.range_v, acq.adc_bits)
        force = vq[self._force] / sens[self._force]
        first = max(pre, 1)
        seg = force[first - 1: self._lead + self._search]
        lvl = acq.trigger_level
        if acq.trigger_slope == "rising":
            cross = np.flatnonzero((seg[1:] >= lvl) & (seg[:-1] < lvl))
        else:
            cross = np.flatnonzero((seg[1:] <= lvl) & (seg[:-1] > lvl))
        if cross.size == 0:
            return None
        i = first + int(cross[0])
        a, b = i - pre, i - pre + n
        over = np.abs(v[:, a:b]).max(axis=1) >= rng_v
        for c in range(n_ch):
            if analog[c] is not None and np.abs(analog[c][a * os_: b * os_]).max() >= rng_v[c]:
                over[c] = True
        data = vq[:, a:b] / sens[:, None]
        self._hits += 1
        starts = [t0 + q.delay_s - i / fs for q in h["pulses"]]
        sim = dict(arm=p["arm"], point=str(h["point"]), pulse_starts_s=starts,
                   pulse_peaks_n=[q.amplitude_n for q in h["pulses"]],
                   pulse_widths_s=[q.width_s for q in h["pulses"]], double_hit=len(h["pulses"]) > 1,
                   miss_m=h["miss_m"], miss_arm_m=h["arm"],
                   miss_moment_m={str(d): m for d, m in h["moment"]}, overload_storm=bool(p["storm"]),
                   dead_channels=[c for c, ch in enumerate(self.channels) if ch.dead],
                   tip=self.hammer.tip if self.hammer.tip_stiffness_n_per_m is None else "custom",
                   automatic=self.hammer.automatic)
        meta = {"point": str(h["point"]), "range": [ch.range for ch in self.channels],
                "range_v": rng_v.tolist(), "quantization_step_v": [quantization_step(r, acq.adc_bits) for r in rng_v],
                "highpass_hz": [ch.coupling_corner_hz for ch in self.channels], "aa_filter": acq.aa_filter,
                "source": "hardware_sim", "sim": sim}
        dofs = [h["point"] if c == self._force else ch.dof for c, ch in enumerate(self.channels)]
        log.debug("hit %d at %s: %.1f N peak%s", self._hits, h["point"], sim["pulse_peaks_n"][0],
                  ", OVERLOAD" if over.any() else "")
        return TimeRecord(sample_rate_hz=fs, data=data, dofs=dofs, roles=[ch.role for ch in self.channels],
                          units=[ch.units for ch in self.channels], sensitivity=sens, trigger_index=pre,
                          overload=over, hit_id=self._hits, metadata=meta)

    def _add_storm(self, v: np.ndarray) -> None:
        """Transients beyond the range on every channel inside the record (ESD, a loose ground)."""
        lo = self._lead
        hi = max(lo + 1, self._lead + self.setup.n_samples - self.setup.pretrigger_samples - 16)
        shape = np.exp(-np.arange(12) / 2.0)
        for c, ch in enumerate(self.channels):
            k = int(self._rng.integers(3, 9))
            pos = self._rng.integers(lo, hi, size=k)
            amp = ch.range_v * self._rng.uniform(1.2, 3.0, size=k) * self._rng.choice([-1.0, 1.0], size=k)
            for p_, a_ in zip(pos, amp):
                m = min(shape.size, v.shape[1] - p_)
                v[c, p_: p_ + m] += a_ * shape[:m]
