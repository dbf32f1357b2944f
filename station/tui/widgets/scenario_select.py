"""The example scenarios as a Select's options, and choosing a scenario file in one (Robust layouts, Assemble)."""

from __future__ import annotations

from pathlib import Path

from textual.widgets import Select

from station.services.contraption import example_files


def scenario_choices() -> list[tuple[str, str]]:
    """(label, path) of the example scenarios."""
    return [(name, str(path)) for name, path in example_files()]


def select_scenario(select: Select, path: str) -> str:
    """Choose the scenario file ``path`` in ``select`` (added to the examples when it is not one); the value set."""
    path = str(Path(path).resolve())
    choices = scenario_choices()
    known = next((value for _, value in choices if str(Path(value).resolve()) == path), None)
    if known is None:
        select.set_options([*choices, (Path(path).stem, path)])
        known = path
    select.value = known
    return known


def scenario_select(widget_id: str = "scenario") -> Select:
    """A Select of the example scenarios, the first chosen (blank only when there is none)."""
    choices = scenario_choices()
    return Select(choices, id=widget_id, allow_blank=not choices, value=choices[0][1] if choices else Select.BLANK)
