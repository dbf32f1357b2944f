"""GRBL streaming through the simulated controller (115200 baud wire time, added USB latency each way).

Prints
- lines/s of character counting vs send-response at 2 ms and 8 ms latency (goal: >= 5x at 2 ms), for compact lines
  (modal G1, 0.1 mm grid) and full ones. At 115200 baud the ratio is bounded by 1 + 4/n + 2L/(n b) for n-byte lines,
  latency L and byte time b = 87 us: about 5.5 for 11-byte lines but 4.0 for 17-byte lines at 2 ms;
- the average planner fill on a job of 0.1 mm segments at F6000 (goal: >= 14 of 15 blocks), time-weighted from the
  simulator's record and as seen in the driver's status reports;
- how long the driver takes, with its default settings, to notice a lost ``ok`` (goal <= 2 s) and a vanished port
  (goal <= 1 s).
"""

from __future__ import annotations

import time

import numpy as np

from drivers.grbl import GrblConnection, Job, JobRunner


def _segments(n: int, step: float = 0.1, centre: float = 200.0, compact: bool = False) -> list[str]:
    # a slow spiral of short segments inside the laser's work area
    theta = np.cumsum(np.full(n, step / 40.0))
    radius = 40.0 + 0.002 * np.arange(n)
    x, y = centre + radius * np.cos(theta), centre + radius * np.sin(theta)
    if compact:  # modal G1 left out, 0.1 mm grid: "X12.3Y45.6" (11 bytes with the newline)
        return [f"X{a:.1f}Y{b:.1f}" for a, b in zip(x, y)]
    return [f"G1X{a:.2f}Y{b:.2f}" for a, b in zip(x, y)]


def lines_per_second(latency: float, sync_all: bool, n: int, compact: bool) -> float:
    # motion 10000x faster than real: the protocol, not the motion, is measured
    url = f"sim://grbl?profile=laser&time_scale=0.0001&latency={latency}"
    with GrblConnection(url) as conn:
        lines = ["G90 G1 F6000"] + _segments(n, centre=50.0 if compact else 200.0, compact=compact)
        conn.stream(lines[:1])
        start = time.perf_counter()
        conn.stream(lines[1:], sync_all=sync_all)
        return n / (time.perf_counter() - start)


def planner_fill(latency: float, n: int = 3000) -> tuple[float, float, float]:
    url = f"sim://grbl?profile=laser&latency={latency}"
    seen: list[int] = []
    with GrblConnection(url, poll_interval=0.2) as conn:

        def watch(event, data) -> None:
            if event == "status" and data.state == "Run" and data.planner_free is not None:
                seen.append(conn.planner_size - data.planner_free)

        conn.add_listener(watch)
        lines = ["G21 G90 G0 X240 Y200", "F6000"] + _segments(n)
        start = time.perf_counter()
        result = JobRunner(conn, Job("segments", lines)).run()
        elapsed = time.perf_counter() - start
        assert result.ok, result.message
        record = conn.port.machine.snapshot()
    return record.mean_planner_fill(), float(np.mean(seen)) if seen else float("nan"), elapsed


def lost_ok_detection() -> float:
    lines = ["G21 G90 F3000"] + [f"G1 X{10 + i} Y10" for i in range(5)] + ["G28.1"]
    with GrblConnection("sim://grbl?profile=laser&time_scale=0.01&drop_reply_at=8") as conn:
        conn.stream(lines[:-1] + ["G4 P0"])  # the machine is idle from here on
        idle_at = time.monotonic()
        try:
            conn.stream(lines[-1:])
        except Exception:  # noqa: BLE001 - the lost ok is the point
            pass
        return time.monotonic() - idle_at


def vanished_port_detection(silent: bool = False) -> float:
    with GrblConnection("sim://grbl?profile=plotter") as conn:
        unplugged = time.monotonic()
        if silent:
            conn.port.machine.mute()  # no error from the port: only the silence tells
        else:
            conn.port.machine.unplug()
        conn.wait_for(lambda: conn.position_lost, 5.0)
        return time.monotonic() - unplugged


def main() -> None:
    print("streaming through the simulated GRBL (115200 baud wire time, motion not limiting):")
    for compact, label in ((True, "'X12.3Y45.6' (11 B)"), (False, "'G1X212.35Y200.12' (17 B)")):
        for latency in (0.002, 0.008):
            counting = lines_per_second(latency, sync_all=False, n=2000, compact=compact)
            send_response = lines_per_second(latency, sync_all=True, n=300, compact=compact)
            print(
                f"  {label:26s} latency {latency * 1000:.0f} ms each way: character counting {counting:5.0f} "
                f"lines/s, send-response {send_response:4.0f} lines/s, ratio {counting / send_response:4.1f}x"
                + ("  (goal >= 5x)" if latency == 0.002 else "")
            )
    for latency in (0.0, 0.002):
        sim_fill, seen_fill, elapsed = planner_fill(latency)
        print(
            f"  planner fill, 3000 x 0.1 mm at F6000, latency {latency * 1000:.0f} ms: {sim_fill:5.2f} of 15 blocks "
            f"(time-weighted, simulator), {seen_fill:5.2f} in the driver's 5 Hz status reports; job {elapsed:.1f} s "
            "(goal >= 14)"
        )
    print(f"  lost ok noticed after {lost_ok_detection():.2f} s of idle (default watchdog; goal <= 2 s)")
    print(f"  vanished port noticed after {vanished_port_detection() * 1000:.0f} ms when reads fail, "
          f"{vanished_port_detection(silent=True) * 1000:.0f} ms when it just falls silent (goal <= 1 s)")
