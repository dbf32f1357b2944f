"""The Assemble screen's guide, shown as a maker reads it: :class:`StepsTable` (a row per part, in the order placed,
with its tag and how carefully it must be placed), :class:`PartParameters` (the current part's design parameters:
value, how to set it, what it means at the table) and :class:`ToleranceTable` (the tolerance map).

Each fills itself from a guide (:class:`projector.guide.Guide`, reached through the guide job the services return).
"""

from __future__ import annotations

from rich.text import Text
from textual.widgets import DataTable, Static

from station.services.guide import where_coords

#: How each care class of a part is coloured.
CARE_STYLE = {"tight": "red", "normal": "dark_orange", "loose": "green"}
#: How the parameters say each is set (the guide manifest's ``set_with``).
HOW_TEXT = {"sheet": "on the sheet", "ruler": "ruler", "jig": "jig", "check": "sheet + camera check"}


class StepsTable(DataTable):
    """A row per part of the guide, keyed by its name: step, part, kind, tag, centre (the point the steps give: a run
    of pieces' centroid, :func:`station.services.guide.where_coords`), care."""

    def on_mount(self) -> None:
        self.add_columns("step", "part", "kind", "tag", "centre mm", "care")

    def load(self, guide) -> None:
        self.clear()
        for part in guide.parts:
            care = Text(part.care or "-", style=CARE_STYLE.get(part.care or "", ""))
            self.add_row(str(part.step), Text(part.name), str(part.kind),
                         "-" if part.tag_id is None else str(part.tag_id),
                         where_coords(part), care, key=part.name)


class PartParameters(Static):
    """The current step's part: a line per design parameter that moves it, with its value, tolerance, how to set it
    and what it means at the table (hidden on the calibrate frame and for a part no parameter moves)."""

    def show(self, part) -> None:
        settings = () if part is None else part.settings
        text = Text()
        for setting in settings:  # the meaning carries the tolerance: "... 58.7 mm (+-5.3 mm)"
            if text:
                text.append("\n")
            text.append(f"{setting.name} = {setting.value:.1f} {setting.unit}", style="bold")
            text.append(f"  [{HOW_TEXT.get(setting.set_with, setting.set_with)}]  ", style="cyan")
            text.append(setting.meaning)
        self.update(text)
        self.display = bool(settings)


class ToleranceTable(DataTable):
    """The tolerance map: a row per part and parameter, its zone (± delta), the predicted and measured success."""

    def on_mount(self) -> None:
        self.add_columns("part", "parameter", "± delta", "predicted", "measured")

    def load(self, guide) -> None:
        self.clear()
        for part in guide.parts:
            for tolerance in part.tolerances:
                delta = "-" if tolerance.delta is None else f"{tolerance.delta:.1f} {tolerance.unit}"
                if tolerance.bound_limited:  # only a lower bound: the layout sits at its range's end
                    delta = f">= {delta} (range end)"
                self.add_row(Text(part.name), Text(tolerance.parameter), delta,
                             "-" if tolerance.predicted is None else f"{tolerance.predicted:.2f}",
                             "-" if tolerance.measured is None else f"{tolerance.measured:.2f}")
