"""The thesis scenarios shipped as example files: each has a success and a failure layout that do what they say."""

from __future__ import annotations

import pytest

from design.contraption import check_validity, load_scenario, simulate
from design.contraption.catalog import EXAMPLES_DIR, example_names

EXAMPLES = example_names()


def test_every_thesis_scenario_is_shipped():
    assert {"simple", "branching", "ballrun", "causalityswitch_ball", "causalityswitch_dominoes", "longchain",
            "teapotadventure"} <= set(EXAMPLES)


def _simulate_layout(name: str, layout: str):
    """The example ``name`` and the simulation of its layout ``layout`` (checked valid first)."""
    scenario = load_scenario(EXAMPLES_DIR / f"{name}.toml")
    x = scenario.layout(layout)
    assert check_validity(scenario, x) == []
    return scenario, simulate(scenario, x)


@pytest.mark.parametrize("name", EXAMPLES)
def test_example_success_layout_succeeds(name):
    scenario, result = _simulate_layout(name, "success")
    assert result.success, result.states()
    assert result.n_successful_events == len(scenario.events)


@pytest.mark.parametrize("name", EXAMPLES)
def test_example_failure_layout_fails(name):
    scenario, result = _simulate_layout(name, "failure")
    assert not result.success
    assert any(o.state == "failure" for o in result.events.values()) or result.steps == round(
        scenario.settings.max_duration / scenario.settings.time_step
    )


def test_causality_switch_variants_are_one_contraption_with_two_graphs():
    ball = load_scenario(EXAMPLES_DIR / "causalityswitch_ball.toml")
    dominoes = load_scenario(EXAMPLES_DIR / "causalityswitch_dominoes.toml")
    assert ball.design_space.names == dominoes.design_space.names
    assert [o.name for o in ball.objects] == [o.name for o in dominoes.objects]
    assert ball.layout("success").tolist() == dominoes.layout("failure").tolist()
    assert ball.layout("failure").tolist() == dominoes.layout("success").tolist()
    assert len(ball.events) == 14 and ball.design_space.dim == 4
