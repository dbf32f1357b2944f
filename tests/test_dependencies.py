"""Every third-party package the code imports is declared in pyproject.toml (not only brought by another one: a
dependency of a dependency can be dropped by its next release), checked on the source, deferred imports too."""

from __future__ import annotations

import re
import sys
from importlib.metadata import packages_distributions
from pathlib import Path

import pytest

from .test_layering import imported_top_levels

if sys.version_info >= (3, 11):
    import tomllib
else:
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]

OWN = {"common", "design", "drivers", "calibration", "projector", "vision", "cam", "station", "bench", "tests",
       "conftest"}

#: The packages and what they may use: the station's code its dependencies and the optional extras it defers
#: (PostgreSQL, the real projector); the tests and benchmarks the dev extra too.
AREAS = {
    "common design drivers calibration projector vision cam station": ("postgres", "projector"),
    "tests bench": ("postgres", "projector", "dev"),
}


def canonical(name: str) -> str:
    """A distribution's name as pip compares them (PEP 503): ``Hershey_Fonts`` and ``hershey-fonts`` are one."""
    return re.sub(r"[-_.]+", "-", name).lower()


def declared(extras: tuple[str, ...]) -> set[str]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    requirements = [*project["dependencies"], *(r for extra in extras for r in project["optional-dependencies"][extra])]
    return {canonical(re.match(r"[A-Za-z0-9_.-]+", requirement).group()) for requirement in requirements}


def third_party_imports(folders: list[str], root: Path = ROOT) -> dict[str, list[str]]:
    """Top-level module -> the files importing it, for the modules neither the standard library's nor ours."""
    found: dict[str, list[str]] = {}
    for folder in folders:
        for path in sorted((root / folder).rglob("*.py")):
            for name in imported_top_levels(path) - OWN - set(sys.stdlib_module_names) - {"__future__"}:
                found.setdefault(name, []).append(str(path.relative_to(root)))
    return found


@pytest.mark.parametrize("folders", sorted(AREAS))
def test_every_imported_package_is_declared(folders):
    wanted = declared(AREAS[folders])
    distributions = packages_distributions()
    undeclared = []
    for module, files in sorted(third_party_imports(folders.split()).items()):
        # a module not installed here (tomli on Python 3.11+) is declared under its own name
        names = {canonical(name) for name in distributions.get(module, [module])}
        if not names & wanted:
            undeclared.append(f"{module} ({' or '.join(sorted(names))}), imported by {files[0]}"
                              + (f" and {len(files) - 1} more" if len(files) > 1 else ""))
    assert not undeclared, "imported but not declared in pyproject.toml:\n" + "\n".join(undeclared)


def test_the_check_sees_an_undeclared_import(tmp_path):
    # the test above must be able to fail: a deferred import of a package only another one brings is caught
    (tmp_path / "station").mkdir()
    (tmp_path / "station" / "x.py").write_text("def f():\n    import markdown_it\n    import numpy\n")
    assert set(third_party_imports(["station"], tmp_path)) == {"markdown_it", "numpy"}
    assert "markdown-it-py" not in declared(()) and "numpy" in declared(())
