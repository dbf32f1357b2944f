"""The README's quick tour, run as written: every command of its shell block, in order, in a fresh folder.

The folder holds a copy of ``examples/`` (the tour's relative paths), so the tour's outputs never land in the
repository; ``station`` is this checkout's console script, and ``CHAOS_STATION_HOME`` is the test's own (conftest),
so nothing is cached from an earlier run, as on a fresh clone. ``make run`` (the TUI) is not in the block and would
be skipped.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def tour_commands(readme: str) -> list[str]:
    """The command lines of the first ``sh`` block under "A quick tour", comments and blank lines left out."""
    section = readme.split("## A quick tour", 1)[1].split("\n## ", 1)[0]
    block = re.search(r"```sh\n(.*?)```", section, re.S)
    assert block, "the quick tour has no ```sh block"
    commands = []
    for line in block.group(1).splitlines():
        line = line.strip()
        if line and not line.startswith("#") and not line.startswith("make run"):
            commands.append(line)
    return commands


def test_the_tour_block_is_found():
    commands = tour_commands((REPO / "README.md").read_text(encoding="utf-8"))
    assert len(commands) >= 8 and all(c.startswith("station ") for c in commands)


def test_the_quick_tour_runs_as_written(tmp_path):
    commands = tour_commands((REPO / "README.md").read_text(encoding="utf-8"))
    shutil.copytree(REPO / "examples", tmp_path / "examples")
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    assert shutil.which("station", path=env["PATH"]), "the station console script is not installed"
    for command in commands:
        # A shell, as a reader types it: quotes, redirections and trailing comments behave as in a terminal.
        done = subprocess.run(["bash", "-c", command], cwd=tmp_path, env=env, capture_output=True, text=True,
                              timeout=600)
        tail = "\n".join(done.stderr.strip().splitlines()[-5:])
        assert done.returncode == 0, f"README tour: `{command}` exited {done.returncode}:\n{tail}"
        assert "Traceback" not in done.stderr, f"README tour: `{command}` printed a traceback:\n{tail}"
    # What the tour says it makes, made where the reader ran it (and nothing written into the repository).
    for name in ("hits.json", "star.png", "explore.png", "star.gcode", "parts/parts.svg", "layout.json", "rho.png"):
        assert (tmp_path / name).exists(), f"the tour should have written {name}"
