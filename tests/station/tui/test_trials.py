"""The Trials screen (Pilot): tick the events of a run in the graph's order, log it, filter the list, export."""

from __future__ import annotations

import json

from textual.widgets import DataTable, Input

from station.db import DATABASE_VARIABLE
from station.services.trials import build_trial, layout_values, load_trial_scenario
from station.triallog import TrialStore

from ...conftest import opened, settle

#: Areas the test does not need (their screens take seconds to build under load).
OTHER_AREAS = ("drawing", "explore", "sketch", "fabricate", "machines", "assemble", "optimize", "contraption")


async def test_tick_events_in_graph_order_log_filter_and_export(tmp_path, monkeypatch):
    url = str(tmp_path / "trials.sqlite3")
    monkeypatch.setenv(DATABASE_VARIABLE, url)
    with TrialStore(url) as store:  # a trial logged earlier (by the CLI, another station)
        ballrun = load_trial_scenario("ballrun")
        store.add(build_trial(ballrun, layout_values(ballrun, ballrun.layout("success")), {"ball_stops": "yes"},
                              who="bo"))
    async with opened(tmp_path, "t", without=OTHER_AREAS) as (app, pilot):
        screen = app.screen
        assert screen.name == "trials"
        trials = screen.query_one("#trials", DataTable)
        assert trials.row_count == 1
        screen.choose_scenario(str(load_trial_scenario("simple").source))
        await pilot.pause()
        events = screen.query_one("#events", DataTable)
        assert [str(events.get_cell(e, "event")) for e in screen.scenario.graph_order] == [
            "ball_rolls", "ball_hits_domino", "first_topples", "last_topples", "last_stops"]
        assert str(events.get_cell("ball_rolls", "outcome")) == "?"
        events.focus()
        await pilot.press("y")  # ball_rolls happened; the cursor moves on to ball_hits_domino
        await pilot.press("y")
        await pilot.press("n")  # first_topples did not: the two after it are not reached, shown dim
        assert screen.given == {"ball_rolls": "yes", "ball_hits_domino": "yes", "first_topples": "no"}
        assert str(events.get_cell("last_topples", "outcome")) == "(not-reached)"
        assert "a failure; l logs it" in str(screen.query_one("#status").render())
        screen.query_one("#who", Input).value = "ann"
        screen.prediction_samples = 4  # the physical success shown after the log, from 4 simulations
        await pilot.press("l")
        await settle(app, pilot)
        assert screen.last_logged == 2
        await app.workers.wait_for_complete()
        await pilot.pause()
        outlook = str(screen.query_one("#outlook").render())
        assert "after trial #2: physical success" in outlook and "attempts" in outlook, outlook
        assert "logged trial #2 (SIMPLE, failure)" in str(screen.query_one("#status").render())
        assert trials.row_count == 2
        with TrialStore(url) as store:
            logged = store.get(2)
        assert logged["outcomes"] == {"ball_rolls": "yes", "ball_hits_domino": "yes", "first_topples": "no",
                                      "last_topples": "not-reached", "last_stops": "not-reached"}
        assert logged["who"] == "ann" and logged["layout"] == {"track.x": -0.06, "track.z": 0.06, "track.roll": 30.0}

        # an impossible tick is said on the status line, and logging it is refused, nothing written
        events.move_cursor(row=0)
        await pilot.press("y", "y")  # ball_rolls yes, ball_hits_domino yes
        events.move_cursor(row=0)
        await pilot.press("n")  # then ball_rolls no: ball_hits_domino's yes is impossible
        assert "ball_hits_domino: expected 'not-reached', got 'yes'" in str(screen.query_one("#status").render())
        await pilot.press("l")
        await settle(app, pilot)
        assert "ball_hits_domino: expected 'not-reached'" in str(screen.query_one("#status").render())
        assert trials.row_count == 2

        # filter, then export what is listed
        screen.query_one("#filter", Input).value = "simple"
        await pilot.pause()
        assert [t["id"] for t in screen.trials] == [2]
        out = tmp_path / "simple.json"
        screen.query_one("#export-path", Input).value = str(out)
        events.focus()
        await pilot.press("e")
        await settle(app, pilot)
        assert "1 trial(s) exported" in str(screen.query_one("#status").render())
        exported = json.loads(out.read_text())
        assert [t["id"] for t in exported["trials"]] == [2]


async def test_c_takes_the_scenario_and_layout_of_the_contraptions_screen(tmp_path, monkeypatch):
    monkeypatch.setenv(DATABASE_VARIABLE, str(tmp_path / "trials.sqlite3"))
    others = tuple(a for a in OTHER_AREAS if a != "contraption")
    async with opened(tmp_path, "c", without=others) as (app, pilot):
        await pilot.press("l")  # the Contraptions screen's next layout: SIMPLE's "failure"
        await pilot.press("escape", "t")
        await settle(app, pilot)
        screen = app.screen
        assert screen.name == "trials"
        screen.choose_scenario(str(load_trial_scenario("ballrun").source))
        screen.query_one("#events", DataTable).focus()
        await pilot.press("c")
        assert screen.scenario.name == "SIMPLE"
        assert screen.query_one("#layout", Input).value == "failure"


def _status(screen) -> str:
    return str(screen.query_one("#status").render())


def _footer_keys(app) -> dict[str, str]:
    """The keys the footer shows, key -> label (what a maker sees at the bottom of the screen)."""
    from textual.widgets._footer import FooterKey

    return {key.key: key.description for key in app.screen.query(FooterKey)}


async def test_after_a_no_the_cursor_and_the_hint_go_to_the_next_event_to_say_and_implied_ones_stay(tmp_path,
                                                                                                   monkeypatch):
    """BALLRUN: y y n leaves lever_pivots and low_plank_leaves not reached (the plank did not topple), but
    ball_rolls_bottom (after the plank was hit) still to say: the cursor and the hint go there, and a y there keeps
    the implied outcomes. A key on an implied event is refused, naming the event to change instead."""
    monkeypatch.setenv(DATABASE_VARIABLE, str(tmp_path / "trials.sqlite3"))
    async with opened(tmp_path, "t", without=OTHER_AREAS) as (app, pilot):
        screen = app.screen
        screen.choose_scenario(str(load_trial_scenario("ballrun").source))
        await pilot.pause()
        events = screen.query_one("#events", DataTable)
        events.focus()
        await pilot.press("y", "y", "n")
        assert screen.current_event() == "ball_rolls_bottom"
        assert _status(screen).startswith("ball_rolls_bottom: missing")
        implied = {name: str(events.get_cell(name, "outcome")) for name in ("lever_pivots", "low_plank_leaves")}
        assert implied == {"lever_pivots": "(not-reached)", "low_plank_leaves": "(not-reached)"}
        await pilot.press("y")  # the ball rolled down the bottom track (but the low plank never left: no goblet)
        assert screen.given == {"ball_rolls_top": "yes", "ball_hits_plank": "yes", "plank_topples": "no",
                                "ball_rolls_bottom": "yes"}
        assert {name: str(events.get_cell(name, "outcome")) for name in implied} == implied
        assert str(events.get_cell("ball_stops", "outcome")) == "(not-reached)"
        assert "every event said: a failure" in _status(screen)

        events.move_cursor(row=screen.scenario.graph_order.index("lever_pivots"))
        await pilot.press("y")  # the lever cannot have pivoted: the plank did not topple
        assert "lever_pivots" not in screen.given
        assert str(events.get_cell("lever_pivots", "outcome")) == "(not-reached)"
        assert _status(screen) == ("lever_pivots is not reached: plank_topples is 'no'; change plank_topples to "
                                   "change it")
        await pilot.press("u")  # agrees with what is implied: nothing changes, it stays implied
        assert "lever_pivots" not in screen.given and "every event said: a failure" in _status(screen)

        screen.choose_scenario(str(load_trial_scenario("ballrun").source))
        events.move_cursor(row=screen.scenario.graph_order.index("ball_stops"))
        await pilot.press("y")  # the ball stopped in the goblet: everything before it happened
        events.move_cursor(row=0)
        await pilot.press("n")
        assert screen.given == {"ball_stops": "yes"}
        assert _status(screen) == ("ball_rolls_top happened: ball_stops is 'yes', so it was reached; change "
                                   "ball_stops to change it")


async def test_y_n_u_stay_shown_and_working_while_the_past_trials_have_the_focus(tmp_path, monkeypatch):
    monkeypatch.setenv(DATABASE_VARIABLE, str(tmp_path / "trials.sqlite3"))
    async with opened(tmp_path, "t", without=OTHER_AREAS) as (app, pilot):
        screen = app.screen
        screen.choose_scenario(str(load_trial_scenario("simple").source))
        screen.query_one("#events", DataTable).focus()
        await pilot.press("y")
        await pilot.press("tab")  # to the past trials
        await pilot.pause()
        assert app.focused is screen.query_one("#trials", DataTable)
        assert {"y", "n", "u"} <= set(_footer_keys(app)), _footer_keys(app)
        await pilot.press("y", "n")
        assert screen.given == {"ball_rolls": "yes", "ball_hits_domino": "yes", "first_topples": "no"}
        assert "a failure; l logs it" in _status(screen)


async def test_the_screen_opens_on_the_scenario_and_layout_chosen_on_the_assemble_screen(tmp_path, monkeypatch):
    from station.tui.screens.assemble import AssembleScreen

    monkeypatch.setattr(AssembleScreen, "forecast_samples", 4)
    monkeypatch.setattr(AssembleScreen, "simulation_workers", 1)
    monkeypatch.setenv(DATABASE_VARIABLE, str(tmp_path / "trials.sqlite3"))
    others = tuple(a for a in OTHER_AREAS if a != "assemble")
    async with opened(tmp_path, "a", without=others) as (app, pilot):
        app.screen.open_layout(str(load_trial_scenario("simple").source), "failure")
        await settle(app, pilot)
        assert app.screen.job is not None
        await pilot.press("escape", "t")
        await settle(app, pilot)
        screen = app.screen
        assert screen.name == "trials"
        assert screen.scenario.name == "SIMPLE" and screen.query_one("#layout", Input).value == "failure"
        # a scenario picked here is kept until another is chosen on the Assemble screen
        screen.choose_scenario(str(load_trial_scenario("ballrun").source))
        await pilot.press("escape", "t")
        await settle(app, pilot)
        assert screen.scenario.name == "BALLRUN"
        await pilot.press("escape", "a")
        await pilot.pause()
        app.screen.open_layout(str(load_trial_scenario("simple").source), "success")
        await settle(app, pilot)
        await pilot.press("escape", "t")
        await settle(app, pilot)
        assert screen.scenario.name == "SIMPLE" and screen.query_one("#layout", Input).value == "success"
