"""Simulated serial instruments, reachable as pyserial URLs.

``simcond://NAME`` is an 8-channel IEPE signal conditioner and
``simhammer://NAME`` an automatic impact hammer, speaking the protocols
documented in :mod:`acquisition.instruments`.  :func:`register` adds
``hardware_sim`` to ``serial.protocol_handler_packages`` so that
``serial.serial_for_url`` finds them; devices with the same NAME share state
(:func:`device`), so a test can inspect or fault them.  A simulated hammer
calls its ``on_fire(force_n)`` callback, which the simulated DAQ uses to
produce the hit.
"""
from __future__ import annotations

import threading
from typing import Callable
from urllib.parse import urlsplit

import serial
from serial.serialutil import SerialException
from serial.urlhandler import protocol_loop

__all__ = ["register", "device", "reset_devices", "SimConditioner", "SimAutoHammer"]

_DEVICES: dict[str, object] = {}
_LOCK = threading.Lock()


class _LineDevice:
    """A simulated instrument: one reply line per command line, every exchange kept in ``log``."""

    log: list

    def handle(self, line: str) -> str:
        reply = self._handle(line.strip())
        self.log.append((line.strip(), reply))
        return reply

    def _handle(self, line: str) -> str:  # pragma: no cover - defined by each device
        raise NotImplementedError


class SimConditioner(_LineDevice):
    """State machine of the IEPE conditioner: ``handle(line) -> reply``."""

    def __init__(self, unit: int = 1, n_channels: int = 8):
        self.unit = unit
        self.n_channels = n_channels
        self.gain = {c: 1 for c in range(1, n_channels + 1)}
        self.mode = {c: "IEPE" for c in range(1, n_channels + 1)}
        self.exc = {c: True for c in range(1, n_channels + 1)}
        self.ovl = {c: False for c in range(1, n_channels + 1)}
        self.fault = {c: "" for c in range(1, n_channels + 1)}   # '', 'OPEN', 'SHORT'
        self.log: list[tuple[str, str]] = []

    def _handle(self, line: str) -> str:
        if line == "*IDN?":
            return "MODALAB-SIM,IEPE-8,0001,1.0"
        parts = line.split(":", 2)
        if len(parts) != 3:
            return "0:0:ERR=1,syntax"
        u, c, cmd = parts
        addr = f"{u}:{c}"
        try:
            unit, ch = int(u), int(c)
        except ValueError:
            return f"{addr}:ERR=1,syntax"
        if unit != self.unit or not 1 <= ch <= self.n_channels:
            return f"{addr}:ERR=2,no such channel"
        name, eq, value = cmd.partition("=")
        query = name.endswith("?")
        name = name.rstrip("?")
        if name == "GAIN":
            if eq:
                if value not in ("1", "10", "100"):
                    return f"{addr}:ERR=3,gain must be 1, 10 or 100"
                self.gain[ch] = int(value)
            return f"{addr}:GAIN={self.gain[ch]}"
        if name == "MODE":
            if eq:
                if value not in ("IEPE", "AC", "DC"):
                    return f"{addr}:ERR=3,mode must be IEPE, AC or DC"
                self.mode[ch] = value
                if value != "IEPE":
                    self.exc[ch] = False
            return f"{addr}:MODE={self.mode[ch]}"
        if name == "EXC":
            if eq:
                if value not in ("ON", "OFF"):
                    return f"{addr}:ERR=3,EXC must be ON or OFF"
                self.exc[ch] = value == "ON"
            return f"{addr}:EXC={'ON' if self.exc[ch] else 'OFF'}"
        if name == "STAT" and query:
            if self.fault[ch] and self.exc[ch]:
                return f"{addr}:STAT={self.fault[ch]}"
            return f"{addr}:STAT={'OVL' if self.ovl[ch] else 'OK'}"
        if name == "OVL" and query:
            v = self.ovl[ch]
            self.ovl[ch] = False
            return f"{addr}:OVL={int(v)}"
        return f"{addr}:ERR=4,unknown command {name}"


class SimAutoHammer(_LineDevice):
    """State machine of the automatic hammer: ``handle(line) -> reply``."""

    def __init__(self, min_n: float = 5.0, max_n: float = 800.0):
        self.min_n, self.max_n = min_n, max_n
        self.armed = False
        self.fault = ""
        self.fired: list[float] = []
        self.on_fire: Callable[[float], None] | None = None
        self.log: list[tuple[str, str]] = []

    def _handle(self, line: str) -> str:
        if line == "*IDN?":
            return "MODALAB-SIM,AUTOHAMMER,0001,1.0"
        if line == "LEVEL?":
            return f"LEVEL {self.min_n:g} {self.max_n:g}"
        if line == "STAT?":
            return f"FAULT {self.fault}" if self.fault else ("ARMED" if self.armed else "READY")
        if self.fault:
            return f"ERR 9 {self.fault}"
        if line == "ARM":
            self.armed = True
            return "OK"
        if line.startswith("FIRE"):
            try:
                f = float(line.split()[1])
            except (IndexError, ValueError):
                return "ERR 1 syntax: FIRE <force in N>"
            if not self.armed:
                return "ERR 2 not armed"
            if not self.min_n <= f <= self.max_n:
                return f"ERR 3 force out of range {self.min_n:g}..{self.max_n:g} N"
            self.armed = False
            self.fired.append(f)
            if self.on_fire is not None:
                self.on_fire(f)
            return "OK"
        return "ERR 4 unknown command"


_KINDS = {"simcond": SimConditioner, "simhammer": SimAutoHammer}


def device(url_or_kind: str, name: str | None = None):
    """The shared simulated device behind ``simcond://NAME`` or ``simhammer://NAME`` (created on first use)."""
    if name is None:
        parts = urlsplit(url_or_kind)
        kind, name = parts.scheme, parts.netloc or parts.path.strip("/") or "default"
    else:
        kind = url_or_kind
    if kind not in _KINDS:
        raise KeyError(f"unknown simulated serial device kind {kind!r}; expected simcond or simhammer")
    with _LOCK:
        key = f"{kind}://{name}"
        if key not in _DEVICES:
            _DEVICES[key] = _KINDS[kind]()
        return _DEVICES[key]


def reset_devices() -> None:
    """Forget every simulated serial device (tests)."""
    with _LOCK:
        _DEVICES.clear()


def register() -> None:
    """Make ``serial.serial_for_url`` find the ``simcond://`` and ``simhammer://`` handlers."""
    if "hardware_sim" not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append("hardware_sim")


def make_serial_class(kind: str):
    """A pyserial ``Serial`` class for ``kind`` (used by the protocol_* modules)."""
    class Serial(protocol_loop.Serial):
        def from_url(self, url):
            parts = urlsplit(url)
            if parts.scheme != kind:
                raise SerialException(f"expected a URL {kind}://NAME, got {url!r}")
            self._device = device(url)
            self._inbuf = b""

        def write(self, data):
            n = super().write(b"")  # port-open checks
            data = bytes(data)
            self._inbuf += data
            while b"\n" in self._inbuf:
                line, self._inbuf = self._inbuf.split(b"\n", 1)
                reply = self._device.handle(line.decode("ascii", errors="replace").rstrip("\r"))
                for b in (reply + "\n").encode("ascii"):
                    self.queue.put(bytes([b]))
            return len(data) + n

    Serial.__name__ = f"Serial_{kind}"
    return Serial
