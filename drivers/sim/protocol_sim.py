"""pyserial URL handler for ``sim://`` ports (found through ``serial.protocol_handler_packages``).

``serial.serial_for_url("sim://grbl?profile=laser")`` returns a :class:`Serial` whose other end is a
:class:`drivers.sim.grbl.SimulatedGrbl`; the machine is reachable as ``port.machine`` (its record, ``unplug()``).
A ``name=...`` query shares one machine between successive opens (a reconnect finds the same machine).
"""

from __future__ import annotations

import threading
import urllib.parse

from serial.serialutil import PortNotOpenError, SerialBase, SerialException, to_bytes

from drivers.errors import SimConfigError
from drivers.sim.grbl import SimConfig, SimulatedGrbl

_SHARED: dict[str, SimulatedGrbl] = {}
_SHARED_LOCK = threading.Lock()


def machine_named(name: str) -> SimulatedGrbl | None:
    """The shared machine opened with ``name=...``, if any."""
    with _SHARED_LOCK:
        return _SHARED.get(name)


def forget_machines() -> None:
    """Stop and forget every shared machine (tests)."""
    with _SHARED_LOCK:
        machines = list(_SHARED.values())
        _SHARED.clear()
    for machine in machines:
        machine.stop()


class Serial(SerialBase):
    """A serial port whose far end is a simulated device."""

    def __init__(self, *args, **kwargs):
        self.machine: SimulatedGrbl | None = None
        self._shared = False
        super().__init__(*args, **kwargs)

    def open(self) -> None:
        if self.is_open:
            raise SerialException("Port is already open.")
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        parts = urllib.parse.urlsplit(self._port)
        if parts.scheme != "sim":
            raise SerialException(f"expected a sim:// URL, got {self._port!r}")
        device = parts.netloc or parts.path.lstrip("/")
        if device != "grbl":
            raise SerialException(f"{self._port!r}: unknown simulated device {device!r}; known: grbl")
        query = {k: v[-1] for k, v in urllib.parse.parse_qs(parts.query, keep_blank_values=True).items()}
        try:
            config = SimConfig.from_query(query)
        except SimConfigError as error:
            raise SerialException(f"{self._port!r}: {error}") from None
        if config.name:
            self._shared = True
            with _SHARED_LOCK:
                machine = _SHARED.get(config.name)
                if machine is None or not machine.connected:
                    if machine is not None:
                        machine.stop()
                    machine = SimulatedGrbl(config, self._baudrate)
                    _SHARED[config.name] = machine
                else:
                    machine.greet()  # opening the port resets an Arduino (DTR): it greets again
            self.machine = machine
        else:
            self.machine = SimulatedGrbl(config, self._baudrate)
        self.is_open = True

    def close(self) -> None:
        if self.is_open and self.machine is not None and not self._shared:
            self.machine.stop()
        self.is_open = False
        super().close()

    def _reconfigure_port(self) -> None:
        pass

    def _check(self) -> SimulatedGrbl:
        if not self.is_open or self.machine is None:
            raise PortNotOpenError()
        return self.machine

    @property
    def in_waiting(self) -> int:
        machine = self._check()
        if not machine.connected and not machine.bytes_waiting():
            raise SerialException("device disconnected (simulated unplug)")
        return machine.bytes_waiting()

    def read(self, size: int = 1) -> bytes:
        machine = self._check()
        try:
            return machine.read_output(size, self._timeout)
        except ConnectionError:
            raise SerialException("device reports readiness to read but returned no data "
                                  "(device disconnected or multiple access on port?)") from None

    def write(self, data) -> int:
        machine = self._check()
        if not machine.connected:
            raise SerialException("write failed: device disconnected (simulated unplug)")
        data = to_bytes(data)
        machine.receive(data)
        return len(data)

    def reset_input_buffer(self) -> None:
        self._check().clear_output()

    def reset_output_buffer(self) -> None:
        self._check()

    @property
    def out_waiting(self) -> int:
        return 0

    def _update_break_state(self) -> None:
        pass

    def _update_rts_state(self) -> None:
        pass

    def _update_dtr_state(self) -> None:
        pass

    @property
    def cts(self) -> bool:
        return True

    @property
    def dsr(self) -> bool:
        return True

    @property
    def ri(self) -> bool:
        return False

    @property
    def cd(self) -> bool:
        return True
