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


#: The packages whose modules must not import each other in a circle.
PACKAGES = ("common", "design", "drivers", "calibration", "projector", "vision", "cam", "station")


def module_files(root: Path, packages=PACKAGES) -> dict[str, Path]:
    """Every module of ``packages`` under ``root`` by its dotted name (a package by its ``__init__.py``)."""
    files = {}
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            files[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return files


def import_graph(root: Path, files: dict[str, Path]) -> dict[str, set[str]]:
    """Which of ``files``' modules each one imports, at any depth (inside a function or an ``if TYPE_CHECKING:`` as
    well: a cycle that lives only because an import waits inside a function is still a cycle). ``from pkg import
    name`` points at the module ``pkg.name`` when there is one, else at ``pkg``."""

    def owner(name: str) -> str | None:  # the module a dotted name lives in: its longest prefix that is a module
        parts = name.split(".")
        while parts and ".".join(parts) not in files:
            parts.pop()
        return ".".join(parts) or None

    graph: dict[str, set[str]] = {}
    for name, path in files.items():
        package = list(path.relative_to(root).with_suffix("").parts[:-1])
        targets: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
            if isinstance(node, ast.Import):
                targets.update(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = package[:len(package) - node.level + 1] if node.level else []
                module = ".".join([*base, *([node.module] if node.module else [])])
                targets.update(f"{module}.{a.name}" if f"{module}.{a.name}" in files else module for a in node.names)
        graph[name] = {found for found in map(owner, targets) if found is not None and found != name}
    return graph


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The modules that import each other in a circle: the graph's strongly connected components of more than one
    module (Tarjan's algorithm, without recursion), each sorted, in the order found."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles = []
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, successors = work[-1]
            advanced = False
            for successor in successors:
                if successor not in index:
                    index[successor] = low[successor] = len(index)
                    stack.append(successor)
                    on_stack.add(successor)
                    work.append((successor, iter(sorted(graph.get(successor, ())))))
                    advanced = True
                    break
                if successor in on_stack:
                    low[node] = min(low[node], index[successor])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    cycles.append(sorted(component))
    return cycles


def test_no_import_cycles():
    # Modules that import each other only work in one import order: the graph the imports draw must have no circle.
    graph = import_graph(ROOT, module_files(ROOT))
    cycles = import_cycles(graph)
    assert not cycles, "\n".join(
        " <-> ".join(cycle) + ": " + "; ".join(f"{a} imports {sorted(graph[a] & set(cycle))}" for a in cycle)
        for cycle in cycles)


def test_cycle_finder_sees_a_cycle_behind_a_function_and_type_checking(tmp_path):
    package = tmp_path / "pkg"
    package.mkdir()
    (package / "__init__.py").write_text("from pkg.a import f\n")
    (package / "a.py").write_text("def f():\n    from pkg import b\n    return b\n")
    (package / "b.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg.c import C\n")
    (package / "c.py").write_text("from . import a\nclass C: ...\n")
    (package / "d.py").write_text("import pkg.c\nfrom pkg import a\n")
    graph = import_graph(tmp_path, module_files(tmp_path, ("pkg",)))
    assert graph["pkg.a"] == {"pkg.b"} and graph["pkg.d"] == {"pkg.a", "pkg.c"}
    assert import_cycles(graph) == [["pkg.a", "pkg.b", "pkg.c"]]
    (package / "c.py").write_text("class C: ...\n")
    assert import_cycles(import_graph(tmp_path, module_files(tmp_path, ("pkg",)))) == []


# -- the faces and the services' boundary ------------------------------------------------------------------------
#: The packages below the station: a face (a command, the CLI's helpers, a screen or a widget) reaches them only
#: through station.services, so that one workflow is written once, for both faces.
BELOW_THE_STATION = {"common", "design", "drivers", "calibration", "projector", "vision", "cam"}

def face_files() -> list[Path]:
    """The command line (its commands and helpers), the terminal UI and the browser's server."""
    station = ROOT / "station"
    return sorted([*station.joinpath("commands").glob("*.py"), *station.glob("cli*.py"), *station.glob("serve*.py"),
                   *station.joinpath("tui").rglob("*.py")])


def test_faces_import_only_the_station():
    offenders = [f"{path.relative_to(ROOT)} imports {sorted(below)}: reach it through station.services"
                 for path in face_files() if (below := imported_top_levels(path) & BELOW_THE_STATION)]
    assert not offenders, "\n".join(offenders)


#: What a service may raise besides the station's errors: a stop (the one Cancelled, or KeyboardInterrupt at a
#: safe point of a run the user interrupted), never a package's error or a builtin one.
STOPS = {"Cancelled", "KeyboardInterrupt"}
STATION_ERROR_BASES = {"StationError", "ServiceError", "UsageError", "ConfigError"}


def station_error_classes() -> set[str]:
    """The names of the classes in ``station`` that are station errors (their bases, followed by name)."""
    bases: dict[str, set[str]] = {}
    for path in (ROOT / "station").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ClassDef):
                bases.setdefault(node.name, set()).update(ast.unparse(b).split(".")[-1] for b in node.bases)
    errors = set(STATION_ERROR_BASES)
    while True:
        more = {name for name, parents in bases.items() if parents & errors} - errors
        if not more:
            return errors
        errors |= more


def raised_classes(path: Path) -> list[tuple[int, str]]:
    """The classes ``path`` raises by name (``raise Name(...)``, ``raise Name``, ``raise module.Name(...)``), with
    their lines; a raise of a call to a lowercase name (a factory such as ``fail(...)``) or of a variable is not
    seen."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Raise) and node.exc is not None:
            target = node.exc.func if isinstance(node.exc, ast.Call) else node.exc
            name = target.id if isinstance(target, ast.Name) else target.attr if isinstance(target, ast.Attribute) \
                else ""
            if name[:1].isupper():
                found.append((node.lineno, name))
    return sorted(found)


def test_services_raise_only_station_errors():
    # A face catches station.errors.USER_ERRORS and nothing else: a service that raised a package's or a builtin
    # error would reach the user as a traceback. (What a service calls is translated at its entry, see below.)
    allowed = station_error_classes() | STOPS
    offenders = [f"{path.relative_to(ROOT)}:{line} raises {name}"
                 for path in sorted((ROOT / "station" / "services").glob("*.py"))
                 for line, name in raised_classes(path) if name not in allowed]
    assert not offenders, "\n".join(offenders)


def test_raise_checker_sees_package_and_builtin_errors(tmp_path):
    sample = tmp_path / "x.py"
    sample.write_text("def f(x):\n    if x:\n        raise FileFormatError('a')\n    raise errors.DriverError\n"
                      "def g():\n    raise fail('b')\n    raise ValueError\n")
    assert raised_classes(sample) == [(3, "FileFormatError"), (4, "DriverError"), (7, "ValueError")]
    assert {"ServiceError", "DatabaseError", "JobStateError"} <= station_error_classes()


ENTRY_DUNDERS = ("__init__", "__post_init__", "__call__", "__iter__", "__next__", "__enter__", "__exit__")


def entry_points_without_translation(path: Path) -> list[str]:
    """The public functions, and the public classes with public methods, of a service module that are not
    decorated with ``station_errors``."""
    missing = []
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if not isinstance(node, (ast.FunctionDef, ast.ClassDef)) or node.name.startswith("_"):
            continue
        bases = {ast.unparse(b).split(".")[-1] for b in node.bases} if isinstance(node, ast.ClassDef) else set()
        if isinstance(node, ast.ClassDef) and (
                bases & {"Enum", "StrEnum", "IntEnum"} or any(b.endswith(("Error", "Exception")) for b in bases)
                or not any(isinstance(m, ast.FunctionDef) and (not m.name.startswith("_") or m.name in ENTRY_DUNDERS)
                           for m in node.body)):
            continue  # plain data, a choice among names or an error: nothing of it runs the work
        decorators = {ast.unparse(d.func if isinstance(d, ast.Call) else d).split(".")[-1] for d in node.decorator_list}
        if "station_errors" not in decorators:
            missing.append(node.name)
    return missing


def test_service_entry_points_translate_the_packages_errors():
    # The packages' errors (design, drivers, calibration, projector, vision, data files) become station errors,
    # message kept, where a service is entered: every public function and class wears @station_errors.
    offenders = [f"{path.relative_to(ROOT)}: {', '.join(names)}"
                 for path in sorted((ROOT / "station" / "services").glob("*.py"))
                 if (names := entry_points_without_translation(path))]
    assert not offenders, "not decorated with @station_errors:\n" + "\n".join(offenders)


def test_entry_point_checker_sees_an_undecorated_function(tmp_path):
    sample = tmp_path / "x.py"
    sample.write_text("@station_errors\ndef a(): ...\ndef b(): ...\ndef _c(): ...\n"
                      "@dataclass\nclass D:\n    x: int\n@dataclass\nclass E:\n    def run(self): ...\n"
                      "class F(ServiceError):\n    def __init__(self): ...\n")
    assert entry_points_without_translation(sample) == ["b", "E"]
