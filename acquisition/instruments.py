"""Serial instruments: an IEPE signal conditioner and an automatic impact hammer.

Transport and command vocabulary are separate (pymeasure style):
:class:`LineTransport` moves text lines over any pyserial URL
(``serial.serial_for_url``: ``/dev/ttyUSB0``, ``socket://host:port``,
``loop://``, and the simulated twins ``simcond://NAME`` and ``simhammer://NAME``
that :mod:`hardware_sim.serial_devices` registers); the instrument classes only
know their commands.  Drivers are tested by replaying command/reply transcripts.

IEPE conditioner protocol (ASCII, one command per line, ``\\n`` terminated)
----------------------------------------------------------------------------
``U:C:CMD=VALUE`` sets, ``U:C:CMD?`` queries; U is the unit address (1..9), C
the channel (1..8).  Every command gets exactly one reply line: the effective
setting ``U:C:CMD=VALUE`` or ``U:C:ERR=CODE,TEXT``.

=========  ======================  =====================================
command    values                  meaning
=========  ======================  =====================================
GAIN       1, 10, 100              voltage gain of the channel
MODE       IEPE, AC, DC            input mode (IEPE = current excitation + AC coupling)
EXC        ON, OFF                 IEPE excitation current
STAT?      OK, OVL, OPEN, SHORT    status (OVL = overload latched; OPEN/SHORT = IEPE bias fault)
OVL?       0, 1                    overload latch; reading it clears it
=========  ======================  =====================================

``*IDN?`` (no address) answers ``MAKER,MODEL,SERIAL,VERSION``.

Automatic impact hammer protocol
--------------------------------
``*IDN?`` → identification; ``LEVEL?`` → ``LEVEL MIN MAX`` (N);
``ARM`` → ``OK``; ``FIRE F`` → ``OK`` (F in N, only when armed);
``STAT?`` → ``READY`` | ``ARMED`` | ``FAULT TEXT``; errors: ``ERR CODE TEXT``.
The session arms the DAQ first and then fires the hammer.
"""
from __future__ import annotations

import logging

import serial

from modalab.core.errors import ModalabValueError, SerialProtocolError

log = logging.getLogger(__name__)
__all__ = ["LineTransport", "IEPEConditioner", "AutoHammer", "open_serial"]


def open_serial(url: str, *, baudrate: int = 115200, timeout: float = 1.0):
    """Open a pyserial port from a URL with ``serial.serial_for_url``."""
    try:
        return serial.serial_for_url(url, baudrate=baudrate, timeout=timeout)
    except (serial.SerialException, ValueError) as e:
        raise SerialProtocolError(f"cannot open serial port {url!r}: {e}. Check the port name/URL, that the "
                                  "device is connected and not used by another program") from None


class LineTransport:
    """Text lines over a serial port: ``write_line``, ``read_line``, ``query``."""

    def __init__(self, port, *, eol: str = "\n", encoding: str = "ascii"):
        self.port = port
        self.eol = eol
        self.encoding = encoding

    @classmethod
    def from_url(cls, url: str, **kw) -> "LineTransport":
        return cls(open_serial(url, **kw))

    def write_line(self, text: str) -> None:
        log.debug("serial > %s", text)
        self.port.write((text + self.eol).encode(self.encoding))

    def read_line(self) -> str:
        raw = self.port.read_until(self.eol.encode(self.encoding))
        if not raw or not raw.endswith(self.eol.encode(self.encoding)):
            raise SerialProtocolError(f"no complete reply from {getattr(self.port, 'name', 'the port')} within "
                                      f"{getattr(self.port, 'timeout', '?')} s (got {raw!r}); check power, cable and "
                                      "baud rate")
        text = raw.decode(self.encoding, errors="replace").strip()
        log.debug("serial < %s", text)
        return text

    def query(self, text: str) -> str:
        self.write_line(text)
        return self.read_line()

    def close(self) -> None:
        self.port.close()


class IEPEConditioner:
    """Multi-channel IEPE signal conditioner (protocol in the module docstring)."""

    GAINS = (1, 10, 100)
    MODES = ("IEPE", "AC", "DC")

    def __init__(self, transport: LineTransport, *, unit: int = 1, n_channels: int = 8):
        if not 1 <= unit <= 9:
            raise ModalabValueError(f"conditioner unit address {unit} outside 1..9")
        self.t = transport
        self.unit = unit
        self.n_channels = n_channels

    def _addr(self, channel: int) -> str:
        if not 1 <= int(channel) <= self.n_channels:
            raise ModalabValueError(f"conditioner channel {channel} outside 1..{self.n_channels}")
        return f"{self.unit}:{int(channel)}"

    def _exchange(self, channel: int, command: str) -> str:
        addr = self._addr(channel)
        reply = self.t.query(f"{addr}:{command}")
        head, _, value = reply.partition("=")
        if head == f"{addr}:ERR":
            raise SerialProtocolError(f"conditioner refused {addr}:{command}: {value}")
        name = command.split("=")[0].rstrip("?")
        if head != f"{addr}:{name}" or not value:
            raise SerialProtocolError(f"conditioner replied {reply!r} to {addr}:{command}; expected "
                                      f"'{addr}:{name}=VALUE'. Check the unit address and the protocol version")
        return value

    def identify(self) -> str:
        return self.t.query("*IDN?")

    def set_gain(self, channel: int, gain: int) -> int:
        if int(gain) not in self.GAINS:
            raise ModalabValueError(f"gain {gain} not available; expected one of {self.GAINS}")
        return int(self._exchange(channel, f"GAIN={int(gain)}"))

    def gain(self, channel: int) -> int:
        return int(self._exchange(channel, "GAIN?"))

    def set_mode(self, channel: int, mode: str) -> str:
        m = mode.upper()
        if m not in self.MODES:
            raise ModalabValueError(f"input mode {mode!r}; expected one of {self.MODES}")
        return self._exchange(channel, f"MODE={m}")

    def set_excitation(self, channel: int, on: bool) -> bool:
        return self._exchange(channel, f"EXC={'ON' if on else 'OFF'}") == "ON"

    def status(self, channel: int) -> str:
        return self._exchange(channel, "STAT?")

    def overload(self, channel: int) -> bool:
        """Read and clear the channel's overload latch."""
        return self._exchange(channel, "OVL?") == "1"

    def setup_iepe(self, channel: int, gain: int = 1) -> None:
        """Put a channel in IEPE mode with excitation on and the given gain; check the bias is healthy."""
        self.set_mode(channel, "IEPE")
        self.set_excitation(channel, True)
        self.set_gain(channel, gain)
        st = self.status(channel)
        if st in ("OPEN", "SHORT"):
            raise SerialProtocolError(f"channel {channel}: IEPE bias fault {st}; check the sensor cable "
                                      "(OPEN = no sensor or broken cable, SHORT = shorted cable)")


class AutoHammer:
    """Automatic impact hammer: arm, fire with a force level, status (protocol in the module docstring)."""

    def __init__(self, transport: LineTransport):
        self.t = transport
        self._level = None

    def _ok(self, command: str) -> str:
        reply = self.t.query(command)
        if reply.startswith("ERR"):
            raise SerialProtocolError(f"automatic hammer refused {command!r}: {reply[3:].strip()}")
        return reply

    def identify(self) -> str:
        return self.t.query("*IDN?")

    def level_range(self) -> tuple[float, float]:
        reply = self._ok("LEVEL?")
        parts = reply.split()
        if len(parts) != 3 or parts[0] != "LEVEL":
            raise SerialProtocolError(f"hammer replied {reply!r} to LEVEL?; expected 'LEVEL MIN MAX'")
        return float(parts[1]), float(parts[2])

    def arm(self) -> None:
        if self._ok("ARM") != "OK":
            raise SerialProtocolError("hammer did not acknowledge ARM with OK")

    def fire(self, force_n: float) -> None:
        if self._level is None:
            self._level = self.level_range()
        lo, hi = self._level
        if not lo <= force_n <= hi:
            raise ModalabValueError(f"hammer force {force_n} N outside the device's range {lo:g}..{hi:g} N; choose a force in that range")
        if self._ok(f"FIRE {force_n:.6g}") != "OK":
            raise SerialProtocolError("hammer did not acknowledge FIRE with OK")

    def status(self) -> str:
        return self.t.query("STAT?")
