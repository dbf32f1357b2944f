"""The focused widget is easy to see: every stop of the focus chain changes a border or background to the theme's
accent colour when focused (a 5 % tint on a table, or a focused scroll container, showed nothing one could see)."""

from __future__ import annotations

from textual.color import Color

from ...conftest import opened


def _look(widget):
    styles = widget.styles
    return styles.border_top, styles.border_left, styles.background, styles.text_style


def _shows_accent(look, accent: Color) -> bool:
    (_, top), (_, left), background, _ = look
    return any(colour is not None and colour.rgb == accent.rgb for colour in (top, left, background))


async def _assert_focus_visible(app, pilot, screen):
    accent = Color.parse(app.theme_variables["accent"])
    chain = list(screen.focus_chain)
    assert len(chain) >= 2
    for widget in chain:
        widget.focus()
        await pilot.pause()
        focused = _look(widget)
        next(w for w in chain if w is not widget).focus()
        await pilot.pause()
        blurred = _look(widget)
        assert _shows_accent(focused, accent), f"{widget} does not show that it is focused"
        assert not _shows_accent(blurred, accent), f"{widget} looks focused when it is not"


async def test_focus_is_visible_on_the_explore_screen(tmp_path):
    async with opened(tmp_path, "x", size=(150, 45)) as (app, pilot):
        screen = app.screen
        assert screen.name == "explore" and screen.explorer is not None
        await _assert_focus_visible(app, pilot, screen)


async def test_focus_is_visible_on_the_fabricate_screen(tmp_path):
    async with opened(tmp_path, "f", wait=False) as (app, pilot):
        screen = app.screen
        assert screen.name == "fabricate"
        await _assert_focus_visible(app, pilot, screen)


async def test_tab_goes_from_the_machine_choice_straight_to_the_sliders(tmp_path):
    # The sliders' scroll container was a focus stop of its own, showing nothing: Tab seemed to do nothing once.
    from textual.containers import ScrollableContainer

    async with opened(tmp_path, "d", size=(140, 40)) as (app, pilot):
        chain = list(app.screen.focus_chain)
        assert chain and not any(isinstance(widget, ScrollableContainer) for widget in chain)
        assert [type(widget).__name__ for widget in chain[1:]] == ["ParameterControl"] * (len(chain) - 1)
