"""The architecture's one-way imports, checked on the source (not at run time, so lazy imports count too)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

FORBIDDEN = {
    "common": {"design", "drivers", "calibration", "projector", "vision", "cam", "station", "textual", "rich"},
    "design": {"station", "drivers", "calibration", "projector", "vision", "cam", "textual"},
    # The simulated camera draws its tags itself: a renderer sharing the station's tag code could not test it.
    "drivers": {"design", "station", "vision", "cam", "textual"},
    "calibration": {"station", "textual"},
    "projector": {"station", "textual"},
    # Tags and their detection: one definition under guides (projector) and measurement (calibration) alike.
    "vision": {"design", "drivers", "calibration", "projector", "cam", "station", "textual"},
    # Tool paths are written in the machines' G-code (drivers) from plain polylines the station hands over.
    "cam": {"design", "calibration", "projector", "vision", "station", "textual"},
}


def imported_top_levels(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_package_imports_only_downwards(package):
    offenders = []
    for path in sorted((ROOT / package).rglob("*.py")):
        bad = imported_top_levels(path) & FORBIDDEN[package]
        if bad:
            offenders.append(f"{path.relative_to(ROOT)} imports {sorted(bad)}")
    assert not offenders, "\n".join(offenders)


def test_checker_sees_forbidden_imports(tmp_path):
    # The test above must be able to fail: a file with a lazy, nested forbidden import is caught.
    sample = tmp_path / "x.py"
    sample.write_text("def f():\n    from station.cli import main\n    import textual.app\n")
    assert imported_top_levels(sample) == {"station", "textual"}


def imported_modules(path: Path) -> set[str]:
    """Every module ``path`` imports, dotted in full, at any depth (``from station import commands`` counts as
    ``station.commands``; relative imports are resolved against the file's package)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = list(path.relative_to(ROOT).with_suffix("").parts[:-1]) if path.is_relative_to(ROOT) else []
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = package[:len(package) - node.level + 1] if node.level else []
            module = ".".join([*base, *([node.module] if node.module else [])])
            names.add(module)
            names.update(f"{module}.{alias.name}" for alias in node.names)
    return names


def imports_of(path: Path, forbidden: str) -> list[str]:
    """The modules ``path`` imports that are ``forbidden`` or inside it."""
    return sorted(m for m in imported_modules(path) if m == forbidden or m.startswith(forbidden + "."))


def test_screens_never_import_the_commands():
    # The TUI and the CLI stand side by side on station.services; a screen that imports a command gets the CLI's
    # errors (naming --flags) and its printing.
    offenders = [f"{path.relative_to(ROOT)} imports {imports_of(path, 'station.commands')}"
                 for path in sorted((ROOT / "station" / "tui").rglob("*.py")) if imports_of(path, "station.commands")]
    assert not offenders, "\n".join(offenders)


def test_checker_sees_a_screen_importing_a_command(tmp_path):
    sample = tmp_path / "x.py"
    sample.write_text("from station.services import robust\n"
                      "def f():\n    from station.commands.robust import psp_settings\n"
                      "def g():\n    from station import commands\n    import station.commands.fabricate\n")
    assert imports_of(sample, "station.commands") == [
        "station.commands", "station.commands.fabricate", "station.commands.robust",
        "station.commands.robust.psp_settings"]
