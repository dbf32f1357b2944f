"""The architecture's one-way imports, checked on the source (not at run time, so lazy imports count too)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

FORBIDDEN = {
    "common": {"design", "drivers", "calibration", "projector", "station", "textual", "rich"},
    "design": {"station", "drivers", "calibration", "projector", "textual"},
    "drivers": {"design", "station", "textual"},
    "calibration": {"station", "textual"},
    "projector": {"station", "textual"},
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
