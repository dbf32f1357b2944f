"""What a GRBL controller's settings (``$$``) and build options (``[OPT:]``) say about the machine: homing, soft
limits, the machine space they allow, the travel, laser mode, how long homing may take."""

from __future__ import annotations

__all__ = ["MachineSettings"]


class MachineSettings:
    """Read-only views of ``settings`` (``{N: value}`` of ``$N=value``) and ``options`` (the letters of ``[OPT:]``).

    A base of :class:`drivers.grbl.connection.GrblConnection`, which keeps both up to date from ``$$`` and ``$I``.
    """

    settings: dict[int, float]
    options: str

    @property
    def homing_enabled(self) -> bool:
        """``$22=1``: the machine homes, so machine coordinates say where the head is on the machine. Without homing
        machine zero is wherever the head stood at power-up (or the last ``$X`` after a reset in motion)."""
        return int(self.settings.get(22, 0)) == 1

    @property
    def soft_limits(self) -> bool:
        """``$20=1`` (GRBL accepts it only with homing on, and ``$22=0`` clears it)."""
        return int(self.settings.get(20, 0)) == 1 and self.homing_enabled

    @property
    def force_origin(self) -> bool:
        """Built with HOMING_FORCE_SET_ORIGIN (``Z`` in ``[OPT:...]``): homing sets every homed axis to 0."""
        return "Z" in self.options

    def machine_bounds(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """The homed machine space ``(lo, hi)`` per axis, as GRBL's soft limits (``system_check_travel_limits``)
        see it: -travel..0 for every axis; with HOMING_FORCE_SET_ORIGIN, 0..+travel for an axis whose homing
        direction bit (``$23``) is set and -travel..0 for the others. Meaningful only when :attr:`homing_enabled`."""
        mask = int(self.settings.get(23, 0))
        lo, hi = [], []
        for axis, travel in enumerate(self.travel):
            positive = self.force_origin and bool(mask & (1 << axis))
            lo.append(0.0 if positive else -travel)
            hi.append(travel if positive else 0.0)
        return tuple(lo), tuple(hi)

    def homing_seconds(self) -> float:
        """An upper bound of how long ``$H`` may take, from the settings: GRBL answers nothing until it ends.

        ``limits_go_home`` runs, per homing cycle, a search of 1.5 x the travel (``$130``-``$132``) at the seek
        rate ``$25``, a pull-off ``$27`` at the seek rate, a locate of 5 x the pull-off at the feed rate ``$24`` and a
        pull-off again, each followed by the debounce delay ``$26`` (ms). Each axis is counted as a cycle of its
        own (the cycles GRBL was built with group some), and the sum is doubled for acceleration: a bound, not an
        estimate. 60 s before the settings are read.
        """
        if not self.settings:
            return 60.0
        seek = max(self.settings.get(25, 500.0), 1.0) / 60.0  # mm/s
        feed = max(self.settings.get(24, 25.0), 1.0) / 60.0
        pulloff = self.settings.get(27, 1.0)
        debounce = self.settings.get(26, 250.0) / 1000.0
        per_axis = [1.5 * travel / seek + 2 * pulloff / seek + 5 * pulloff / feed + 4 * debounce
                    for travel in self.travel]
        return 2.0 * sum(per_axis) + 5.0

    @property
    def travel(self) -> tuple[float, float, float]:
        return (self.settings.get(130, 0.0), self.settings.get(131, 0.0), self.settings.get(132, 0.0))

    @property
    def laser_mode(self) -> bool:
        return int(self.settings.get(32, 0)) == 1
