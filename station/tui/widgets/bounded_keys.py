"""The keys and look shared by the one-line controls that move a value between live bounds (the Drawing screen's
parameter sliders, the Explore screen's invariant sliders)."""

from __future__ import annotations

from collections.abc import Callable

from textual.binding import Binding


def one_line_control_css(widget: str) -> str:
    """``DEFAULT_CSS`` of a one-line focusable control named ``widget``: full width, highlighted when focused."""
    return f"""
    {widget} {{ height: 1; width: 1fr; padding: 0 1; }}
    {widget}:focus {{ background: $accent 30%; }}
    """


def bounded_value_bindings(nudge_arguments: Callable[[int, str], str]) -> list[Binding]:
    """left/right nudge the value (``coarse``), shift+left/right nudge it ``fine``, home/end go to the bounds.

    ``nudge_arguments(direction, size)`` (direction -1 or +1, size ``"coarse"`` or ``"fine"``) is the text of the
    widget's ``nudge`` action arguments, e.g. ``"-0.2"`` for ``nudge(-0.2)``.
    """
    return [
        *(Binding(f"{prefix}{key}", f"nudge({nudge_arguments(direction, size)})", f"{sign}{suffix}", show=False)
          for prefix, size, suffix in (("", "coarse", ""), ("shift+", "fine", " fine"))
          for key, direction, sign in (("left", -1, "−"), ("right", 1, "+"))),
        Binding("home", "to_bound('lower')", "min", show=False),
        Binding("end", "to_bound('upper')", "max", show=False),
    ]
