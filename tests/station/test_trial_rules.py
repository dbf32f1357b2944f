"""A trial's outcomes follow the causal graph: implied outcomes, refusals naming the event, the graph's order."""

from __future__ import annotations

import pytest

from station.errors import ServiceError
from station.services.trials import load_trial_scenario, parse_outcomes, parse_times
from station.trialformat import check_times, complete_outcomes, goal_reached, scenario_from_content

from .conftest import EXAMPLES


@pytest.fixture(scope="module")
def simple():
    return load_trial_scenario("simple")


@pytest.fixture(scope="module")
def ballrun():
    return load_trial_scenario("ballrun")


def test_a_goal_that_happened_implies_every_event_before_it(simple):
    outcomes = complete_outcomes(simple, {"last_stops": "yes"})
    assert outcomes == dict.fromkeys(simple.events, "yes")
    assert list(outcomes) == list(simple.graph_order)
    assert goal_reached(simple, outcomes)


def test_events_after_one_that_did_not_happen_are_not_reached(simple):
    outcomes = complete_outcomes(simple, {"ball_hits_domino": "no"})
    assert outcomes == {"ball_rolls": "yes", "ball_hits_domino": "no", "first_topples": "not-reached",
                        "last_topples": "not-reached", "last_stops": "not-reached"}
    assert not goal_reached(simple, outcomes)


def test_a_join_of_two_branches_needs_both(ballrun):
    # ball_in_goblet waits for low_plank_leaves AND ball_rolls_bottom: one branch failing leaves it unreached
    given = {"ball_rolls_top": "yes", "ball_hits_plank": "yes", "plank_topples": "yes", "lever_pivots": "no",
             "ball_rolls_bottom": "yes"}
    outcomes = complete_outcomes(ballrun, given)
    assert outcomes["low_plank_leaves"] == outcomes["ball_in_goblet"] == outcomes["ball_stops"] == "not-reached"
    # ...and a branch nobody spoke of, whose parent happened, must be said
    with pytest.raises(ServiceError, match=r"^outcome\.ball_rolls_bottom: missing; its parents happened") as error:
        complete_outcomes(ballrun, {"plank_topples": "yes", "lever_pivots": "no"})
    assert error.value.field == "outcome.ball_rolls_bottom"


@pytest.mark.parametrize(("given", "match"), [
    ({"ball_bounces": "yes"}, r"^outcome\.ball_bounces: unknown event; the scenario SIMPLE has ball_rolls, "),
    ({"ball_rolls": "maybe"}, r"^outcome\.ball_rolls: expected yes, no or not-reached, got 'maybe'"),
    ({"ball_rolls": "not-reached"}, r"^outcome\.ball_rolls: the root event is always reached"),
    ({"ball_rolls": "no", "ball_hits_domino": "yes"},
     r"^outcome\.ball_hits_domino: expected 'not-reached', got 'yes': an event can happen only after its parents; "
     r"it waits for ball_rolls \(all of them\); ball_rolls is 'no'"),
    ({"ball_rolls": "no", "first_topples": "yes"},
     r"^outcome\.first_topples: 'yes' means ball_hits_domino happened before it, but it waits for ball_rolls"),
    ({"ball_hits_domino": "yes", "first_topples": "not-reached"},
     r"^outcome\.first_topples: expected yes or no, got 'not-reached', but it was reached"),
    ({}, r"^outcome\.ball_rolls: missing; the root is always reached"),
])
def test_impossible_outcomes_are_refused_naming_the_event(simple, given, match):
    with pytest.raises(ServiceError, match=match):
        complete_outcomes(simple, given)


def test_command_line_pairs_refuse_twice_a_bad_word_and_a_bad_time():
    assert parse_outcomes(["ball_rolls=yes", " last_stops = no "]) == {"ball_rolls": "yes", "last_stops": "no"}
    with pytest.raises(ServiceError, match=r"^outcome\.ball_rolls: given twice$"):
        parse_outcomes(["ball_rolls=yes", "ball_rolls=no"])
    with pytest.raises(ServiceError, match=r"^outcome\.ball_rolls: expected yes, no or not-reached, got 'Yes!'"):
        parse_outcomes(["ball_rolls=Yes!"])
    with pytest.raises(ServiceError, match=r"^outcome: expected EVENT=yes\|no\|not-reached, got 'ball_rolls'"):
        parse_outcomes(["ball_rolls"])
    assert parse_times(["ball_rolls=0.25"]) == {"ball_rolls": 0.25}
    for bad in ("ball_rolls=-1", "ball_rolls=soon", "ball_rolls=nan", "ball_rolls=inf"):
        with pytest.raises(ServiceError, match=r"^time\.ball_rolls: expected a number of seconds >= 0"):
            parse_times([bad])
    with pytest.raises(ServiceError, match=r"^time\.ball_rolls: given twice"):
        parse_times(["ball_rolls=1", "ball_rolls=2"])


def test_times_only_for_events_that_happened(simple):
    outcomes = complete_outcomes(simple, {"ball_hits_domino": "no"})
    assert check_times(simple, {"ball_rolls": 0.4}, outcomes) == {"ball_rolls": 0.4}
    with pytest.raises(ServiceError, match=r"^time\.ball_hits_domino: a time is for an event that happened; "
                                           r"its outcome is 'no'"):
        check_times(simple, {"ball_hits_domino": 1.0}, outcomes)
    with pytest.raises(ServiceError, match=r"^time\.domino: unknown event"):
        check_times(simple, {"domino": 1.0}, outcomes)


def test_graph_order_puts_parents_first_when_the_file_does_not():
    text = (EXAMPLES / "simple.toml").read_text(encoding="utf-8")
    head, *events = text.split("[[events]]")
    # the file lists the events backwards: children before their parents
    reordered = scenario_from_content(head + "".join("[[events]]" + e.rstrip() + "\n\n" for e in events[::-1]),
                                      "backwards.toml")
    assert reordered.events[0] == "last_stops"
    assert reordered.graph_order == ("ball_rolls", "ball_hits_domino", "first_topples", "last_topples",
                                     "last_stops")
    assert list(complete_outcomes(reordered, {"last_stops": "yes"})) == list(reordered.graph_order)
