from __future__ import annotations

import numpy as np
from textual.widgets import Select

from design.machines import get_machine, machine_names
from station.errors import StationError
from station.services.drawing import feasible_interval, machine_choices, pattern, validate_design
from station.tui.screens.drawing import mechanism_to_drawing
from station.tui.widgets.canvas import PatternCanvas
from station.tui.widgets.parameter import ParameterControl

from ...conftest import opened, settle


async def test_slider_move_changes_pattern_and_undo_restores_it(tmp_path):
    async with opened(tmp_path, "d", size=(140, 40)) as (app, pilot):
        screen = app.screen
        assert screen.name == "drawing"
        before = screen.pattern.copy()
        d_before = screen.params["d"]
        control = screen.query_one("#param-d", ParameterControl)
        control.focus()
        await pilot.press("right", "right", "right")
        await settle(app, pilot)
        assert screen.params["d"] > d_before
        assert not np.allclose(screen.pattern, before)
        canvas = screen.query_one("#canvas", PatternCanvas)
        assert np.allclose(canvas.polylines[0], screen.pattern)
        for _ in range(3):
            await pilot.press("ctrl+z")
        await settle(app, pilot)
        assert screen.params["d"] == d_before
        assert np.allclose(screen.pattern, before)


async def test_slider_never_leaves_feasible_interval(tmp_path):
    async with opened(tmp_path, "d", size=(140, 40)) as (app, pilot):
        screen = app.screen
        control = screen.query_one("#param-d", ParameterControl)
        control.focus()
        await pilot.press("end")
        await settle(app, pilot)
        lower, upper = screen.machine.feasible_interval(screen.params, "d")
        assert screen.params["d"] == control.state.upper
        assert lower <= screen.params["d"] <= upper
        assert screen.machine.is_feasible(screen.params)
        await pilot.press("right")
        await settle(app, pilot)
        assert screen.params["d"] <= upper


async def test_gear_stepper_only_reaches_feasible_designs_and_rebounds_sliders(tmp_path):
    async with opened(tmp_path, "d", size=(140, 40)) as (app, pilot):
        screen = app.screen
        control = screen.query_one("#param-r_r", ParameterControl)
        control.focus()
        seen = []
        for key in ["right"] * 3 + ["left"] * 6:
            await pilot.press(key)
            await settle(app, pilot)
            seen.append(dict(screen.params))
        assert all(screen.machine.is_feasible(p) for p in seen)
        # Up: r_r stops below the ring (r_f = 5); down: the pen distance is pulled inside the smaller gear.
        assert max(p["r_r"] for p in seen) == 4
        assert seen[-1]["r_r"] < 2 and seen[-1]["d"] < 2.0
        d_control = screen.query_one("#param-d", ParameterControl)
        assert (d_control.state.lower, d_control.state.upper) == screen.machine.feasible_interval(screen.params, "d")


async def test_switching_machine_rebuilds_controls_and_load_design(tmp_path):
    async with opened(tmp_path, "d", size=(140, 40)) as (app, pilot):
        screen = app.screen
        other = next(name for name in machine_names() if name != screen.machine.name)
        screen.query_one("#machine", Select).value = other
        await settle(app, pilot)
        names = {c.parameter_name for c in screen.query(ParameterControl)}
        assert names == set(get_machine(other).parameter_names)
        app.open_design("spirograph", {"r_f": 7, "r_r": 2, "d": 1.0})
        await settle(app, pilot)
        assert screen.current_design() == ("spirograph", {"r_f": 7, "r_r": 2, "d": 1.0})
        assert {c.parameter_name for c in screen.query(ParameterControl)} == {"r_f", "r_r", "d"}
        # A bad design is reported, and the current one stays.
        app.open_design("spirograph", {"r_f": 7, "r_r": 9, "d": 1.0})
        await settle(app, pilot)
        assert screen.current_design()[1]["r_r"] == 2


async def test_animation_draws_mechanism(tmp_path):
    async with opened(tmp_path, "d", size=(140, 40)) as (app, pilot):
        screen = app.screen
        canvas = screen.query_one("#canvas", PatternCanvas)
        await pilot.press("p")
        await pilot.pause(0.3)
        assert screen.animating and screen.time > 0
        assert len(canvas.polylines) > 2  # pattern, traced part, mechanism parts
        await pilot.press("p")
        assert not screen.animating


def test_mechanism_shapes_become_polylines_and_markers():
    model = get_machine("elliptic_spirograph")
    polylines, markers = mechanism_to_drawing(model.mechanism(model.defaults(), 0.5))
    assert len(polylines) >= 3
    assert all(p.ndim == 2 and p.shape[1] == 2 for p in polylines)
    assert markers


async def test_open_design_before_the_drawing_screen_was_ever_shown(tmp_path):
    async with opened(tmp_path, size=(140, 40)) as (app, pilot):
        await pilot.pause()
        app.open_design("cycloid_drawing_machine", get_machine("cycloid_drawing_machine").defaults())
        await settle(app, pilot)
        screen = app.screen
        assert screen.name == "drawing"
        assert screen.current_design()[0] == "cycloid_drawing_machine"
        names = {c.parameter_name for c in screen.query(ParameterControl)}
        assert names == set(get_machine("cycloid_drawing_machine").parameter_names)
        assert screen.query_one("#machine", Select).value == "cycloid_drawing_machine"
        assert screen.pattern is not None


async def test_the_app_hands_the_drawing_design_to_other_screens(tmp_path):
    async with opened(tmp_path, size=(140, 40)) as (app, pilot):
        await pilot.pause()
        app.open_design("spirograph", {"r_f": 7, "r_r": 2, "d": 1.0})
        await settle(app, pilot)
        design = app.current_design()
        assert design == ("spirograph", {"r_f": 7, "r_r": 2, "d": 1.0})
        assert (design.machine, design.params) == app.screen.current_design()
        design.params["r_r"] = 3  # a copy: the Drawing screen's design stays
        assert app.current_design().params["r_r"] == 2
    async with opened(tmp_path, without=("drawing",)) as (app, pilot):
        await pilot.pause()
        assert app.current_design() is None
        assert app.open_area_if_installed("drawing") is None  # a warning, not a crash
        app.open_design("spirograph", {"r_f": 7, "r_r": 2, "d": 1.0})
        await pilot.pause()
        assert app.screen.name == "home" and app.current_design() is None


async def test_slider_bounds_read_as_numbers_for_people(tmp_path):
    # The spirograph's d > 0 is strict: its feasible interval starts at the smallest float above 0, which was shown
    # as [4.94e-324…3]. A strict end is shown open at its round number; the value keeps a fixed number of places.
    async with opened(tmp_path, "d", size=(140, 40)) as (app, pilot):
        control = app.screen.query_one("#param-d", ParameterControl)
        assert 0 < control.state.lower < 1e-300
        shown = str(control.render())
        assert "(0…3]" in shown and "e-" not in shown
        control.focus()
        await pilot.press("home")
        await settle(app, pilot)
        shown = str(control.render())
        assert " 0.000 (0…3]" in shown and "e-" not in shown


def test_bounds_are_rounded_to_the_span_and_strict_ends_shown_open():
    from station.tui.widgets.parameter import format_bounds, format_value

    assert format_bounds(5e-324, 3.0) == "(0…3]"
    assert format_bounds(7.000000000000001, 14.58539533417132) == "(7…14.59]"  # d_tf > r_t + r_e, strict
    assert format_bounds(0.0, 3.9999999999999996) == "[0…4)"
    assert format_bounds(1.0960738664727085, 1.397526788541976) == "[1.096…1.398]"
    assert format_bounds(2.0, 2.0) == "[2…2]"
    assert format_value(2.0, 5e-324, 3.0) == "2.000"
    assert format_value(-1e-9, 0.0, 3.0) == "0.000"


def test_the_live_design_is_asked_through_the_service_and_refused_as_a_station_error():
    # The screen catches only the station's errors: the model's own refusals must come out as one of them, with the
    # model's message, and the answers must be the model's.
    model = get_machine("spirograph")
    try:
        validate_design(model, {"r_f": 2, "r_r": 5, "d": 1})
    except StationError as error:
        assert "r_r must be smaller than r_f" in str(error)
    else:
        raise AssertionError("an infeasible design was accepted")
    assert feasible_interval(model, model.defaults(), "d") == model.feasible_interval(model.defaults(), "d")
    period, points = pattern(model, model.defaults(), lambda period: 300)
    assert period == model.period(model.defaults()) and points.shape == (300, 2)
    assert [name for _, name in machine_choices()] == machine_names()
