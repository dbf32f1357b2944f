"""How close the station's GRBL streamer comes to the serial wire, in check mode (``$C``: GRBL parses every line and
moves nothing, so the protocol alone is measured).

A job of short lines (a raster-like spiral, ``X12.3Y45.6``: about 11.4 bytes with the newline) is streamed by
character counting, and the figures are lines per second against

- the wire's limit: ``baud / 10`` bytes per second over the mean line length (8 data bits, a start and a stop bit);
- a bare character-counting streamer: one loop on the raw port, no threads, no checks, no progress (the most a
  streamer written in Python gets from this port on this host);

for the station's streamer (``GrblConnection.stream``) and for a dry run of the job as ``station send --dry-run``
runs it (``JobRunner`` with its progress callbacks drawn as plain lines; the pre-flight, which reads the job before
any byte is sent, is timed apart). The CPU each line costs the station's threads (the streamer and the port reader)
is printed too: on a busy host (a simulator or a browser beside it) that, not the wire, is what slows it.

Ports: the simulated GRBL at 115200 baud (``sim://grbl``, wire time on; latency 0 and 1 ms each way, a USB serial
adapter's order), and a real controller when ``CHAOS_STATION_GRBL_PORT`` names its port URL (e.g. the real firmware
built for the host behind ``socat``). Prints figures only; the goal is >= 90 % of the wire.
"""

from __future__ import annotations

import io
import os
import threading
import time

import numpy as np
import serial

from drivers.grbl import GrblConnection, Job, JobRunner
from drivers.grbl.connection import open_port

BAUD = 115200
LINES = 3000
GOAL = 0.90
SEED = 0
ROUNDS = 3


def job_lines(n: int = LINES, seed: int = SEED) -> list[str]:
    """A spiral of short modal moves around (75, 75), 0.1 mm grid: ``X12.3Y45.6``, some wider (``X112.3``)."""
    rng = np.random.default_rng(seed)
    theta = np.cumsum(rng.uniform(0.004, 0.012, n))
    radius = 10.0 + 60.0 * np.arange(n) / n
    x, y = 75.0 + radius * np.cos(theta), 75.0 + radius * np.sin(theta)
    return [f"X{a:.1f}Y{b:.1f}" for a, b in zip(x, y)]


def mean_length(lines: list[str]) -> float:
    """Bytes per line on the wire (with the newline)."""
    return float(np.mean([len(line) + 1 for line in lines]))


def wire_limit(lines: list[str], baud: int = BAUD) -> float:
    """Lines per second the wire carries: ``baud / 10`` bytes per second over the mean line length."""
    return baud / 10.0 / mean_length(lines)


def _thread_cpu(thread: threading.Thread) -> float:
    """CPU seconds a thread of this process has used (Linux: /proc; 0 elsewhere)."""
    try:
        with open(f"/proc/self/task/{thread.native_id}/stat") as stat:
            fields = stat.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return 0.0


# ------------------------------------------------------------------ a bare streamer


def _read_until(port, markers: tuple[bytes, ...], timeout: float) -> bytes:
    data = b""
    deadline = time.monotonic() + timeout
    while not any(marker in data for marker in markers) and time.monotonic() < deadline:
        data += port.read(max(1, port.in_waiting))
    return data


def bare_streamer(url: str, lines: list[str], baud: int = BAUD, rx_size: int = 128) -> float:
    """Lines per second of the simplest character-counting streamer, in check mode (``$C``)."""
    port = open_port(url, baud)
    try:
        port.write(b"\x18")  # a known state, whatever ran before: the banner follows
        _read_until(port, (b"Grbl",), 3.0)
        _read_until(port, (), 0.5)  # and whatever else comes (a second banner, a message)
        for command in (b"$C\n", b"G1F1000\n"):
            port.write(command)
            reply = _read_until(port, (b"ok", b"error"), 2.0)
            if b"ok" not in reply:
                raise RuntimeError(f"{url}: {command!r} answered {reply!r}")
        data = [(line + "\n").encode("ascii") for line in lines]
        in_flight: list[int] = []
        used = sent = answered = errors = 0
        buffer = b""
        start = time.perf_counter()
        while answered < len(data):
            while sent < len(data) and used + len(data[sent]) <= rx_size - 1:
                port.write(data[sent])
                in_flight.append(len(data[sent]))
                used += len(data[sent])
                sent += 1
            buffer += port.read(max(1, port.in_waiting))
            while b"\n" in buffer:
                reply, buffer = buffer.split(b"\n", 1)
                if reply.startswith((b"ok", b"error")):
                    errors += reply.startswith(b"error")
                    used -= in_flight.pop(0)
                    answered += 1
        elapsed = time.perf_counter() - start
        port.write(b"$C\n")  # leave check mode (GRBL resets)
        _read_until(port, (b"Grbl",), 3.0)
        if errors:
            raise RuntimeError(f"{url}: {errors} line(s) answered with an error in check mode")
        return len(lines) / elapsed
    finally:
        port.close()


# ------------------------------------------------------------------ the station's streamer


def station_stream(url: str, lines: list[str], baud: int = BAUD) -> tuple[float, float, float]:
    """``GrblConnection.stream`` in check mode: lines per second, and CPU microseconds per line of the streaming
    thread and of the port reader."""
    with GrblConnection(url, baud) as conn:
        conn.command("$C")
        conn.stream(["G1F1000"])
        reader = next(thread for thread in conn._threads if thread.name == "grbl-reader")
        main0, reader0 = time.thread_time(), _thread_cpu(reader)
        start = time.perf_counter()
        results = conn.stream(lines)
        elapsed = time.perf_counter() - start
        main_cpu, reader_cpu = time.thread_time() - main0, _thread_cpu(reader) - reader0
        conn.expect_reset()
        conn.command("$C")
        assert all(result.status == "ok" for result in results)
    return len(lines) / elapsed, main_cpu / len(lines) * 1e6, reader_cpu / len(lines) * 1e6


def station_dry_run(url: str, lines: list[str], baud: int = BAUD) -> tuple[float, float]:
    """A dry run of the job as ``station send --dry-run`` runs it (``JobRunner``, progress drawn as plain lines):
    lines per second from the first byte to the end of check mode, and the pre-flight's seconds."""
    from station.commands.machines_io import SendProgress

    with GrblConnection(url, baud) as conn:
        runner = JobRunner(conn, Job("bench", ["G21 G90 G1 F1000", *lines]), dry_run=True,
                           on_progress=SendProgress(io.StringIO(), tty=False))
        start = time.perf_counter()
        runner.preflight()
        preflight = time.perf_counter() - start
        runner.preflight = lambda: {}  # measured above: run() would read the job again
        start = time.perf_counter()
        result = runner.run()
        elapsed = time.perf_counter() - start
        assert result.ok, result.message
    return len(lines) / elapsed, preflight


def measure(label: str, url: str, lines: list[str], baud: int = BAUD, rounds: int = ROUNDS) -> None:
    """Print the figures of one port: each the median of ``rounds`` runs taken in turn (bare, stream, dry run), so
    that a busy host slows all three alike."""
    wire = wire_limit(lines, baud)
    runs: dict[str, list[float]] = {"bare": [], "stream": [], "main": [], "reader": [], "dry": [], "preflight": []}
    for _ in range(rounds):
        runs["bare"].append(bare_streamer(url, lines, baud))
        stream, main_us, reader_us = station_stream(url, lines, baud)
        runs["stream"].append(stream)
        runs["main"].append(main_us)
        runs["reader"].append(reader_us)
        dry, preflight = station_dry_run(url, lines, baud)
        runs["dry"].append(dry)
        runs["preflight"].append(preflight)
    median = {name: float(np.median(values)) for name, values in runs.items()}

    def spread(name: str) -> str:
        return f" [{min(runs[name]):.0f}-{max(runs[name]):.0f}]" if rounds > 1 else ""

    bare, stream, dry = median["bare"], median["stream"], median["dry"]
    print(f"  {label}" + (f", median of {rounds} runs [range]" if rounds > 1 else ""))
    print(f"    wire {wire:6.0f} lines/s | bare streamer {bare:6.0f}{spread('bare')} ({bare / wire:4.0%}) | "
          f"station stream {stream:6.0f}{spread('stream')} ({stream / wire:4.0%} of the wire, {stream / bare:4.0%} "
          f"of bare) | dry run {dry:6.0f}{spread('dry')} ({dry / wire:4.0%}; pre-flight "
          f"{median['preflight'] * 1e3:.0f} ms before it)  goal >= {GOAL:.0%} of the wire")
    print(f"    CPU per line: streamer {median['main']:5.1f} us, port reader {median['reader']:5.1f} us", flush=True)


def main() -> None:
    lines = job_lines()
    print(f"check mode, {len(lines)} lines of {mean_length(lines):.1f} bytes on average, {BAUD} baud:", flush=True)
    for latency in (0.0, 0.001):
        url = f"sim://grbl?profile=laser&latency={latency}"
        measure(f"simulated GRBL, latency {latency * 1e3:.0f} ms each way ({url})", url, lines, rounds=1)
    real = os.environ.get("CHAOS_STATION_GRBL_PORT", "")
    if real:
        try:
            measure(f"real controller at {real}", real, lines)
        except (OSError, serial.SerialException, RuntimeError, AssertionError) as error:
            print(f"  real controller at {real}: not measured ({error})")
    else:
        print("  (set CHAOS_STATION_GRBL_PORT to a port URL to measure a real controller too)")


if __name__ == "__main__":
    main()
