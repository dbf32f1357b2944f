"""The Assemble screen's camera check: :class:`CheckTable`, a row per tagged part (how far it is off, within its
tolerance or not, what to do), one per part the side camera read (its height and tilt on the board's plane: ``du``
along the board, ``dv`` up, the turn its tilt) and one per part checked by eye, and :func:`check_lines`, what the check
says under the camera frame.
"""

from __future__ import annotations

from collections.abc import Collection

from rich.text import Text
from textual.widgets import DataTable

from station.services.assemble import misplaced
from station.services.check import no_zone_words, summary_lines


class CheckTable(DataTable):
    """A check's parts, keyed by name (``eye:NAME`` for a part checked by eye)."""

    def on_mount(self) -> None:
        self.add_columns("part", "tag", "du mm", "dv mm", "dist mm", "turn deg", "ok", "cost", "what to do")

    def load(self, report, side_off: Collection[str] = ()) -> None:
        """Fill the table from a check's report (:class:`station.services.check.CheckJob`'s ``report``);
        ``side_off``: the parts whose height or tilt is to set again
        (:attr:`station.services.assemble.Assembly.side_off`)."""
        self.clear()
        for part in report.parts:
            error = part.error
            numbers = (["-"] * 4 if error is None else
                       [f"{error[0]:+.1f}", f"{error[1]:+.1f}", f"{error[2]:.1f}", f"{error[3]:+.1f}"])
            # the check's one rule: no zone on the sheet (*) and off by 1 mm / 1 deg or more is to move
            star = "*" if part.within_tolerance is None and error is not None else ""
            ok = (Text("-", style="dim") if error is None else Text("NO" + star, style="bold red")
                  if misplaced(part) else Text("yes" + star, style="green"))
            self.add_row(Text(part.name), str(part.tag_id), *numbers, ok,
                         "-" if part.cost is None else f"{part.cost:.2f}", Text(part.instruction), key=part.name)
        for part in report.side_parts:  # the side camera's: along the board, up, the tilt
            error = part.error
            numbers = (["-"] * 4 if error is None else
                       [f"{error[0]:+.1f}", f"{error[1]:+.1f}", f"{error[2]:.1f}", f"{error[3]:+.1f}"])
            ok = (Text("not seen", style="bold red") if not part.found else Text("NO", style="bold red")
                  if part.name in side_off else Text("yes", style="green"))
            via = f", jig {part.via}" if part.via else ""
            self.add_row(Text(f"{part.name} (side{via})"), str(part.tag_id), *numbers, ok, "-",
                         Text(part.instruction or ""), key=f"side:{part.name}")
        for name in report.by_eye:
            self.add_row(Text(name), "-", "", "", "", "", Text("by eye", style="dim"), "-",
                         Text("check by eye against the sheet"), key=f"eye:{name}")


def check_lines(check, side_off: Collection[str] = ()) -> list[str]:
    """What a check says in short lines: its summary (with a side camera, how many parts to set again in height or
    tilt: ``side_off``), what a star means when a part has no zone, the prediction's note."""
    report = check.report
    lines = summary_lines(report, check.physical)
    if report.side_parts:  # next to the top camera's count: what the side camera read
        seen = sum(1 for p in report.side_parts if p.found)
        off = sum(1 for p in report.side_parts if p.name in side_off)
        at = next((i + 1 for i, line in enumerate(lines) if "tagged parts measured" in line), len(lines))
        lines.insert(at, f"side camera: {seen} of {len(report.side_parts)} jig stands read, {off} to raise, lower or "
                         "tilt")
    if any(part.found and part.within_tolerance is None for part in report.parts):
        lines.append(f"yes*/NO*: {no_zone_words()}")
    measured = report.measured_by_side
    if measured:
        lines.append(f"measured by the side camera: {', '.join(measured)}")
    if report.prediction_note:
        lines.append(report.prediction_note)
    return lines
