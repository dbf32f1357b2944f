"""The Machines screen's console: what was sent to and heard from the machines, and the screen's messages."""

from __future__ import annotations

from rich.text import Text
from textual.widgets import RichLog


class MachineConsole(RichLog):
    """A log of plain text lines, wrapped at the panel's edge, never focused.

    Lines carry what users and devices wrote (G-code, ``[MSG:...]`` replies, file names), so they are never read as
    markup. Never focused: a focused log takes the arrows and PgUp/PgDn (it scrolls), and the screen jogs with them;
    the mouse wheel still scrolls it.
    """

    def __init__(self, **kwargs) -> None:
        # Long lines wrap (GRBL's settings and error replies were cut at the panel's edge).
        super().__init__(max_lines=500, wrap=True, markup=False, **kwargs)
        self.can_focus = False

    def say(self, text: str, style: str = "") -> None:
        """Add ``text`` as one (wrapped) line in ``style`` (``"red"``)."""
        self.write(Text(text, style=style))
