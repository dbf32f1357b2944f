"""The ``station`` command line.

Subcommands live one area per module in :mod:`station.commands`; each module defines
``register(subparsers) -> None`` which adds its parsers and sets ``func=run(args) -> int`` on them. Modules are
discovered, so adding a command never edits this file.

Exit codes: 0 success, 1 a negative but valid outcome (e.g. a simulated contraption failed), 2 bad input or a
device error (one clear line on stderr, never a traceback), 130 interrupted (Ctrl-C, or SIGTERM from ``kill``,
which stops a command the same clean way: a laser job is aborted with the laser off, a simulation pool is shut
down and its cache kept).
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import signal
import sys
import textwrap
import threading
from collections.abc import Sequence

import station.commands as package
from station import __version__
from station.config import configured_devices
from station.errors import USER_ERRORS


def command_modules() -> list[str]:
    """Names of the modules in :mod:`station.commands`, sorted for a stable help text."""
    return sorted(
        f"{package.__name__}.{info.name}"
        for info in pkgutil.iter_modules(package.__path__)
        if not info.name.startswith("_")
    )


class LineKeepingFormatter(argparse.HelpFormatter):
    """argparse's formatter, but each line of a description or epilog is wrapped on its own.

    Descriptions are one long line (wrapped to the terminal as before); an epilog's ``examples:`` are one command
    per line, which the default formatter would run together into one paragraph.
    """

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        lines = []
        for line in text.splitlines():
            stripped = line.lstrip()
            inner = indent + line[: len(line) - len(stripped)]
            # A wrapped example line is indented further, so that it reads as one command.
            follow = inner + "  " if inner != indent else inner
            lines.append(textwrap.fill(stripped, width, initial_indent=inner, subsequent_indent=follow)
                         if stripped else "")
        return "\n".join(lines)


class StationParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line: what is wrong, and which ``--help`` to read.

    argparse prints the whole usage (2-8 lines) before its error; in a terminal the line that matters scrolls by.
    Every subcommand parser is one of these (``parser_class``, inherited down the tree by argparse), and a command
    group with subcommands (``station scenario``) given none names them instead of printing its help.

    Parameters
    ----------
    command_required
        Whether a subcommand must be given when this parser has subcommands. False only for ``station`` itself,
        where no command starts the terminal UI.
    """

    def __init__(self, *args, command_required: bool = True, **kwargs) -> None:
        kwargs.setdefault("formatter_class", LineKeepingFormatter)
        super().__init__(*args, **kwargs)
        self.command_required = command_required

    def error(self, message: str):
        """Print ``PROG: error: MESSAGE (see PROG --help)`` on one line and exit 2."""
        message = " ".join(str(message).split())
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

    def parse_known_args(self, args=None, namespace=None):
        namespace, extras = super().parse_known_args(args, namespace)
        if self.command_required:
            for action in self._subcommand_actions():
                if getattr(namespace, action.dest, None) is None:
                    name = action.metavar or action.dest.upper()
                    self.error(f"expected {name}, one of: {', '.join(action.choices)}")
        return namespace, extras

    def parse_args(self, args=None, namespace=None):
        # argparse reports unknown options from the top parser ("station: error: ..."); name the command they were
        # given to, so the hint points at the --help that lists its options.
        namespace, extras = self.parse_known_args(args, namespace)
        if extras:
            self._chosen_parser(namespace).error(f"unrecognized arguments: {' '.join(extras)}")
        return namespace

    def _subcommand_actions(self) -> list[argparse._SubParsersAction]:
        return [a for a in self._actions
                if isinstance(a, argparse._SubParsersAction) and a.dest is not argparse.SUPPRESS]

    def _chosen_parser(self, namespace) -> argparse.ArgumentParser:
        """The innermost (sub)command parser the parsed ``namespace`` went through."""
        for action in self._subcommand_actions():
            chosen = action.choices.get(getattr(namespace, action.dest, None))
            if chosen is not None:
                return chosen._chosen_parser(namespace) if isinstance(chosen, StationParser) else chosen
        return self


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser, with every discovered subcommand."""
    parser = StationParser(
        prog="station",
        description="Crafting Chaos station: drawing machines and chain-reaction contraptions. "
        "Without a command, starts the terminal UI on simulated devices.",
        command_required=False,
    )
    parser.add_argument("--version", action="version", version=f"station {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=StationParser)
    for name in command_modules():
        module = importlib.import_module(name)
        module.register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``station`` console script."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "func", None) is None:
        if args.command is None:
            try:
                return run_tui()
            except USER_ERRORS as error:  # a bad station.toml, CHAOS_STATION_HOME a file: before the screen
                print(f"station: error: {error}", file=sys.stderr)
                return 2
        parser.parse_args([args.command, "--help"])
        return 2
    previous = _stop_cleanly_on_sigterm()
    try:
        return int(args.func(args) or 0)
    except BrokenPipeError:
        return 0
    except FileNotFoundError as error:
        print(f"station: error: no such file: {error.filename}", file=sys.stderr)
        return 2
    except (IsADirectoryError, PermissionError) as error:
        print(f"station: error: cannot use {error.filename}: {error.strerror}", file=sys.stderr)
        return 2
    except USER_ERRORS as error:
        print(f"station: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("station: interrupted", file=sys.stderr)
        return 130
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _raise_interrupt(signum, frame) -> None:
    raise KeyboardInterrupt


def _stop_cleanly_on_sigterm():
    """Make SIGTERM raise KeyboardInterrupt, so every command's Ctrl-C clean-up also runs on ``kill``.

    Without it the process dies at once: a streaming laser job gets no laser-off and simulation workers are left
    running. Returns the previous handler (None when not on the main thread, where handlers cannot be set).
    """
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, _raise_interrupt)


def run_tui() -> int:
    """Start the Textual app on the station's devices (its config file, else all simulated) and local SQLite."""
    from station.tui.app import StationApp  # heavy: rich, textual

    StationApp(devices=configured_devices()).run()
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
