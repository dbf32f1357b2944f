"""The streamer's writes: as many lines as fit in GRBL's RX buffer go in one write (fewer system calls and wake-ups
at both ends of the wire), in order, never more than the buffer holds, and a line that must go alone still does.
(How close it comes to the wire is measured by ``python -m bench grbl_stream``.)"""

from __future__ import annotations

from ..conftest import sim_url


def _count_writes(conn) -> list[bytes]:
    writes: list[bytes] = []
    port_write = conn.port.write

    def write(data):
        if data != b"?":
            writes.append(bytes(data))
        return port_write(data)

    conn.port.write = write
    return writes


def test_lines_that_fit_go_in_one_write_in_order_and_never_overfill(make_connection):
    # replies come back in bursts (5 ms each way, no wire time): each burst frees room for several lines
    conn = make_connection(sim_url("laser", latency=0.005, wire=0, time_scale=0.0001))
    conn.command("$C")  # check mode: the protocol alone
    writes = _count_writes(conn)
    moves = [f"X{10 + (i % 50) * 0.5:.1f}Y{10 + (i // 50) * 0.5:.1f}" for i in range(400)]
    lines = ["G21 G90 G1 F1000", *moves[:200], "G10 L20 P1 X0 Y0", *moves[200:]]
    results = conn.stream(lines)
    assert all(result.status == "ok" for result in results)
    sent = [line.replace(" ", "") for line in lines]
    assert b"".join(writes).decode().split("\n")[:-1] == sent
    # how many lines share a write depends on how the replies' bursts fall on a loaded machine; one line per write
    # (402 writes) is what this refuses
    assert len(writes) < len(lines) // 2
    assert b"G10L20P1X0Y0\n" in writes  # alone, all the same: GRBL writes its EEPROM meanwhile
    assert max(len(data) for data in writes) <= conn.rx_size - 1 and conn.max_pending_bytes <= conn.rx_size - 1
    record = conn.port.machine.snapshot()
    assert record.overflow_bytes == 0
    assert [line for line in record.received if not line.startswith("$")] == sent
