"""A simulated GRBL 1.1 controller that speaks the serial protocol byte for byte.

What it models
--------------
- The 128-byte serial RX buffer (a ring buffer: 127 bytes usable; ``Bf`` second field reports 128 minus the bytes in
  it, as GRBL's ``serial_get_rx_buffer_available`` does), with overflow counted (a correct streamer never overflows it)
  and GRBL's line reading (one line at a time, blocked while the planner is full).
- The 15-block planner (``Bf`` first field) and motion that takes time: each block runs at its feed (``G0`` at
  ``$110``-``$112``), limited by acceleration (``$120``-``$122``) so that the machine can always stop within the
  planned blocks, as GRBL's look-ahead does; all motion and dwell times are multiplied by ``time_scale``.
- Time from an injectable clock (:mod:`drivers.sim.clock`): the wall clock, or a virtual one on which simulated time
  jumps ahead whenever the machine would wait for motion, a dwell or homing to finish and the host has had its turn,
  so that a job runs as fast as the host streams it, with the same simulated timing. The host (the driver's status
  poll, watchdogs, streaming) stays on the wall clock and works unchanged.
- Real-time commands ``?`` ``!`` ``~`` 0x18 (soft reset) 0x85 (jog cancel) and overrides, handled on arrival.
- ``$$``, ``$x=val``, ``$I`` (``[OPT:V,15,128]``), ``$#``, ``$G``, ``$N``, ``$C`` (check mode), ``$X``, ``$H``,
  ``$J=``, ``$RST=``; G-code errors with GRBL's numbers (error:9 locked, error:20 unsupported, error:22 no feed ...).
- Soft limits as GRBL 1.1 checks them (``system_check_travel_limits``): only with ``$20=1``, which needs homing
  (``$20=1`` with ``$22=0`` answers error:10, and ``$22=0`` also clears ``$20``); every axis in -travel..0, or with
  the build option HOMING_FORCE_SET_ORIGIN (``force_origin=1``, ``Z`` in ``[OPT:]``) an axis whose ``$23`` bit is
  set in 0..+travel. A target outside: a running cycle is held to a stop first (``limits_soft_check``), then
  ALARM:2, ``[MSG:Reset to continue]``, nothing at all (not even a status report) until a soft reset, and the
  triggering line's ``ok`` only after the reset. Without homing there are no machine-space limits at all: machine
  zero is where the head stood at power-up (and G54 starts at zero there, GRBL's default).
- Homing ``$H`` (error:5 with ``$22=0``) ends where GRBL's ``limits_go_home`` sets the position: ``-$27`` (pull-off)
  for an axis homing towards +, ``-travel + $27`` for one whose ``$23`` bit is set, 0 with HOMING_FORCE_SET_ORIGIN.
  As in GRBL 1.1, ``?`` gets no answer while the cycle runs (1.5 simulated seconds): one ``<Home|...>`` report
  follows its end, however many were asked for.
- ``$I`` prints ``[VER:1.1h.20190830:<build info>]`` (report.c's format) with the build info ``$I=`` stored.
- Reset during motion: ALARM:3 and alarm lock; laser mode ``$32=1`` with M3 (constant) and M4 (dynamic) power,
  dark rapids and dark feed hold (the status report's spindle speed is what motion set: ``FS:0,0`` in a completed
  hold, ``[MSG:Restoring spindle]`` when it resumes).
- Probing ``G38.2``-``G38.5`` as ``mc_probe_cycle`` runs it, against a touch plate whose top is at machine Z
  ``probe_z``: ``[PRB:x,y,z:1]`` at contact (the machine stops just past it), ALARM:4 when the probe touches before it
  starts (away: does not touch), ALARM:5 when a G38.2/G38.4 never touches, ``Pn:P`` while touching, ``$#``'s
  ``[PRB:]``.
- Power-up: with homing (``$22=1``) and ``homed=0``, GRBL's HOMING_INIT_LOCK: alarm until ``$H`` or ``$X``, G54 at 0.
- A record of what it executed (:class:`SimRecord`): every block's end position, laser power and timing, samples of
  position and laser power over time, soft resets, lines received.

URL query parameters (``sim://grbl?profile=laser&time_scale=0.05&seed=3``)
--------------------------------------------------------------------------
``profile`` (``plotter``/``laser``), ``name`` (share one machine between opens), ``time_scale`` (real seconds per
simulated second), ``latency`` (seconds each way), ``wire`` (0 disables the baud-rate transfer time), ``seed``,
``drop`` / ``corrupt`` / ``stray`` / ``delay`` (probabilities per reply line), ``delay_max`` (seconds),
``disconnect_at`` (the N-th G-code line received unplugs the port), ``drop_reply_at`` (the reply to the N-th
G-code line is lost), ``locked`` (power up in alarm), ``homing`` (``0``: ``$22=0``, which also clears soft limits
``$20`` as GRBL does; ``1``: ``$22=1``), ``homed`` (with homing: ``1``, the default, is the station's machine as its
maker left it, homed at machine zero with work zero, G54, at the front-left corner; ``0`` is GRBL as switched on:
locked in alarm until ``$H`` or ``$X`` (HOMING_INIT_LOCK), at machine zero, with G54 at 0 as a fresh EEPROM has it),
``travel`` (``$130``-``$132`` as ``WxD`` or ``WxDxH`` in mm, e.g.
``travel=400x400``), ``force_origin`` (``1``: built with HOMING_FORCE_SET_ORIGIN), ``probe_z`` (the top of a touch
plate, machine Z in mm; without it a probe never touches), ``record`` (a file the machine
writes its record to as JSON when its port closes: what another process, e.g. a test of ``station send``, can
inspect), ``clock`` (``wall``, the default, or ``virtual``: simulated time skips the machine's waits; the record's
times are then simulated seconds from 0, and ``time_scale`` still scales them), ``pace`` (with ``clock=virtual``:
at most this many simulated seconds per wall second, for a test that acts while a job runs), and ``s<N>=<value>``
to override setting ``$N`` (applied last; ``s20=1`` with homing off is refused, as GRBL answers ``$20=1`` with
error:10). An unknown option or a bad value is a :class:`drivers.errors.SimConfigError` (also a ``ValueError``)
naming it.

From Python: ``SimulatedGrbl(SimConfig(profile="laser"), clock=VirtualClock())``.

Modules
-------
The package beside the driver it mirrors (:mod:`drivers.grbl`); it re-exports the names of its modules:
:mod:`~drivers.sim.grbl.machine` (the machine: its loop, line parser, soft reset, status report),
:mod:`~drivers.sim.grbl.wire` (wire, faults, real-time bytes), :mod:`~drivers.sim.grbl.settings` (EEPROM,
:data:`SIM_PROFILES`, :class:`SimConfig`, ``$`` commands), :mod:`~drivers.sim.grbl.gcode` (G-code interpretation),
:mod:`~drivers.sim.grbl.motion` (planner and timing), :mod:`~drivers.sim.grbl.record` (what it executed) and
:mod:`~drivers.sim.clock`.
"""

from drivers.sim.clock import Clock, VirtualClock, WallClock
from drivers.sim.grbl.gcode import GrblError, clean_block, grbl_words
from drivers.sim.grbl.machine import SimulatedGrbl
from drivers.sim.grbl.motion import Block
from drivers.sim.grbl.record import ExecutedBlock, Sample, SimRecord
from drivers.sim.grbl.settings import (
    BANNER,
    BUILD_DATE,
    DEFAULT_SETTINGS,
    INTEGER_SETTINGS,
    LINE_BUFFER_SIZE,
    PLANNER_BLOCKS,
    RX_BUFFER_SIZE,
    SIM_PROFILES,
    VERSION,
    ZERO_DECIMAL_SETTINGS,
    SimConfig,
)
from drivers.sim.grbl.wire import (
    REALTIME_HOLD,
    REALTIME_JOG_CANCEL,
    REALTIME_RESET,
    REALTIME_SAFETY_DOOR,
    REALTIME_START,
    REALTIME_STATUS,
)

__all__ = [
    "BANNER", "BUILD_DATE", "DEFAULT_SETTINGS", "INTEGER_SETTINGS", "LINE_BUFFER_SIZE", "PLANNER_BLOCKS",
    "REALTIME_HOLD", "REALTIME_JOG_CANCEL", "REALTIME_RESET", "REALTIME_SAFETY_DOOR", "REALTIME_START",
    "REALTIME_STATUS", "RX_BUFFER_SIZE", "SIM_PROFILES", "VERSION", "ZERO_DECIMAL_SETTINGS", "Block", "Clock",
    "ExecutedBlock", "GrblError", "Sample", "SimConfig", "SimRecord", "SimulatedGrbl", "VirtualClock", "WallClock",
    "clean_block", "grbl_words",
]
