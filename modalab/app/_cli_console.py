"""What the command line shows at the console: printing, progress bars, the acquisition's per-hit
report and previews, and the terminal prompt (used by :mod:`modalab.app.cli` and the ``_cli_*`` commands)."""
from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np

from modalab.core.plots import plot_frf, plot_hit

log = logging.getLogger("modalab")

__all__ = ["_print", "_CountProgress", "_TerminalPrompter", "_ConsoleObserver"]


def _print(*a):
    print(*a, flush=True)


class _CountProgress:
    """Progress of a counted task (``progress(done, total, item)``): a bar on a terminal, else a line per item."""

    def __init__(self, what: str):
        self.what = what
        self._bar = None
        self._task = None

    def __enter__(self):
        return self

    def __call__(self, done, total, item=""):
        if self._bar is None:
            from rich.console import Console  # lazy: rich, only when drawing (start-up time)

            console = Console(stderr=False, highlight=False)
            if console.is_terminal:
                from rich.progress import (  # lazy: rich, only when drawing (start-up time)
                    BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn)

                self._bar = Progress(TextColumn(f"[bold]{self.what}"), BarColumn(), MofNCompleteColumn(),
                                     TextColumn("{task.description}"), TimeElapsedColumn(), console=console,
                                     transient=True)
                self._bar.start()
                self._task = self._bar.add_task("", total=total)
            else:
                self._bar = False
        if self._bar:
            self._bar.update(self._task, completed=done, description=str(item))
        else:
            _print(f"  {self.what} {done}/{total}" + (f": {item}" if item else ""))

    def __exit__(self, *exc):
        if self._bar:
            self._bar.stop()
        return False


class _TerminalPrompter:
    """A key per choice at the terminal (the key, then Enter); end of input answers 'q' (quit, resume later)."""

    def __call__(self, prompt: str, choices: str) -> str:
        while True:
            try:
                a = input(prompt + " ").strip().lower()[:1]
            except EOFError:
                return "q"
            if a in choices:
                return a
            _print(f"  please answer one of: {', '.join(choices)}")


class _ConsoleObserver:
    """Prints per-hit checks, decisions and a progress bar; previews per point.

    A live plot window (force trace, force spectrum, running FRF and coherence, updated every hit) opens
    only when ``live_plot`` is asked for *and* a display exists (``DISPLAY`` set) and an interactive
    matplotlib backend loads; otherwise the last hit and the running FRF of every point are written as
    PNG files to ``OUT/preview/``.
    """

    def __init__(self, out_dir: Path, live_plot: bool = False, quiet: bool = False):
        self.out_dir = Path(out_dir)
        self.quiet = quiet
        self.live = bool(live_plot) and bool(os.environ.get("DISPLAY"))
        self._progress = None
        self._task = None
        self._last = None
        self._fig = None

    def _say(self, msg):
        if not self.quiet:
            (self._progress.console.print if self._progress else _print)(msg)

    def _bar(self, n):
        if self._progress is None and not self.quiet:
            try:
                from rich.progress import (  # lazy: rich, only when drawing (start-up time)
                    BarColumn, MofNCompleteColumn, Progress, TextColumn)

                self._progress = Progress(TextColumn("[bold]points"), BarColumn(), MofNCompleteColumn(),
                                          TextColumn("{task.description}"), transient=False)
                self._progress.start()
                self._task = self._progress.add_task("", total=n)
            except ImportError:  # pragma: no cover
                self._progress = False

    def point_started(self, index, point, n_points):
        self._bar(n_points)
        if self._progress:
            self._progress.update(self._task, completed=index, description=f"at {point}")

    def _live_update(self, point, rec, running):
        try:
            import matplotlib.pyplot as plt  # lazy: matplotlib, only when drawing (start-up time)

            if self._fig is None:
                plt.switch_backend("TkAgg")
                plt.ion()
                self._fig, self._axes = plt.subplots(3, 1, figsize=(8, 8))
            a1, a2, a3 = self._axes
            for ax in self._axes:
                ax.clear()
            i = rec.force_channels[0]
            a1.plot(rec.t * 1e3, rec.data[i], lw=0.8)
            a1.set_xlabel("time [ms]")
            a1.set_ylabel("force [N]")
            F = np.abs(np.fft.rfft(rec.data[i])) / rec.sample_rate_hz
            a2.semilogy(np.fft.rfftfreq(rec.n_samples, rec.dt), np.maximum(F, 1e-12), lw=0.8)
            a2.set_ylabel("|F| [N s]")
            if running is not None:
                for r in range(running.n_out):
                    a3.semilogy(running.freq_hz, np.abs(running.H[r, 0]), lw=0.8, label=str(running.responses[r]))
                ac = a3.twinx()
                ac.plot(running.freq_hz, running.coherence[:, 0].T, lw=0.5, alpha=0.5)
                ac.set_ylim(0, 1.05)
                a3.set_xlabel("frequency [Hz]")
            self._fig.suptitle(f"hit at {point}")
            plt.pause(0.001)
        except Exception as e:  # noqa: BLE001 - no window: fall back to preview files
            log.warning("live plot unavailable (%s); writing preview PNGs instead", e)
            self.live = False

    def hit(self, index, point, rec, report, running):
        self._last = (rec, running)
        if self.live:
            self._live_update(point, rec, running)
        peak = max(abs(rec.data[i]).max() for i in rec.force_channels)
        flags = ", ".join(report.flags) if report.flags else "ok"
        self._say(f"  hit at {point}: peak force {peak:.1f} N, checks: {flags}")

    def decided(self, index, point, hit_id, decision, reasons):
        if decision != "candidate" or reasons:
            self._say(f"    hit {hit_id}: {decision}" + (f" ({', '.join(reasons)})" if reasons else ""))

    def point_finished(self, index, point, summary):
        if self._last is not None and not self.live:
            rec, running = self._last
            try:
                prev = self.out_dir / "preview"
                prev.mkdir(parents=True, exist_ok=True)
                plot_hit(rec, path=prev / f"point_{index:03d}_hit.png", title=f"last hit at {point}")
                if running is not None:
                    plot_frf(running, path=prev / f"point_{index:03d}_frf.png", title=f"running H1 at {point}")
            except Exception as e:  # noqa: BLE001 - a preview must never stop acquisition
                log.warning("preview figure failed: %s", e)
        self._last = None
        coh = "" if summary.mean_coherence != summary.mean_coherence else f", mean coherence {summary.mean_coherence:.3f}"
        self._say(f"  point {point}: {summary.accepted} accepted, {len(summary.rejected)} rejected{coh}"
                  + (f" (skipped: {summary.skipped})" if summary.skipped else ""))
        if self._progress:
            self._progress.update(self._task, completed=index + 1)

    def message(self, text):
        self._say("  " + text)

    def close(self):
        if self._progress:
            self._progress.stop()
            self._progress = None
