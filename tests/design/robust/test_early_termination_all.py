"""Early termination gives the label of the full run, on every shipped scenario (not only SIMPLE).

The optimizer labels every layout with a simulation that stops at termination (design/contraption/simulation.py,
thesis 4.3): global success once every leaf event has succeeded, global failure once a leaf no longer can. The
module promises the label of a run to ``max_duration`` ("by construction").
tests/design/contraption/test_api.py checks it on SIMPLE, a plain chain; here every scenario of examples/scenarios,
with its branches, OR-joins and duration events.

Cost: two layouts per scenario (its named success and failure layouts), each simulated twice: about 45 s of CPU
(0.3 s for SIMPLE to 9 s for longchain). The four long scenarios, and three seeded valid layouts more per scenario,
are marked slow (``pytest -m slow``).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from design.contraption import load_scenario
from design.contraption.simulation import FAILURE, SUCCESS, simulate

SCENARIOS = sorted((Path(__file__).resolve().parents[3] / "examples" / "scenarios").glob("*.toml"))


def decided_by(scenario, events) -> bool | None:
    """The module's termination rule, applied to final event outcomes: True when every leaf succeeded, False when a
    leaf can no longer succeed (it failed, or it sleeps behind a failed AND-parent or behind failed OR-parents)."""
    specs = {spec.name: spec for spec in scenario.event_specs}
    leaves = [name for name in specs if not any(name in other.after for other in specs.values())]

    def hopeless(name: str) -> bool:
        state, spec = events[name].state, specs[name]
        if state == FAILURE:
            return True
        if state != "asleep" or not spec.after:
            return False
        parents = [hopeless(parent) for parent in spec.after]
        return any(parents) if spec.join == "all" else all(parents)

    if all(events[leaf].state == SUCCESS for leaf in leaves):
        return True
    if any(hopeless(leaf) for leaf in leaves):
        return False
    return None


def assert_same_label_as_the_full_run(scenario, x) -> bool:
    """Simulate ``x`` with and without early termination and compare; returns the label."""
    fast = simulate(scenario, x)
    full = simulate(scenario, x, early_stop=False)
    n_steps = round(scenario.settings.max_duration / scenario.settings.time_step)
    assert full.steps == n_steps and not full.early_stopped
    assert fast.success == full.success
    # It stopped because the label was decided (by the rule, on what it had seen), at the step that decided it.
    assert fast.early_stopped and fast.steps < n_steps
    assert decided_by(scenario, fast.events) is fast.success
    assert fast.timeline[-1][0] == pytest.approx(fast.duration)
    # Up to the stop, the two runs are the same run: same timeline, and every event decided by then has the same
    # outcome (time included) at the end of the full run. Only the undecided ones go on.
    assert full.timeline[: len(fast.timeline)] == fast.timeline
    decided = {name: o for name, o in fast.events.items() if o.state in (SUCCESS, FAILURE)}
    assert decided, "early termination with no event decided"
    assert {name: full.events[name] for name in decided} == decided
    return fast.success


#: Scenarios whose named layouts take 8-9 s each to simulate twice: run under -m slow to keep the default suite
#: within its time. SIMPLE, BRANCHING and BALLRUN stay in it (a chain, an AND-join with branches, a thrown plank).
LONG = {"longchain", "causalityswitch_ball", "causalityswitch_dominoes", "teapotadventure"}


@pytest.mark.parametrize("path", [pytest.param(p, marks=pytest.mark.slow) if p.stem in LONG else p for p in SCENARIOS],
                         ids=[p.stem for p in SCENARIOS])
def test_early_termination_keeps_the_label_of_the_named_layouts(path):
    scenario = load_scenario(path)
    assert {"success", "failure"} <= set(scenario.layouts), f"{path.name}: no success and failure layouts to check"
    assert assert_same_label_as_the_full_run(scenario, scenario.layout("success")) is True
    assert assert_same_label_as_the_full_run(scenario, scenario.layout("failure")) is False


@pytest.mark.slow
@pytest.mark.parametrize("path", SCENARIOS, ids=[p.stem for p in SCENARIOS])
def test_early_termination_keeps_the_label_of_seeded_valid_layouts(path):
    from design.robust.contraption import load_problem
    from design.robust.sampling import sobol_valid

    scenario = load_scenario(path)
    problem = load_problem(path)
    for u in sobol_valid(problem, 3, seed=0):
        assert_same_label_as_the_full_run(scenario, problem.to_real(u))


def test_every_shipped_scenario_is_checked():
    assert len(SCENARIOS) >= 7 and any(p.stem == "simple" for p in SCENARIOS)
