"""pyserial URL handler for ``simhammer://NAME`` (see :mod:`hardware_sim.serial_devices`)."""
from .serial_devices import make_serial_class

Serial = make_serial_class("simhammer")
