"""Finding GRBL controllers: serial ports from :mod:`serial.tools.list_ports`, each probed for a GRBL banner."""

from __future__ import annotations

import time
from dataclasses import dataclass

import serial
from serial.tools import list_ports as _list_ports

from drivers.errors import PortError
from drivers.grbl.connection import open_port

__all__ = ["PortInfo", "list_ports", "probe"]

SIMULATED_URLS = ("sim://grbl?profile=plotter", "sim://grbl?profile=laser")


@dataclass(frozen=True)
class PortInfo:
    """A port and what answered on it (``grbl`` is the version, e.g. ``1.1h``, or empty)."""

    url: str
    description: str
    hwid: str = ""
    grbl: str = ""
    simulated: bool = False


def probe(url: str, baud: int = 115200, timeout: float = 2.5) -> str:
    """The GRBL version answering on ``url`` (``""`` if none): waits for the banner that an Arduino prints when the
    port opens (DTR reset), and sends a soft reset if none comes within half the timeout."""
    try:
        port = open_port(url, baud, timeout=0.1)
    except PortError:
        return ""
    buffer = b""
    try:
        deadline = time.monotonic() + timeout
        reset_sent = False
        while time.monotonic() < deadline:
            buffer += port.read(256)
            for line in buffer.split(b"\n"):
                text = line.strip().decode("latin-1")
                if text.startswith("Grbl ") and "for help" in text:
                    return text.split()[1]
            if not reset_sent and time.monotonic() > deadline - timeout / 2:
                port.write(b"\x18")
                reset_sent = True
    except (serial.SerialException, OSError):
        return ""
    finally:
        try:
            port.close()
        except (serial.SerialException, OSError):
            pass
    return ""


def list_ports(probe_ports: bool = True, include_simulated: bool = True, baud: int = 115200) -> list[PortInfo]:
    """Serial ports of this computer (each probed for a GRBL banner) and the simulated machines."""
    found = []
    for info in sorted(_list_ports.comports(), key=lambda p: p.device):
        version = probe(info.device, baud) if probe_ports else ""
        found.append(PortInfo(info.device, info.description or "", info.hwid or "", version))
    if include_simulated:
        for url in SIMULATED_URLS:
            version = probe(url, baud, timeout=1.0) if probe_ports else ""
            found.append(PortInfo(url, "simulated GRBL 1.1", "", version, simulated=True))
    return found
