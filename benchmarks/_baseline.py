"""What the side-by-side benchmarks share: a baseline revision's code, and one measured child process.

``checkout(rev, dest)`` extracts ``git archive REV`` of this repository into ``dest`` (the code a run of
``PYTHONPATH=dest`` imports); ``measure(src, argv, cwd)`` runs ``python ARGV`` on the code in ``src`` and
returns its peak resident set size (sampled from ``/proc`` every 50 ms and read from ``wait4``'s
``ru_maxrss``), CPU time (user + system of the child), wall time and exit code, stopping it at a memory cap.
"""
from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def checkout(rev: str, dest: Path) -> Path:
    """The code of revision ``rev`` of this repository, extracted into ``dest`` (created); returns ``dest``."""
    dest.mkdir(parents=True, exist_ok=True)
    arch = subprocess.run(["git", "-C", str(ROOT), "archive", rev], check=True, capture_output=True)
    subprocess.run(["tar", "-x", "-C", str(dest)], input=arch.stdout, check=True)
    return dest


def _rss_kb(pid: int) -> int:
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS"):
                    return int(line.split()[1])
    except OSError:
        pass
    return 0


def measure(src: Path, argv: list, cwd: Path, cap_gb: float = float("inf")) -> dict:
    """``python ARGV`` on the code in ``src`` (``PYTHONPATH``; ``MODALAB_BLAS_THREADS`` as set, else 1): peak
    RSS (GB), CPU and wall time (s), exit code, whether it was stopped at the cap, its last stderr line."""
    env = dict(os.environ, PYTHONPATH=str(src), MODALAB_BLAS_THREADS=os.environ.get("MODALAB_BLAS_THREADS", "1"))
    t0 = time.perf_counter()
    p = subprocess.Popen([sys.executable, *argv], cwd=cwd, env=env, stdout=subprocess.DEVNULL,
                         stderr=subprocess.PIPE, text=True)
    peak, capped = [0], [False]

    def watch():
        while p.poll() is None:
            peak[0] = max(peak[0], _rss_kb(p.pid))
            if peak[0] > cap_gb * 2 ** 20:
                capped[0] = True
                p.kill()
                return
            time.sleep(0.05)

    th = threading.Thread(target=watch, daemon=True)
    th.start()
    err = p.stderr.read()
    _, status, ru = os.wait4(p.pid, 0)
    p.returncode = os.waitstatus_to_exitcode(status)
    th.join()
    return {"peak_gb": max(peak[0], ru.ru_maxrss) / 2 ** 20, "cpu_s": ru.ru_utime + ru.ru_stime,
            "sys_s": ru.ru_stime, "wall_s": time.perf_counter() - t0, "rc": p.returncode, "capped": capped[0],
            "err": err.strip().splitlines()[-1:] if p.returncode else []}


def side_by_side(rev: str, tmp: Path, what: str) -> dict:
    """``{'baseline': the code of revision rev (extracted into tmp/baseline), 'now': this checkout}`` for the
    benchmarks that run one ``what`` on each, one after the other; prints which, with the BLAS threads."""
    print(f"baseline {rev} against this checkout; MODALAB_BLAS_THREADS="
          f"{os.environ.get('MODALAB_BLAS_THREADS', '1')}; one {what} at a time")
    return {"baseline": checkout(rev, tmp / "baseline"), "now": ROOT}
