"""The documentation site: it builds strictly and offline, every page is in its navigation, its tour is the README's,
the commands it marks runnable run as written, and the guide keeps its measurements on the results pages.

A shell block preceded by the line ``<!-- run -->`` in a page is run the way the README tour is
(tests/test_readme_tour.py): each command line in ``bash``, in order, in a fresh folder holding a copy of
``examples/``, with the station's data folder the test's own. The blocks of one page share the folder, so a later
block may use what an earlier one wrote.
"""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from .test_readme_tour import tour_commands

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
RUN_MARK = "<!-- run -->"


def hooks():
    spec = importlib.util.spec_from_file_location("docs_hooks", DOCS / "hooks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def runnable_blocks(text: str) -> list[list[str]]:
    """The command lines of each ``sh`` block right after a ``<!-- run -->`` line, comments and blanks left out."""
    blocks = []
    for match in re.finditer(re.escape(RUN_MARK) + r"\n```sh\n(.*?)```", text, re.S):
        lines = [line.strip() for line in match.group(1).splitlines()]
        blocks.append([line for line in lines if line and not line.startswith("#")])
    return blocks


def pages_with_runnable_blocks() -> list[str]:
    return sorted(p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*.md")
                  if runnable_blocks(p.read_text(encoding="utf-8")))


def test_the_site_builds_strictly(tmp_path):
    """`mkdocs build --strict`: a broken link or anchor, a missing page or one left out of the navigation fails."""
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                          cwd=REPO, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    for page in ("index.html", "reference/cli/index.html", "reference/tui/index.html", "formats/check/index.html",
                 "results/index.html", "changelog/index.html", "formats/schemas/check.schema.json"):
        assert (tmp_path / "site" / page).is_file(), page


def test_every_page_is_in_the_navigation():
    def flatten(entries):
        for entry in entries:
            value = next(iter(entry.values())) if isinstance(entry, dict) else entry
            yield from flatten(value) if isinstance(value, list) else [value]

    nav = set(flatten(hooks().build_nav(DOCS)))
    pages = {p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*.md")}
    assert pages <= nav, f"pages missing from the navigation: {sorted(pages - nav)}"


def test_the_reference_lists_every_command_and_option():
    from station.cli import build_parser

    reference = hooks().cli_reference()
    parser = build_parser()
    for name, sub, _ in hooks()._subparsers(parser):
        assert f"## `station {name}`" in reference
        for action in sub._actions:
            for option in action.option_strings:
                if option not in ("-h", "--help"):
                    assert f"`{option}" in reference, f"station {name} {option} is not in the reference"


def test_the_tui_reference_lists_every_screens_keys():
    from station.tui.registry import discover_screens

    reference = hooks().tui_reference()
    for entry in discover_screens():
        assert f"## {entry.title}" in reference and f"| `{entry.key}` |" in reference
        for binding in getattr(entry.factory, "BINDINGS", []):
            assert f"`{binding.key.split(',')[0]}`" in reference, (entry.title, binding.key)


def test_the_sites_tour_is_the_readmes():
    readme = tour_commands((REPO / "README.md").read_text(encoding="utf-8"))
    site = tour_commands((DOCS / "index.md").read_text(encoding="utf-8"))
    assert site == readme, "docs/index.md's tour differs from the README's (the README's is the one a test runs)"


def test_the_guide_has_runnable_examples():
    pages = pages_with_runnable_blocks()
    assert len(pages) >= 8, pages
    for page in pages:
        for block in runnable_blocks((DOCS / page).read_text(encoding="utf-8")):
            assert block and all(line.startswith(("station ", "printf ")) for line in block), (page, block)


#: Pages whose examples run optimizations, loops or laser cards for 10 s or more: with the slow tests
#: (``pytest -m slow``), so the default suite keeps to its time.
SLOW_PAGES = {"guide/the-loop.md", "guide/robust-layouts.md", "guide/laser-test-cards.md"}


@pytest.mark.parametrize("page", [pytest.param(page, marks=pytest.mark.slow) if page in SLOW_PAGES else page
                                  for page in pages_with_runnable_blocks()])
def test_the_pages_examples_run_as_written(page, tmp_path):
    shutil.copytree(REPO / "examples", tmp_path / "examples")
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    for block in runnable_blocks((DOCS / page).read_text(encoding="utf-8")):
        for command in block:
            done = subprocess.run(["bash", "-c", command], cwd=tmp_path, env=env, capture_output=True, text=True,
                                  timeout=600)
            tail = "\n".join(done.stderr.strip().splitlines()[-5:])
            assert done.returncode == 0, f"{page}: `{command}` exited {done.returncode}:\n{tail}"
            assert "Traceback" not in done.stderr, f"{page}: `{command}` printed a traceback:\n{tail}"


#: A table cell holding a measured figure: a duration, a rate, a share, a ± or a speed-up.
MEASURED = re.compile(r"\d\s*(ms|s|%|x|lines/s)(?![\w/])|±|\+-")


def test_the_guide_pages_hold_no_measurement_tables():
    """The figures of a measurement campaign belong on its dated results page, not in the guide."""
    found = []
    for path in sorted((DOCS / "guide").glob("*.md")):
        in_code = False
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if line.lstrip().startswith("```"):
                in_code = not in_code
            if not in_code and line.lstrip().startswith("|") and MEASURED.search(line):
                found.append(f"{path.relative_to(REPO)}:{number}: {line.strip()[:100]}")
    assert not found, "measurement tables in the guide (move them to docs/results/):\n" + "\n".join(found)


def test_the_changelogs_top_entry_is_the_version():
    import station

    if sys.version_info >= (3, 11):
        import tomllib
    else:
        import tomli as tomllib
    top = re.search(r"^## (\S+)", (DOCS / "changelog.md").read_text(encoding="utf-8"), re.M).group(1)
    project = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]["version"]
    assert top == station.__version__ == project
    done = subprocess.run([sys.executable, "-m", "station", "--version"], capture_output=True, text=True, timeout=60)
    assert done.stdout.strip() == f"station {station.__version__}"
