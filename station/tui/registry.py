"""Discovery of the TUI's area screens, and the values they hand each other through the app.

Each module in :mod:`station.tui.screens` (except ``home``) defines ``SCREEN = ScreenEntry(...)``. The app installs
every entry under its ``name`` and binds its ``key`` on the home screen, so adding an area never edits the app.
Screens never import each other: one reaches another through :class:`station.tui.app.StationApp`'s accessors
(``current_design()``, ``machines_screen()``), which answer None in an app without that area.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

from textual.screen import Screen

import station.tui.screens as screens_package
from station.services.designs import get_machine


class MachineDesign(NamedTuple):
    """A drawing-machine design: the machine's name and its parameters (what the Drawing screen shows)."""

    machine: str
    params: dict[str, float]

    @classmethod
    def defaults(cls, machine: str) -> MachineDesign:
        """``machine`` with its default parameters (a screen's start when there is no Drawing screen)."""
        model = get_machine(machine)
        return cls(model.name, model.defaults())


@dataclass(frozen=True)
class ScreenEntry:
    """An area screen of the TUI.

    Parameters
    ----------
    name : str
        Install name (``app.switch_screen(name)``), e.g. ``"drawing"``.
    key : str
        The key that opens it from the home screen (one lower-case letter).
    title : str
        Shown on the home screen.
    description : str
        One line shown under the title.
    factory : callable
        Builds the screen (no arguments).
    order : int
        Position on the home screen.
    """

    name: str
    key: str
    title: str
    description: str
    factory: Callable[[], Screen]
    order: int = 100


def discover_screens() -> list[ScreenEntry]:
    """Every area screen, in home-screen order. Duplicate names or keys are a programming error."""
    entries: list[ScreenEntry] = []
    for info in pkgutil.iter_modules(screens_package.__path__):
        if info.name.startswith("_") or info.name == "home":
            continue
        module = importlib.import_module(f"{screens_package.__name__}.{info.name}")
        entry = getattr(module, "SCREEN", None)
        if isinstance(entry, ScreenEntry):
            entries.append(entry)
    entries.sort(key=lambda e: (e.order, e.name))
    for attr in ("name", "key"):
        seen = [getattr(e, attr) for e in entries]
        duplicates = {v for v in seen if seen.count(v) > 1}
        if duplicates:
            raise RuntimeError(f"TUI screens share a {attr}: {sorted(duplicates)}")
    return entries
