"""The simulated GRBL's G-code interpreter: words with GRBL's error numbers, modal groups, motion, arcs, jogs.

A line becomes a generator (:meth:`GcodeInterpreter._gcode`, :meth:`GcodeInterpreter._jog`) that the machine's
parser runs: it yields what it waits for (``"space"`` in the planner, ``"sync"``: the planner empty, ``("time", t)``:
a dwell) and returns 0 for ``ok`` or GRBL's error number. Words and arc geometry come from
:mod:`drivers.gcode_words`, shared with :mod:`drivers.gcode`; GRBL's own rules stay here: a letter GRBL does not
know is error:20, a bad number error:2, an arc is divided into GRBL's number of segments (``$12``) and a radius
that cannot reach is error:33.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from drivers import gcode_words
from drivers.sim.grbl.settings import Halt, xyz

#: G38.2-G38.5: probe towards the work (alarm if nothing is touched / no alarm), away from it (the same).
PROBE_MODES = (38.2, 38.3, 38.4, 38.5)


class GrblError(Exception):
    """A line GRBL refuses; ``code`` is the number of its ``error:N`` reply."""

    def __init__(self, code: int) -> None:
        super().__init__(code)
        self.code = code


_SUPPORTED_LETTERS = set("FGIJKLMNPRSTXYZ")


def grbl_words(text: str) -> list[tuple[str, float]]:
    """The words of a cleaned block, judged left to right as GRBL's parser does.

    Raises
    ------
    GrblError
        error:1 where a letter is expected, error:2 for a letter without a number, error:20 for a letter GRBL does
        not support; the first fault from the left decides.
    """
    words = []
    try:
        for letter, value in gcode_words.iter_words(text):
            if letter not in _SUPPORTED_LETTERS:
                raise GrblError(20)
            words.append((letter, value))
    except gcode_words.WordSyntaxError as error:
        raise GrblError(1 if error.expected == "letter" else 2) from None
    return words


@dataclass
class _Classified:
    groups: dict
    values: dict


_G_GROUPS = {
    0.0: ("motion", 0), 1.0: ("motion", 1), 2.0: ("motion", 2), 3.0: ("motion", 3), 80.0: ("motion", 80),
    38.2: ("motion", 38.2), 38.3: ("motion", 38.3), 38.4: ("motion", 38.4), 38.5: ("motion", 38.5),
    4.0: ("nonmodal", 4.0), 10.0: ("nonmodal", 10.0), 28.0: ("nonmodal", 28.0), 28.1: ("nonmodal", 28.1),
    30.0: ("nonmodal", 30.0), 30.1: ("nonmodal", 30.1), 53.0: ("nonmodal", 53.0), 92.0: ("nonmodal", 92.0),
    92.1: ("nonmodal", 92.1), 17.0: ("plane", 17), 18.0: ("plane", 18), 19.0: ("plane", 19),
    90.0: ("distance", 90), 91.0: ("distance", 91), 91.1: ("arcdistance", 91.1), 93.0: ("feedmode", 93),
    94.0: ("feedmode", 94), 20.0: ("units", 20), 21.0: ("units", 21), 40.0: ("cutter", 40),
    43.1: ("tlo", 43.1), 49.0: ("tlo", 49), 54.0: ("wcs", 54), 55.0: ("wcs", 55), 56.0: ("wcs", 56),
    57.0: ("wcs", 57), 58.0: ("wcs", 58), 59.0: ("wcs", 59), 61.0: ("control", 61),
}
_M_GROUPS = {0.0: ("stop", 0), 1.0: ("stop", 1), 2.0: ("stop", 2), 30.0: ("stop", 30), 3.0: ("spindle", 3),
             4.0: ("spindle", 4), 5.0: ("spindle", 5), 8.0: ("coolant", 8), 9.0: ("coolant", 9)}


def _classify(words: list[tuple[str, float]]) -> _Classified:
    groups: dict = {}
    values: dict = {}
    for letter, value in words:
        if letter in "GM":
            table = _G_GROUPS if letter == "G" else _M_GROUPS
            key = round(value, 1)
            if key not in table:
                raise GrblError(20 if letter == "G" or value == int(value) else 23)
            group, code = table[key]
            if group in groups:
                raise GrblError(21)
            groups[group] = code
        else:
            if letter in values:
                raise GrblError(25)
            values[letter] = value
    return _Classified(groups, values)


def clean_block(raw: str) -> str:
    """The block GRBL keeps of a line: no comments, no whitespace or control characters, upper case."""
    return "".join(ch for ch in gcode_words.strip_comments(raw) if ch > " " and ch != "\x7f").upper()


def axis_target(base: np.ndarray, axis_words: dict[int, float], unit: float, absolute: bool, wco: np.ndarray,
                machine_coords: bool = False) -> np.ndarray:
    """Where a move ends in machine mm: ``base`` with each named axis (index: value in the line's units) set in
    machine coordinates (G53), in work coordinates (G90: plus the work offset ``wco``) or relative (G91)."""
    target = base.copy()
    for i, v in axis_words.items():
        if machine_coords:
            target[i] = v * unit
        elif absolute:
            target[i] = v * unit + wco[i]
        else:
            target[i] = target[i] + v * unit
    return target


class GcodeInterpreter:
    """G-code lines and jogs of :class:`drivers.sim.grbl.SimulatedGrbl` (a mixin: it works on the machine's modal
    state, work offsets, planner and output)."""

    def _jog(self, body: str):
        if self._state not in ("Idle", "Jog"):
            return 8
        try:
            words = grbl_words(body)
        except GrblError as error:
            return error.code
        absolute = self.modal["distance"] == 90
        unit = 1.0 if self.modal["units"] == 21 else 25.4
        machine = False
        axes: dict[int, float] = {}
        feed = None
        for letter, value in words:
            if letter == "G":
                if value in (90.0, 91.0):
                    absolute = value == 90.0
                elif value in (20.0, 21.0):
                    unit = 1.0 if value == 21.0 else 25.4
                elif value == 53.0:
                    machine = True
                else:
                    return 16
            elif letter in "XYZ":
                axes["XYZ".index(letter)] = value
            elif letter == "F":
                feed = value
            elif letter == "N":
                continue
            else:
                return 16
        if feed is None:
            return 22
        if not axes:
            return 26
        target = axis_target(self._gc_pos, axes, unit, absolute, self._wco(), machine)
        if int(self.settings[20]) and not self._within_travel(target):
            return 15
        if self._check_mode:
            return 0
        while self._planner_full():
            yield "space"
        self._plan(target, False, feed * unit, "$J=" + body, jog=True)
        return 0

    def _gcode(self, text: str):
        try:
            words = grbl_words(text)
            block = _classify(words)
        except GrblError as error:
            return error.code
        m = dict(self.modal)
        unit = 1.0
        if "units" in block.groups:
            m["units"] = block.groups["units"]
        unit = 1.0 if m["units"] == 21 else 25.4
        values = block.values
        for letter in ("F", "S", "T", "N", "P"):
            if letter in values and values[letter] < 0:
                return 4
        if "T" in values and values["T"] > 255:
            return 38
        if "N" in values and values["N"] > 9999999:
            return 27
        if "feedmode" in block.groups:
            m["feedmode"] = block.groups["feedmode"]
        feed = self.feed
        if "F" in values:
            feed = values["F"] * unit
        elif m["feedmode"] == 93:
            feed = 0.0
        motion = block.groups.get("motion", m["motion"])
        nonmodal = block.groups.get("nonmodal")
        axis_words = {i: values[a] for i, a in enumerate("XYZ") if a in values}
        axis_user = nonmodal in (10.0, 28.0, 30.0, 92.0)
        if axis_words and not axis_user and motion == 80:
            return 31
        probe = motion in PROBE_MODES
        if probe and "motion" in block.groups and not axis_words:
            return 26  # [G38 Errors]: no axis words
        uses_motion = bool(axis_words) and not axis_user and (motion in (0, 1, 2, 3) or probe)
        if "motion" in block.groups and motion in (1, 2, 3) and not axis_words and not axis_user:
            uses_motion = False
        if uses_motion and (motion in (1, 2, 3) or probe) and feed <= 0:
            return 22
        if motion in (2, 3) and uses_motion:
            if not ({"I", "J", "K", "R"} & values.keys()):
                return 35
        unused = set(values) & {"I", "J", "K", "R"}
        if unused and not (uses_motion and motion in (2, 3)):
            return 36
        if "L" in values and nonmodal != 10.0:
            return 36
        if "P" in values and nonmodal not in (4.0, 10.0):
            return 36
        if nonmodal == 53.0 and motion not in (0, 1):
            return 30
        if nonmodal == 4.0 and "P" not in values:
            return 28
        if nonmodal == 10.0 and ("L" not in values or "P" not in values):
            return 28
        if nonmodal == 10.0 and (values["L"] not in (2.0, 20.0) or values["P"] not in range(0, 7)):
            return 20

        # -- execute in GRBL's order
        self.modal["feedmode"] = m["feedmode"]
        self.feed = feed
        new_speed = values.get("S", self.spindle_speed)
        new_spindle = block.groups.get("spindle", self.modal["spindle"])
        spindle_changed = new_spindle != self.modal["spindle"]
        speed_changed = new_speed != self.spindle_speed
        if "T" in values:
            self.tool = int(values["T"])
        if spindle_changed or (speed_changed and new_spindle in (3, 4) and not self._laser_mode()):
            if not self._check_mode:
                yield "sync"
            self.modal["spindle"] = new_spindle
            self.spindle_speed = new_speed
            self._spindle_changed()
        else:
            self.spindle_speed = new_speed
        if "coolant" in block.groups:
            self.modal["coolant"] = block.groups["coolant"]
        if nonmodal == 4.0:
            if not self._check_mode:
                yield "sync"
                yield ("time", self._parse_time + values["P"] * self.config.time_scale)
        for key in ("plane", "units", "distance", "wcs"):
            if key in block.groups:
                self.modal[key] = block.groups[key]
        if block.groups.get("arcdistance", 91.1) != 91.1:
            return 20
        if "tlo" in block.groups:
            self.tlo = values.get("Z", 0.0) * unit if block.groups["tlo"] == 43.1 else 0.0
            axis_words.pop(2, None)
        wco = self._wco()
        absolute = self.modal["distance"] == 90

        def work_target(base_machine: np.ndarray, machine_coords: bool = False) -> np.ndarray:
            return axis_target(base_machine, axis_words, unit, absolute, wco, machine_coords)

        if nonmodal == 10.0:
            index = int(values["P"]) or self.modal["wcs"] - 53
            n = 53 + index
            data = self.coords[n].copy()
            for i, v in axis_words.items():
                if values["L"] == 2.0:
                    data[i] = v * unit
                else:  # L20: current position becomes the given work value
                    data[i] = self._gc_pos[i] - self.g92[i] - v * unit - (self.tlo if i == 2 else 0.0)
            if not self._check_mode:
                yield "sync"  # EEPROM write
            self.coords[n] = data
            self._wco_counter = 0  # GRBL reports the new offset in the next status report
            return 0
        if nonmodal == 92.0:
            for i, v in axis_words.items():
                self.g92[i] = self._gc_pos[i] - self.coords[self.modal["wcs"]][i] - v * unit
            self._wco_counter = 0
            return 0
        if nonmodal == 92.1:
            self.g92 = np.zeros(3)
            self._wco_counter = 0
            return 0
        if nonmodal in (28.1, 30.1):
            if not self._check_mode:
                yield "sync"
            if nonmodal == 28.1:
                self.g28 = self._gc_pos.copy()
            else:
                self.g30 = self._gc_pos.copy()
            return 0
        if nonmodal in (28.0, 30.0):
            stored = self.g28 if nonmodal == 28.0 else self.g30
            if axis_words:
                yield from self._move(work_target(self._gc_pos), True, feed, text)
            yield from self._move(stored.copy(), True, feed, text)
            return 0
        if uses_motion and probe:
            target = work_target(self._gc_pos)
            if np.allclose(target, self._gc_pos):
                return 33  # [G38 Errors]: the target is where the head is
            self.modal["motion"] = motion
            yield from self._probe(target, motion, feed, text)
            return 0
        if "motion" in block.groups:
            self.modal["motion"] = block.groups["motion"]
        if uses_motion:
            target = work_target(self._gc_pos, nonmodal == 53.0)
            if motion in (0, 1):
                yield from self._move(target, motion == 0, feed, text)
            else:
                points = self._arc(target, motion == 2, values, unit)
                if points is None:
                    return 33
                for point in points:
                    yield from self._move(point, False, feed, text)
        stop = block.groups.get("stop")
        if stop == 0:  # M0 program pause (M1 optional stop is off on GRBL)
            if not self._check_mode:
                yield "sync"
                self._hold = True
                self._state = "Hold:0"
                self._hold_complete()
        elif stop in (2, 30):
            if not self._check_mode:
                yield "sync"
            self.modal.update(motion=1, wcs=54, plane=17, distance=90, feedmode=94, spindle=5, coolant=9)
            self.g92 = np.zeros(3)
            self._spindle_changed()
        return 0

    def _spindle_changed(self) -> None:
        on = self.modal["spindle"] in (3, 4)
        speed = min(max(self.spindle_speed, self.settings[31]), self.settings[30]) if on else 0.0
        self._spindle_out = speed if on else 0.0
        if not self._check_mode:
            self._sample(self._parse_time)

    def _move(self, target: np.ndarray, rapid: bool, feed: float, text: str):
        if int(self.settings[20]) and not self._within_travel(target):
            if self._state == "Run":
                # limits_soft_check: a feed hold brings the running motion to a controlled stop (Hold:1 in the
                # reports meanwhile), and only then comes the alarm: the position is kept
                self._feed_hold(self._parse_time)
                yield "stopped"
            self._soft_limit_alarm()
            raise Halt
        if self._check_mode:
            self._gc_pos = target.copy()
            return
        while self._planner_full():
            yield "space"
        if self.modal["feedmode"] == 93 and not rapid:
            length = float(np.linalg.norm(target - self._gc_pos))
            feed = length * feed if feed > 0 else feed
        self._plan(target, rapid, feed, text)

    def _probe_pin(self, position: np.ndarray) -> bool:
        """Whether the probe touches at ``position`` (machine mm): the twin's probe is a plate whose top is at machine
        Z ``probe_z`` (the URL option); without one nothing is ever touched."""
        return self.config.probe_z is not None and position[2] <= self.config.probe_z + 1e-9

    def _probe(self, target: np.ndarray, motion: float, feed: float, text: str):
        """G38.2 (towards the work, alarm if nothing is touched), G38.3 (the same without the alarm), G38.4/G38.5 (away
        from it, until contact is lost), as gnea/grbl's ``mc_probe_cycle`` runs them."""
        away, no_error = motion in (38.4, 38.5), motion in (38.3, 38.5)
        if int(self.settings[20]) and not self._within_travel(target):
            self._soft_limit_alarm()  # mc_line checks the probe's target like any other
            raise Halt
        if self._check_mode:
            self._gc_pos = target.copy()  # GC_PROBE_CHECK_MODE: the parser takes the target
            return
        yield "sync"  # protocol_buffer_synchronize: the planner empties first
        start = self.mpos.copy()
        if self._probe_pin(start) != away:
            self._probe_alarm(4)  # "Probe is not in the expected initial state": no motion, no [PRB:] report
            return
        end, contact = target, None
        if self.config.probe_z is not None and start[2] != target[2]:
            t = (start[2] - self.config.probe_z) / (start[2] - target[2])
            if 0.0 <= t <= 1.0:
                contact = start + (target - start) * t
                # the stepper cancels the motion at contact and decelerates to a stop a little further on
                length = float(np.linalg.norm(target - start))
                rate = min(feed, self.settings[110], self.settings[111], self.settings[112]) / 60.0
                stop = rate * rate / (2.0 * min(self.settings[120], self.settings[121], self.settings[122]))
                end = contact + (target - start) / length * min(stop, length * (1.0 - t))
        self._plan(end, False, feed, text)
        yield "sync"  # the cycle runs until the machine is idle again
        self._gc_pos = self.mpos.copy()
        if contact is not None:
            self.probe_position, self.probe_succeeded = contact, True
        elif no_error:
            self.probe_position, self.probe_succeeded = self.mpos.copy(), False
        else:
            self.probe_succeeded = False  # the last probe position stays
            self._probe_alarm(5)
        self._emit(f"[PRB:{xyz(self.probe_position)}:{int(self.probe_succeeded)}]")

    def _probe_alarm(self, code: int) -> None:
        # not a critical event: GRBL reports it, locks G-code (Alarm) and still answers the line and '?'
        self._state = "Alarm"
        self.record.alarms.append(code)
        self._emit(f"ALARM:{code}", "alarm")

    def _soft_limit_alarm(self) -> None:
        now = self._parse_time
        # GRBL has stopped (see _move), resets and spins in its critical-event loop until the user's reset:
        # the position is kept, and nothing but a reset is served meanwhile (not even a status request).
        self.mpos = self._position(now)
        self._planner.clear()
        self._hold = False
        self._decel = None
        self._state = "Alarm"
        self._halted = True
        self._critical = True
        self._owed_ok = True
        self._spindle_out = 0.0
        self._sample(now, 0.0)
        self._fill_changed(now)
        self.record.alarms.append(2)
        self._emit("ALARM:2", "alarm")
        self._emit("[MSG:Reset to continue]")

    def _arc(self, target: np.ndarray, clockwise: bool, values: dict, unit: float) -> np.ndarray | None:
        """Chord end points of an arc as GRBL's ``mc_arc`` divides it (``$12``), None for an invalid target
        (error:33)."""
        a, b = gcode_words.PLANE_AXES[self.modal["plane"]]
        start = self._gc_pos
        if "R" in values:
            r = values["R"] * unit
            d = math.hypot(target[a] - start[a], target[b] - start[b])
            if d == 0 or 4 * r * r - d * d < -1e-9:
                return None
            centre = gcode_words.radius_arc_centre(start, target, r, clockwise, (a, b))
        else:
            names = "IJK"
            centre = (start[a] + values.get(names[a], 0.0) * unit, start[b] + values.get(names[b], 0.0) * unit)
        r0 = math.hypot(start[a] - centre[0], start[b] - centre[1])
        r1 = math.hypot(target[a] - centre[0], target[b] - centre[1])
        if abs(r0 - r1) > 0.5 and abs(r0 - r1) > 0.001 * r0:  # GRBL error:33 (invalid target)
            return None
        t0, sweep = gcode_words.arc_sweep(start, target, centre, clockwise, (a, b), full_turn_below=1e-9)
        tol = self.settings[12]
        n = max(1, int(math.floor(abs(0.5 * sweep * r0) / math.sqrt(max(tol * (2 * r0 - tol), 1e-12)))))
        return gcode_words.arc_chords(start, target, centre, r0, t0, sweep, (a, b), n)
