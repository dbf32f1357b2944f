"""What the simulated GRBL executed: finished blocks, samples of position and power over time, resets, lines.

Times are the machine's clock (:mod:`drivers.sim.clock`): ``time.monotonic`` seconds on the wall clock, simulated
seconds from 0 on a virtual one.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field


@dataclass(frozen=True)
class ExecutedBlock:
    """One planner block the machine finished: the G-code line it came from, where it started and ended (machine
    mm), and whether it was planned with the planner empty (``from_rest``: GRBL enters it at speed 0)."""

    line_no: int
    text: str
    end: tuple[float, float, float]
    power: float
    feed: float
    rapid: bool
    jog: bool
    t_end: float
    start: tuple[float, float, float] = (0.0, 0.0, 0.0)
    from_rest: bool = False


@dataclass(frozen=True)
class Sample:
    """Machine position (mm) and laser/spindle output from time ``t`` (the machine's clock) on."""

    t: float
    x: float
    y: float
    z: float
    power: float
    state: str


@dataclass
class SimRecord:
    """Everything the simulated machine did, for tests and benchmarks."""

    executed: list[ExecutedBlock] = field(default_factory=list)
    samples: list[Sample] = field(default_factory=list)
    resets: list[float] = field(default_factory=list)
    received: list[str] = field(default_factory=list)
    overflow_bytes: int = 0
    planner_fill: list[tuple[float, int, bool]] = field(default_factory=list)
    alarms: list[int] = field(default_factory=list)
    replies_delivered: int = 0

    def write(self, path: str) -> None:
        """Write the record as JSON (``samples`` as ``[t, x, y, z, power, state]`` rows, oldest first)."""
        document = {
            "samples": [[s.t, s.x, s.y, s.z, s.power, s.state] for s in sorted(self.samples, key=lambda s: s.t)],
            "executed": [[b.line_no, b.text, list(b.end), b.power, b.t_end] for b in self.executed],
            "resets": self.resets, "received": self.received, "alarms": self.alarms,
        }
        with open(path, "w", encoding="utf-8") as stream:
            json.dump(document, stream)

    def power_after(self, t: float) -> float | None:
        """Laser output of the first sample at or after ``t`` (None if there is none)."""
        for sample in sorted(self.samples, key=lambda s: s.t):
            if sample.t >= t:
                return sample.power
        return None

    def mean_planner_fill(self) -> float:
        """Time-weighted mean number of planner blocks while the machine was moving."""
        total = weighted = 0.0
        for (t0, n, moving), (t1, _, _) in zip(self.planner_fill, self.planner_fill[1:]):
            if moving and t1 > t0:
                total += t1 - t0
                weighted += (t1 - t0) * n
        return weighted / total if total else 0.0

