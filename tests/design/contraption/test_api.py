"""The public API the robust-layout helper builds on, exercised on SIMPLE."""

from __future__ import annotations

import numpy as np
import pytest

from design.contraption import (
    SUCCESS,
    LayoutError,
    Simulator,
    check_validity,
    load_scenario,
    simulate,
)
from design.contraption.bullet import direct_client


def test_design_space_names_order_and_bounds(simple):
    space = simple.design_space
    assert space.names == ("track.x", "track.z", "track.roll")
    assert space.dim == 3
    np.testing.assert_allclose(space.lower, [-0.15, 0.0, 15.0])
    np.testing.assert_allclose(space.upper, [0.0, 0.15, 75.0])


def test_normalization_round_trip(simple):
    space = simple.design_space
    rng = np.random.default_rng(0)
    u = rng.random((20, 3))
    x = space.from_normalized(u)
    assert np.all(x >= space.lower) and np.all(x <= space.upper)
    np.testing.assert_allclose(space.to_normalized(x), u, atol=1e-12)
    np.testing.assert_allclose(space.to_normalized(space.lower), 0.0)
    np.testing.assert_allclose(space.to_normalized(space.upper), 1.0)


def test_wrong_layout_length_and_out_of_range_are_layout_errors(simple):
    with pytest.raises(LayoutError, match="expected 3 values"):
        simple.design_space.to_normalized([0.0, 0.1])
    with pytest.raises(LayoutError, match=r"track.roll = 80 is outside its range \[15, 75\]"):
        simulate(simple, [-0.06, 0.06, 80.0])


def test_content_hash_is_stable_and_ignores_layouts(simple, scenarios_dir, tmp_path):
    again = load_scenario(scenarios_dir / "simple.toml")
    assert simple.content_hash == again.content_hash
    assert len(simple.content_hash) == 64
    text = (scenarios_dir / "simple.toml").read_text()
    no_layouts = text[: text.index("[layouts.success]")]
    (tmp_path / "a.toml").write_text(no_layouts)
    assert load_scenario(tmp_path / "a.toml").content_hash == simple.content_hash
    (tmp_path / "b.toml").write_text(no_layouts.replace("friction = 0.504", "friction = 0.5"))
    assert load_scenario(tmp_path / "b.toml").content_hash != simple.content_hash


def test_events_in_file_order(simple):
    assert simple.events == ("ball_rolls", "ball_hits_domino", "first_topples", "last_topples", "last_stops")


def test_success_layout_succeeds_with_every_event(simple):
    x = simple.layout("success")
    assert check_validity(simple, x) == []
    result = simulate(simple, x)
    assert result.success
    assert result.n_successful_events == 5
    assert all(o.state == SUCCESS for o in result.events.values())
    times = [result.events[name].time for name in simple.events]
    assert times == sorted(times)
    assert result.steps == round(result.duration / simple.settings.time_step)


def test_failure_layout_fails_at_the_contact(simple):
    result = simulate(simple, simple.layout("failure"))
    assert not result.success
    states = result.states()
    assert states["ball_rolls"] == "success"
    assert states["ball_hits_domino"] == "failure"
    assert states["last_stops"] == "asleep"
    # Timeout 2 s after waking.
    woke = result.events["ball_hits_domino"].woke
    assert result.events["ball_hits_domino"].time == pytest.approx(woke + 2.0, abs=0.003)


def test_deterministic_across_runs_and_clients(simple):
    x = np.array([-0.1, 0.09, 40.0])
    first = simulate(simple, x)
    with Simulator(simple) as sim:
        runs = [sim.run(x) for _ in range(2)]
    other = simulate(simple, x, client=direct_client())
    for result in [*runs, other]:
        assert result.events == first.events
        assert result.steps == first.steps
        assert result.success == first.success


def test_simulator_reuses_one_client(simple):
    with Simulator(simple) as sim:
        client = sim.client
        labels = [sim.run(x).success for x in (simple.layout("success"), simple.layout("failure"))]
        assert sim.client is client
    assert labels == [True, False]


def test_early_stop_gives_same_label_in_fewer_steps(simple):
    for name in ("success", "failure"):
        x = simple.layout(name)
        fast = simulate(simple, x)
        full = simulate(simple, x, early_stop=False)
        assert fast.success == full.success
        assert fast.events == full.events
        assert fast.steps < full.steps == round(simple.settings.max_duration / simple.settings.time_step)
