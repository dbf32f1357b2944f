"""pybullet, imported and connected without its banner lines on stdout (they would corrupt ``--json`` output)."""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys


@contextlib.contextmanager
def quiet_stdout():
    """Send the C-level stdout and stderr to /dev/null for the duration (pybullet's banner lines)."""
    saved: list[tuple[int, int]] = []
    for stream, fd in ((sys.stdout, 1), (sys.stderr, 2)):
        # By number: under a TUI or a capture, sys.stdout is not fd 1, but pybullet's C code still writes there.
        try:
            if stream is not None:
                stream.flush()
        except (AttributeError, OSError, ValueError):
            pass
        try:
            saved.append((fd, os.dup(fd)))
        except OSError:  # no such descriptor: nothing to silence
            continue
    try:
        null = os.open(os.devnull, os.O_WRONLY)
    except OSError:  # pragma: no cover
        null = None
    try:
        if null is not None:
            for fd, _ in saved:
                os.dup2(null, fd)
        yield
    finally:
        _flush_c_stdio()
        for fd, copy in saved:
            os.dup2(copy, fd)
            os.close(copy)
        if null is not None:
            os.close(null)


def _flush_c_stdio() -> None:
    # pybullet prints with C stdio: flush its buffer while stdout still points at /dev/null.
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):  # pragma: no cover - no libc symbol lookup on this platform
        pass


with quiet_stdout():
    import pybullet
    from pybullet_utils.bullet_client import BulletClient


def direct_client() -> BulletClient:
    """A new pybullet client in DIRECT mode (several can coexist in one process)."""
    with quiet_stdout():
        return BulletClient(connection_mode=pybullet.DIRECT)


__all__ = ["BulletClient", "direct_client", "pybullet"]
