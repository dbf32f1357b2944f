"""The simulated GRBL's planner and motion: blocks that take time, feed hold and cycle start, the machine space.

Each block runs at its feed (``G0`` at ``$110``-``$112``), limited by acceleration (``$120``-``$122``) so that the
machine can always stop within the planned blocks, as GRBL's look-ahead does; motion times are multiplied by
``time_scale``. Times are the machine's clock (:mod:`drivers.sim.clock`). :class:`Planner` is a mixin of
:class:`drivers.sim.grbl.SimulatedGrbl`: it works on the machine's planner queue, position, state and record.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from drivers.sim.grbl.record import ExecutedBlock, Sample
from drivers.sim.grbl.settings import PLANNER_BLOCKS


@dataclass
class Block:
    """One planned move: from ``start`` to ``end`` (machine mm); once started, it runs from ``seg_start`` (where a
    resumed hold left it) from time ``t0`` for ``duration``."""

    start: np.ndarray
    end: np.ndarray
    length: float
    feed: float  # mm/min
    rapid: bool
    power: float
    spindle: int
    line_no: int
    text: str
    jog: bool = False
    from_rest: bool = False  # planned with the planner empty: GRBL enters it at speed 0 (drivers.grbl.planner)
    t0: float = 0.0
    duration: float = 0.0
    seg_start: np.ndarray | None = None


class Planner:
    """Motion of :class:`drivers.sim.grbl.SimulatedGrbl` (a mixin)."""

    def _travel(self) -> np.ndarray:
        return np.array([self.settings[130], self.settings[131], self.settings[132]], dtype=float)

    def _machine_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Machine space ``(lo, hi)`` per axis as GRBL's ``system_check_travel_limits`` sees it: -travel..0, or
        0..+travel for an axis whose ``$23`` bit is set when built with HOMING_FORCE_SET_ORIGIN."""
        travel = self._travel()
        mask = int(self.settings[23])
        positive = np.array([self.config.force_origin and bool(mask & (1 << i)) for i in range(3)])
        return np.where(positive, 0.0, -travel), np.where(positive, travel, 0.0)

    def _within_travel(self, target: np.ndarray) -> bool:
        lo, hi = self._machine_bounds()
        return bool(np.all((target <= hi + 1e-4) & (target >= lo - 1e-4)))

    def _planner_full(self) -> bool:
        return len(self._planner) >= PLANNER_BLOCKS

    def _laser_mode(self) -> bool:
        return int(self.settings[32]) == 1

    def _current_block(self) -> Block | None:
        if self._planner and self._planner[0].seg_start is not None:
            return self._planner[0]
        return None

    def _position(self, now: float) -> np.ndarray:
        if self._decel is not None:
            t0, t1, p0, p1, _ = self._decel
            tau = min(1.0, max(0.0, (now - t0) / (t1 - t0))) if t1 > t0 else 1.0
            return p0 + (p1 - p0) * (1.0 - (1.0 - tau) ** 2)  # constant deceleration
        block = self._current_block()
        if block is None or self._hold:
            return self.mpos.copy()
        frac = min(1.0, max(0.0, (now - block.t0) / block.duration)) if block.duration > 0 else 1.0
        return block.seg_start + (block.end - block.seg_start) * frac

    def _block_power(self, block: Block | None) -> float:
        if not self._laser_mode():
            return self._spindle_out
        if block is None or block.rapid or block.jog or (self._hold and self._decel is None) or block.spindle == 5:
            return 0.0
        return min(block.power, self.settings[30])

    def _sample(self, t: float, power: float | None = None) -> None:
        pos = self._position(t)
        if power is None:
            power = self._block_power(self._current_block())
        self.record.samples.append(Sample(t, float(pos[0]), float(pos[1]), float(pos[2]), float(power), self._state))

    def _fill_changed(self, t: float) -> None:
        moving = self._current_block() is not None and not self._hold
        self.record.planner_fill.append((t, len(self._planner), moving))
    def _feed_hold(self, now: float) -> None:
        if self._state in ("Run", "Idle") and not self._halted:
            block = self._current_block()
            if block is not None and block.duration > 0:
                # decelerate along the block at the axes' acceleration (Hold:1), then stop (Hold:0)
                position = self._position(now)
                direction = (block.end - block.seg_start) / max(np.linalg.norm(block.end - block.seg_start), 1e-12)
                speed = np.linalg.norm(block.end - block.seg_start) / (block.duration / self.config.time_scale)
                accel = np.array([self.settings[120], self.settings[121], self.settings[122]])
                moving = np.abs(direction) > 1e-12
                a = float(np.min(accel[moving] / np.abs(direction[moving]))) if moving.any() else 1.0
                remaining = float(np.linalg.norm(block.end - position))
                stop = min(speed * speed / (2 * a), remaining)
                decel_time = (2 * stop / speed if speed > 0 else 0.0) * self.config.time_scale
                left = max(0.0, (remaining - stop) / speed * self.config.time_scale) if speed > 0 else 0.0
                self._decel = (now, now + decel_time, position, position + direction * stop, left)
                self._hold = True
                self._state = "Hold:1"
                self._sample(now)
            else:
                self._hold = True
                self._state = "Hold:0"
                self._sample(now, 0.0 if self._laser_mode() else None)
                self._hold_complete()
            self._fill_changed(now)
        elif self._state == "Jog":
            self._jog_cancel(now)

    def _hold_complete(self) -> None:
        # DISABLE_LASER_DURING_HOLD: in laser mode a completed hold stops the spindle (protocol_exec_rt_suspend's
        # spindle stop override), and the status report's spindle speed reads 0 until the cycle resumes
        if self._laser_mode():
            self._laser_fs = 0.0

    def _jog_cancel(self, now: float) -> None:
        if self._state == "Jog":
            self.mpos = self._position(now)
            self._planner.clear()
            self._gc_pos = self.mpos.copy()
            self._state = "Idle"
            self._sample(now, 0.0 if self._laser_mode() else None)
            self._fill_changed(now)

    def _cycle_start(self, now: float) -> None:
        if self._state == "Hold:0":  # GRBL ignores cycle start until the hold is complete
            self._hold = False
            block = self._current_block()
            if self._laser_mode() and self.modal["spindle"] in (3, 4):
                self._emit("[MSG:Restoring spindle]")  # the spindle stop override of the hold ends
            if block is not None:
                block.seg_start = self.mpos.copy()
                block.t0 = now
                block.duration = self._hold_remaining
                self._state = "Run"
                self._laser_fs = self._block_power(block)
            else:
                self._state = "Idle"
            self._sample(now)
            self._fill_changed(now)
    def _advance(self, now: float) -> None:
        if self._decel is not None and now >= self._decel[1]:
            self.mpos = self._decel[3].copy()
            self._hold_remaining = self._decel[4]
            self._decel = None
            self._state = "Hold:0"
            self._sample(now, 0.0 if self._laser_mode() else None)
            self._hold_complete()
        if self._state == "Home" and now >= self._home_until:
            # where limits_go_home sets each axis: pulled off the switch, inside the machine space
            pulloff = self.settings[27]
            towards_minus = np.array([bool(int(self.settings[23]) & (1 << i)) for i in range(3)])
            if self.config.force_origin:
                self.mpos = np.zeros(3)
            else:
                self.mpos = np.where(towards_minus, -self._travel() + pulloff, -pulloff)
            self._gc_pos = self.mpos.copy()
            if self._report_owed:
                self._report_owed = False
                self._emit(self._status_report(now), "status")  # still in Home: mc_homing_cycle serves it
            self._state = "Idle"
            self._sample(now, 0.0)
            return
        if self._hold or self._halted:
            return
        while self._planner:
            block = self._planner[0]
            if block.seg_start is None:
                self._start_block(block, now)
                continue
            t_end = block.t0 + block.duration
            if t_end > now:
                return
            self.mpos = block.end.copy()
            self._planner.popleft()
            self.record.executed.append(ExecutedBlock(
                block.line_no, block.text, tuple(float(v) for v in block.end), self._block_power(block), block.feed,
                block.rapid, block.jog, t_end, tuple(float(v) for v in block.start), block.from_rest))
            self._motion_t = t_end
            if self._planner:
                self._start_block(self._planner[0], t_end)
            else:
                if self._state in ("Run", "Jog"):
                    self._state = "Idle"
                if block.spindle == 4:
                    self._laser_fs = 0.0  # M4's power follows the speed, which is now 0 (M3 keeps its S)
                self.record.samples.append(Sample(t_end, *map(float, self.mpos), 0.0 if self._laser_mode()
                                                  else self._spindle_out, self._state))
            self._fill_changed(t_end)

    def _start_block(self, block: Block, t: float) -> None:
        delta = np.abs(block.end - block.start)
        unit = delta / block.length
        moving = unit > 1e-12
        max_rate = np.array([self.settings[110], self.settings[111], self.settings[112]])
        accel = np.array([self.settings[120], self.settings[121], self.settings[122]])
        rate_limit = float(np.min(max_rate[moving] / unit[moving]))
        accel_limit = float(np.min(accel[moving] / unit[moving]))
        feed = rate_limit if block.rapid else min(block.feed * self.overrides[0] / 100.0, rate_limit)
        if block.rapid:
            feed = rate_limit * self.overrides[1] / 100.0
        lookahead = sum(b.length for b in self._planner)  # GRBL must be able to stop at the end of the plan
        speed = min(feed / 60.0, math.sqrt(2.0 * accel_limit * lookahead))
        block.seg_start = block.start.copy()
        block.t0 = t
        block.duration = block.length / max(speed, 1e-6) * self.config.time_scale
        if self._state in ("Idle", "Run", "Jog"):
            self._state = "Jog" if block.jog else "Run"
        # laser mode: the stepper sets the spindle speed a report shows as each block starts (0 on G0 and jogs)
        self._laser_fs = self._block_power(block)
        self._sample(t, self._block_power(block))

    def _plan(self, target: np.ndarray, rapid: bool, feed: float, text: str, jog: bool = False) -> None:
        length = float(np.linalg.norm(target - self._gc_pos))
        if length < 1e-6:
            return  # GRBL drops zero-length blocks
        power = self.spindle_speed if self.modal["spindle"] in (3, 4) else 0.0
        self._planner.append(Block(self._gc_pos.copy(), target.copy(), length, feed, rapid, power,
                                    self.modal["spindle"], self._gcode_lines, text, jog, not self._planner))
        self._gc_pos = target.copy()
        self._fill_changed(self._parse_time)
