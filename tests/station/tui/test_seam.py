"""The TUI is a face: it reaches the station only through its services, and its long work reports back one way.

Checked on the source (imports and calls at any depth), so that a lazy import or a worker written the old way inside
a method is seen too.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
TUI = ROOT / "station" / "tui"

#: What a file of the TUI may import from the station: the services, the TUI itself and the one error family.
ALLOWED_STATION = ("station.services", "station.tui", "station.errors")

#: Files still being moved onto the services, each with the station modules it still imports. The list only shrinks.
TUI_IN_MOVE: dict[str, set[str]] = {}


def station_imports(path: Path) -> set[str]:
    """The modules of the station (``station.*``, and the packages below it) that ``path`` imports, at any depth."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    below = ("common", "design", "drivers", "calibration", "projector", "vision", "cam")
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        else:
            continue
        found.update(name for name in names if name == "station" or name.startswith("station.")
                     or name.split(".")[0] in below)
    return found


def outside_the_seam(path: Path) -> set[str]:
    return {name for name in station_imports(path)
            if not any(name == allowed or name.startswith(allowed + ".") for allowed in ALLOWED_STATION)}


def test_the_tui_reaches_the_station_only_through_its_services():
    offenders, cleaned = [], []
    for path in sorted(TUI.rglob("*.py")):
        name = path.relative_to(ROOT).as_posix()
        outside = outside_the_seam(path)
        allowed = TUI_IN_MOVE.get(name, set())
        if outside - allowed:
            offenders.append(f"{name} imports {sorted(outside - allowed)}: reach it through station.services")
        if allowed - outside:
            cleaned.append(f"{name} no longer imports {sorted(allowed - outside)}: take it off TUI_IN_MOVE")
    assert not offenders and not cleaned, "\n".join(offenders + cleaned)


#: Ways a worker thread could talk to the UI other than run_work's messages.
OTHER_WAYS = {"call_from_thread", "get_current_worker", "SimpleQueue", "Queue", "WorkerState"}


def other_ways_back(path: Path) -> list[str]:
    """Where ``path`` runs a thread worker or reaches the UI from a thread other than through run_work."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.Attribute, ast.Name)):
            name = node.attr if isinstance(node, ast.Attribute) else node.id
            if name in OTHER_WAYS:
                found.append(f"{node.lineno}: {name}")
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            if node.name == "on_worker_state_changed":
                found.append(f"{node.lineno}: {node.name}")
            for decorator in node.decorator_list:
                target = decorator.func if isinstance(decorator, ast.Call) else decorator
                if isinstance(target, ast.Name) and target.id == "work":
                    found.append(f"{decorator.lineno}: @work on {node.name}")
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "run_worker":
            if any(k.arg == "thread" and isinstance(k.value, ast.Constant) and k.value.value for k in node.keywords):
                found.append(f"{node.lineno}: run_worker(thread=True)")
    return found


def test_long_work_reports_back_only_through_run_work():
    # A worker thread that calls into the UI (call_from_thread), a private queue a timer drains, or a bare thread
    # worker whose end a screen must pick out of Textual's worker events are three more ways to say the same thing.
    offenders = [f"{path.relative_to(ROOT)}:{where}" for path in sorted(TUI.rglob("*.py"))
                 if path != TUI / "work.py" for where in other_ways_back(path)]
    assert not offenders, "report through station.tui.work.run_work:\n" + "\n".join(offenders)


def test_the_checks_see_the_old_ways(tmp_path):
    sample = tmp_path / "x.py"
    sample.write_text("from textual import work\nfrom station.db import open_database\n"
                      "class S:\n    @work(thread=True)\n    def w(self):\n"
                      "        from design.machines import get_machine\n"
                      "        self.app.call_from_thread(print)\n        self.run_worker(f, thread=True)\n"
                      "    def ok(self):\n        from station.services.trials import logged_trials\n"
                      "    def on_worker_state_changed(self, event):\n        pass\n")
    assert outside_the_seam(sample) == {"station.db", "design.machines"}
    assert sorted(where.split(": ")[1] for where in other_ways_back(sample)) == [
        "@work on w", "call_from_thread", "on_worker_state_changed", "run_worker(thread=True)"]
