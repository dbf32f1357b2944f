"""MkDocs hooks of the documentation site: the navigation and the reference pages are made from the repository at
build time, so neither can drift from the code.

- The navigation lists every page under ``docs/``: the known pages in the order a maker meets them, then any other
  guide page (``docs/guide/*.md``) under "More", and the results pages (``docs/results/*.md``) newest first. A page
  added by someone else is in the navigation without editing ``mkdocs.yml``.
- ``reference/cli.md`` is made from the station's argparse parsers (``station.cli.build_parser``), every command and
  option; ``reference/tui.md`` from the screens' key bindings (``station.tui.registry.discover_screens``);
  ``reference/scenario.md``, ``reference/profile.md`` and ``reference/station-toml.md`` from the docstrings of the
  modules that read those files, with the scenario's primitives and events from its schema tables.
- A line ``<!-- schema: NAME -->`` in a page becomes the schema ``station/schemas/NAME.schema.json``, which is also
  published beside the page (``formats/schemas/NAME.schema.json``).
- ``results/index.md`` lists the measurement campaigns by date.

Nothing here reaches the network: the site builds offline from the checkout.
"""

from __future__ import annotations

import argparse
import inspect
import os
import re
import sys
from pathlib import Path

from mkdocs.structure.files import File

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # the station's packages, when mkdocs runs from another environment's path
    sys.path.insert(0, str(ROOT))

#: The guide in the order a maker meets the tasks: (section, [page, ...]). A guide page not named here is listed under
#: "More", so a new page is never unreachable.
GUIDE = [
    ("Start", ["guide/set-up.md"]),
    ("Drawing machines", ["guide/drawing-machines.md", "guide/sketch-retrieval.md", "guide/guided-exploration.md",
                          "guide/plotting.md", "guide/fabrication.md", "guide/laser-test-cards.md"]),
    ("Contraptions", ["guide/contraptions.md", "guide/robust-layouts.md"]),
    ("Assembly", ["guide/assembly-guides.md", "guide/placement-jigs.md", "guide/camera-check.md",
                  "guide/side-camera.md", "guide/calibration.md", "guide/trials.md", "guide/the-loop.md",
                  "guide/world-twin.md"]),
    ("Machines", ["guide/grbl-machines.md", "guide/laser-placement.md", "guide/job-history.md"]),
    ("Around the station", ["guide/browser.md", "guide/configuration.md"]),
]
REFERENCE = ["reference/cli.md", "reference/tui.md", "reference/scenario.md", "reference/profile.md",
             "reference/station-toml.md"]
FORMATS = ["formats/index.md", "formats/layout.md", "formats/check.md", "formats/guide-manifest.md",
           "formats/jigs.md", "formats/trials.md", "formats/loop.md", "formats/devices.md", "formats/test-card.md"]
SCHEMA_LINE = re.compile(r"^<!-- schema: ([a-z-]+) -->$", re.M)
#: argparse wraps its usage lines to the terminal; the reference is the same on every machine.
COLUMNS = "100"


# -- navigation -------------------------------------------------------------------------------------------------------
def _pages(docs: Path, folder: str) -> list[str]:
    return sorted(p.relative_to(docs).as_posix() for p in (docs / folder).glob("*.md"))


def build_nav(docs: Path) -> list:
    """The site's navigation from the pages under ``docs`` (see the module's docstring)."""
    exists = {p.relative_to(docs).as_posix() for p in docs.rglob("*.md")} | set(REFERENCE) | {"results/index.md"}
    placed = {page for _, pages in GUIDE for page in pages}
    guide = [{section: [p for p in pages if p in exists]} for section, pages in GUIDE]
    guide = [entry for entry in guide if next(iter(entry.values()))]
    more = [p for p in _pages(docs, "guide") if p not in placed]
    if more:
        guide.append({"More": more})
    results = sorted((p for p in _pages(docs, "results") if p != "results/index.md"), reverse=True)
    nav = [{"Home": "index.md"}, {"Guide": guide},
           {"Reference": REFERENCE},
           {"Formats": [p for p in FORMATS if p in exists]}]
    if (docs / "architecture.md").exists():
        nav.append({"Architecture": "architecture.md"})
    nav.append({"Results": ["results/index.md", *results]})
    if (docs / "changelog.md").exists():
        nav.append({"Changelog": "changelog.md"})
    return nav


def on_config(config, **kwargs):
    config["nav"] = build_nav(Path(config["docs_dir"]))
    return config


# -- generated pages --------------------------------------------------------------------------------------------------
def on_files(files, config, **kwargs):
    os.environ["COLUMNS"] = COLUMNS
    generated = {
        "reference/cli.md": cli_reference(),
        "reference/tui.md": tui_reference(),
        "reference/scenario.md": scenario_reference(),
        "reference/profile.md": profile_reference(),
        "reference/station-toml.md": station_toml_reference(),
        "results/index.md": results_index(Path(config["docs_dir"])),
    }
    from station.schemas import FORMATS as SCHEMAS
    from station.schemas import schema_text

    for name in SCHEMAS:
        generated[f"formats/schemas/{name}.schema.json"] = schema_text(name)
    for path, content in generated.items():
        if files.get_file_from_path(path) is None:
            files.append(File.generated(config, path, content=content))
    return files


def on_page_markdown(markdown, page, config, files, **kwargs):
    return SCHEMA_LINE.sub(lambda m: schema_block(m.group(1), page.file.src_uri), markdown)


def schema_block(name: str, src_uri: str) -> str:
    from station.schemas import schema_text

    link = os.path.relpath(f"formats/schemas/{name}.schema.json", os.path.dirname(src_uri) or ".")
    return (f'??? abstract "The schema: `{name}.schema.json` (draft 2020-12; [download]({link}))"\n\n'
            + "    ```json\n" + "".join(f"    {line}\n" for line in schema_text(name).splitlines()) + "    ```\n")


# -- the command line -------------------------------------------------------------------------------------------------
def _subparsers(parser: argparse.ArgumentParser) -> list[tuple[str, argparse.ArgumentParser, str]]:
    found = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {choice.dest: choice.help for choice in action._choices_actions}
            seen = set()
            for name, sub in action.choices.items():
                if id(sub) in seen:  # an alias
                    continue
                seen.add(id(sub))
                found.append((name, sub, helps.get(name) or ""))
    return found


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def _option_rows(parser: argparse.ArgumentParser) -> list[str]:
    rows = []
    for action in parser._actions:
        if isinstance(action, (argparse._SubParsersAction, argparse._HelpAction)) or action.help == argparse.SUPPRESS:
            continue
        if action.option_strings:
            metavar = ""
            if action.nargs != 0:
                metavar = " " + (action.metavar if isinstance(action.metavar, str)
                                 else action.dest.upper())
            name = ", ".join(f"`{o}{metavar}`" for o in action.option_strings)
        else:
            name = f"`{action.metavar or action.dest}`"
        text = action.help or ""
        if "%(" in text:
            try:
                text = text % {**vars(action), "prog": parser.prog,
                               "default": action.default, "choices": ", ".join(map(str, action.choices or []))}
            except (KeyError, TypeError, ValueError):
                pass
        if action.choices and not isinstance(action, argparse._SubParsersAction) and "{" not in name:
            text += f" (one of: {', '.join(map(str, action.choices))})"
        if action.default not in (None, False, argparse.SUPPRESS) and action.option_strings and \
                "default" not in text.lower() and action.nargs != 0:
            text += f" (default: `{action.default}`)"
        rows.append(f"| {name} | {_cell(text)} |")
    return rows


def _command_section(path: str, parser: argparse.ArgumentParser, summary: str, level: int) -> list[str]:
    out = [f"{'#' * level} `{path}`", ""]
    if summary:
        out += [_cell(summary), ""]
    if parser.description and parser.description != summary:
        out += [parser.description.strip(), ""]
    out += ["```text", parser.format_usage().strip(), "```", ""]
    rows = _option_rows(parser)
    if rows:
        out += ["| argument | what it does |", "| --- | --- |", *rows, ""]
    if parser.epilog:
        out += ["```text", parser.epilog.strip(), "```", ""]
    for name, sub, help_text in _subparsers(parser):
        out += _command_section(f"{path} {name}", sub, help_text, min(level + 1, 4))
    return out


def cli_reference() -> str:
    from station.cli import build_parser

    parser = build_parser()
    out = ["# The `station` command", "",
           "Made from the station's own argument parsers when the site is built, so it lists exactly the commands "
           "and options of this version (`station COMMAND --help` prints the same on a terminal). Exit codes: 0 "
           "success, 1 a negative but valid outcome (a simulated contraption that fails), 2 bad input or a device "
           "error (one line on stderr), 130 interrupted (Ctrl-C, or `kill`).", "",
           "```text", parser.format_usage().strip(), "```", "",
           "| command | what it does |", "| --- | --- |"]
    commands = _subparsers(parser)
    for name, _, help_text in commands:
        out.append(f"| [`station {name}`](#station-{name}) | {_cell(help_text)} |")
    out.append("")
    for name, sub, help_text in commands:
        out += _command_section(f"station {name}", sub, help_text, 2)
    return "\n".join(out) + "\n"


# -- the terminal UI ------------------------------------------------------------------------------------------------
def _bindings(cls) -> list:
    """The station's key bindings of a Textual class and its bases, the class's own last (they win, as in
    Textual)."""
    from textual.binding import Binding

    merged: dict[str, Binding] = {}
    for klass in reversed(cls.__mro__):
        if not klass.__module__.startswith("station."):  # Textual's own (focus, copy): the same on every screen
            continue
        for binding in klass.__dict__.get("BINDINGS", []):
            if not isinstance(binding, Binding):
                binding = Binding(*binding)
            merged[binding.key] = binding
    return list(merged.values())


def _key_words(key: str) -> str:
    return " or ".join(f"`{k.strip()}`" for k in key.split(","))


def _binding_table(cls) -> list[str]:
    rows = ["| key | what it does |", "| --- | --- |"]
    for binding in _bindings(cls):
        if binding.action in ("app.bell",):
            continue
        words = binding.description or binding.action
        rows.append(f"| {_key_words(binding.key)} | {_cell(words)} |")
    return rows


def tui_reference() -> str:
    from station.tui.app import StationApp
    from station.tui.registry import discover_screens

    entries = discover_screens()
    out = ["# Terminal UI keys", "",
           "Made from the screens' key bindings when the site is built. `station` (or `make run`) opens the home "
           "screen; each area has one key there. On every screen Tab and Shift+Tab move the focus between fields and "
           "tables (Textual's own keys); a text field with the focus takes the letters typed.", "",
           "## Everywhere", "", *_binding_table(StationApp), "",
           "## Home screen", "", "| key | opens |", "| --- | --- |"]
    out += [f"| `{e.key}` | [{_cell(e.title)}](#{_slug(e.title)}): {_cell(e.description)} |" for e in entries]
    out.append("")
    for entry in entries:
        cls = entry.factory if inspect.isclass(entry.factory) else type(entry.factory())
        out += [f"## {entry.title}", "", f"Key `{entry.key}` on the home screen. {_cell(entry.description)}", "",
                *_binding_table(cls), ""]
        doc = inspect.getdoc(cls)
        if doc:
            out += [doc.split("\n\n")[0].replace("\n", " "), ""]
    return "\n".join(out) + "\n"


def _slug(title: str) -> str:
    return re.sub(r"[^a-z0-9 -]", "", title.lower()).strip().replace(" ", "-")


# -- file formats from the modules that read them ---------------------------------------------------------------------
def rst_to_markdown(text: str) -> str:
    """A module docstring (reST as the station writes it) as Markdown: ``code``, :role:`name`, ``::`` blocks,
    section underlines and definition lists."""
    lines = text.splitlines()
    out: list[str] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        if i + 1 < len(lines) and lines[i + 1] and set(lines[i + 1]) == {"-"} and line.strip():
            out += [f"### {line.strip()}", ""]
            i += 2
            continue
        if line.rstrip().endswith("::"):
            text_part = line.rstrip()[:-2].rstrip()
            if text_part:
                out.append(_inline(text_part) + ":")
            out += ["", "```toml"]
            i += 1
            while i < len(lines) and not lines[i].strip():
                i += 1
            while i < len(lines) and (not lines[i].strip() or lines[i].startswith("    ")):
                out.append(lines[i][4:])
                i += 1
            while out and not out[-1].strip():
                out.pop()
            out += ["```", ""]
            continue
        if line.startswith("    ") and out and out[-1].startswith("``"):
            pass
        out.append(_inline(line[4:] if line.startswith("    ") else line))
        i += 1
    return "\n".join(out)


def _inline(text: str) -> str:
    text = re.sub(r":(?:mod|func|class|data|meth|attr):`~?([^`]+)`", r"`\1`", text)
    return text.replace("``", "`")


def _definition_list(doc: str) -> str:
    """The scenario docstring's ``[table]`` entries (a term line, its text indented) as headed paragraphs."""
    out = []
    for line in doc.splitlines():
        if line.startswith("``") and line.rstrip().endswith(("``", "(optional)")) and not line.startswith("    "):
            out += ["", f"#### {_inline(line.strip())}", ""]
        else:
            out.append(line[4:] if line.startswith("    ") else line)
    return "\n".join(out)


def scenario_reference() -> str:
    import design.contraption.scenario as scenario
    from design.contraption.schema import EVENT_COMMON, EVENTS, PRIMITIVES, REQUIRED

    doc = inspect.getdoc(scenario).split("\nThe code is split by topic")[0]
    body = _inline(_definition_list(doc.split("\n", 1)[1]))
    out = ["# Scenario files", "", _inline(doc.split("\n", 1)[0]), "",
           "Made from `design/contraption/scenario.py` and the schema tables of `design/contraption/schema.py` when "
           "the site is built. The examples are in `examples/scenarios/`; `station scenario check FILE` validates "
           "one.", "", body, "", "## Primitives", "",
           "Shape parameters (`[objects.shape]`) of each `type`: required unless a default is shown.", "",
           "| type | makes bodies | shape parameters |", "| --- | --- | --- |"]
    for name, primitive in PRIMITIVES.items():
        params = ", ".join(_param(k, p, REQUIRED) for k, p in primitive.params.items()) or "none"
        out.append(f"| `{name}` | {'yes' if primitive.body else 'no'} | {params} |")
    out += ["", "## Events", "",
            f"Every event has {', '.join(f'`{k}`' for k in EVENT_COMMON)}; its own parameters:", "",
            "| type | parameters |", "| --- | --- |"]
    for name, params in EVENTS.items():
        out.append(f"| `{name}` | {', '.join(_param(k, p, REQUIRED) for k, p in params.items()) or 'none'} |")
    return "\n".join(out) + "\n"


def _param(key, param, required) -> str:
    words = f"`{key}` ({param.kind.expected}"
    if param.default is not required:
        words += f"; default `{param.default}`" if param.default is not None else "; optional"
    return _cell(words + ")")


def profile_reference() -> str:
    import drivers.profiles as profiles

    doc = inspect.getdoc(profiles).split("\nThe package by topic")[0]
    title, body = doc.split("\n", 1)
    return ("# Machine profiles\n\n" + _inline(title) + "\n\nMade from `drivers/profiles/__init__.py` when the site "
            "is built. The built-in profiles `plotter` and `laser` are in `drivers/profiles/builtin/`; a profile of "
            "your own is any file of this form (`--profile FILE.toml`, or `profile = \"FILE.toml\"` in "
            "`station.toml`).\n\n" + rst_to_markdown(body) + "\n")


def station_toml_reference() -> str:
    import station.config as config

    doc = inspect.getdoc(config)
    title, body = doc.split("\n", 1)
    body = body.split("\nValidation is hand-written")[0]
    return ("# station.toml\n\n" + _inline(title) + "\n\nMade from `station/config.py` when the site is built. "
            "`station devices --init` writes the default as a commented file to edit.\n\n" + rst_to_markdown(body)
            + "\n")


# -- results ----------------------------------------------------------------------------------------------------------
def results_index(docs: Path) -> str:
    out = ["# Results", "",
           "What was measured, on what, and the figures: one page per measurement campaign, newest first. The "
           "guide says what the station does; these pages say how well, on the day they were measured. "
           "`make bench` (and `python -m bench NAME`) runs the benchmarks again; they print figures and never fail "
           "on timings.", "", "| date | campaign |", "| --- | --- |"]
    for path in sorted((docs / "results").glob("*.md"), reverse=True):
        if path.name == "index.md":
            continue
        date = path.name[:10] if re.match(r"\d{4}-\d\d-\d\d", path.name) else ""
        heading = next((line[2:].strip() for line in path.read_text(encoding="utf-8").splitlines()
                        if line.startswith("# ")), path.stem)
        out.append(f"| {date} | [{_cell(heading)}]({path.name}) |")
    return "\n".join(out) + "\n"
