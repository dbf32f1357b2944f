"""Physics profiles: versioned TOML read and written, applied with --physics on the commands that simulate."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from design.contraption import load_scenario
from design.contraption.physics_profile import (
    PhysicsProfile,
    PhysicsProfileError,
    apply_profile,
    load_profile,
    profile_from_text,
    save_profile,
)
from station.cli import main

SLIDE = Path(__file__).resolve().parents[2] / "data" / "calibration" / "slide.toml"
HEADER = '[profile]\nformat = "chaos-station physics"\nversion = 1\nname = "p"\n'


def test_round_trip(tmp_path):
    profile = PhysicsProfile("wood", {"wood.friction": 0.42, "steel.restitution": 0.7},
                             {"wood.friction": (0.4, 0.44)}, "2026-12-03T12:00:00Z", "calibrate sim: 34 trials",
                             {"trials": 34, "brier_before": 0.2, "brier_after": 0.1})
    path = save_profile(profile, tmp_path / "wood.toml")
    assert load_profile(path) == profile
    assert "[profile]" in path.read_text() and not (tmp_path / "wood.toml.tmp").exists()


@pytest.mark.parametrize(("text", "message"), [
    ('[profile]\nformat = "other"\nversion = 1\n[values]\n"wood.friction" = 0.5\n',
     'p.toml: profile.format: expected "chaos-station physics", got text'),
    ('[profile]\nformat = "chaos-station physics"\nversion = 2\n[values]\n"wood.friction" = 0.5\n',
     "p.toml: profile.version: expected 1"),
    (HEADER + '[values]\n"wood.fric" = 0.5\n', 'p.toml: values."wood.fric": expected a name MATERIAL.PARAM'),
    (HEADER + '[values]\n"wood.friction" = -0.5\n', 'p.toml: values."wood.friction": expected a number >= 0'),
    (HEADER + '[values]\n"wood.friction" = 0.5\n[intervals]\n"wood.friction" = [0.6, 0.7]\n',
     'p.toml: intervals."wood.friction": expected [low, high] around the value 0.5'),
    (HEADER, "p.toml: values: missing"),
    ("[profile\n", "p.toml: not valid TOML"),
])
def test_bad_profiles_are_one_line(text, message):
    with pytest.raises(PhysicsProfileError) as error:
        profile_from_text(text, "p.toml")
    assert str(error.value).startswith(message) and "\n" not in str(error.value)


def test_apply_sets_the_scenarios_materials_and_refuses_another_contraptions():
    slide = load_scenario(SLIDE)
    applied = apply_profile(slide, PhysicsProfile("p", {"wood.friction": 0.7, "rubber.restitution": 0.5}))
    assert applied.object("plank").physics.friction == 0.7
    assert applied.physics_overrides == {"wood.friction": 0.7}
    with pytest.raises(PhysicsProfileError, match="none of its values .rubber.restitution. is a material value"):
        apply_profile(slide, PhysicsProfile("p", {"rubber.restitution": 0.5}), "p.toml")
    with pytest.raises(PhysicsProfileError, match=r'p.toml: physics."wood.friction": expected a value inside'):
        apply_profile(slide, PhysicsProfile("p", {"wood.friction": 0.95}), "p.toml")


def test_simulate_with_physics(tmp_path, capsys):
    """At a 31 degree tilt the block slides off the plank with the file's friction 0.5, not with 0.6."""
    layout = tmp_path / "tilt.json"
    layout.write_text(json.dumps({"parameters": {"plank.roll": 31.0}}))
    assert main(["simulate", str(SLIDE), "--layout", str(layout), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["success"] is True
    profile = tmp_path / "sticky.toml"
    profile.write_text(HEADER + '[values]\n"wood.friction" = 0.6\n')
    assert main(["simulate", str(SLIDE), "--layout", str(layout), "--json", "--physics", str(profile)]) == 1
    captured = capsys.readouterr()
    data = json.loads(captured.out)
    assert data["success"] is False and data["physics"] == {"wood.friction": 0.6}
    assert "physics: wood.friction = 0.6 (profile)" in captured.err


def test_bad_physics_option_is_one_line(tmp_path, capsys):
    assert main(["simulate", str(SLIDE), "--physics", str(tmp_path / "none.toml")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("station: error: physics profile") and "no such file" in err and "\n" not in err
    bad = tmp_path / "bad.toml"
    bad.write_text(HEADER + '[values]\n"oak.friction" = 0.6\n')
    assert main(["simulate", str(SLIDE), "--physics", str(bad)]) == 2
    assert "none of its values (oak.friction) is a material value of 'SLIDE'" in capsys.readouterr().err


@pytest.mark.parametrize("command", ["optimize", "robustness", "compare", "guide", "tolerances", "predict"])
def test_the_simulating_commands_take_physics(command, capsys):
    with pytest.raises(SystemExit):
        main([command, "--help"])
    assert "--physics PROFILE.toml" in capsys.readouterr().out


def test_a_profile_says_the_contraptions_it_was_fitted_on(tmp_path):
    profile = PhysicsProfile("simple wood", {"wood.friction": 0.42}, scenarios=("SIMPLE", "BALLRUN"))
    path = save_profile(profile, tmp_path / "both.toml")
    assert 'scenarios = ["SIMPLE", "BALLRUN"]' in path.read_text()
    assert load_profile(path) == profile
    assert load_profile(save_profile(PhysicsProfile("hand", {"wood.friction": 0.4}), tmp_path / "hand.toml")) \
        .scenarios == ()
    with pytest.raises(PhysicsProfileError) as error:
        profile_from_text(HEADER + 'scenarios = "SIMPLE"\n[values]\n"wood.friction" = 0.5\n', "p.toml")
    assert str(error.value).startswith('p.toml: profile.scenarios: expected a list of scenario names')


def test_a_profile_of_another_contraption_is_refused_by_name_not_by_a_range():
    # SLIDE's wood is not SIMPLE's: a SIMPLE profile is refused even where its values would fit SLIDE's ranges.
    slide = load_scenario(SLIDE)
    simple_wood = PhysicsProfile("calibrated SIMPLE", {"wood.friction": 0.5}, scenarios=("SIMPLE",))
    with pytest.raises(PhysicsProfileError) as error:
        apply_profile(slide, simple_wood, "simple-physics.toml")
    assert str(error.value) == ("simple-physics.toml: profile.scenarios: a profile for another contraption (SIMPLE); "
                                "expected one fitted on SLIDE's trials (`station calibrate sim --out`)")
    both = PhysicsProfile("p", {"wood.friction": 0.7}, scenarios=("SIMPLE", "slide"))
    assert apply_profile(slide, both).physics_overrides == {"wood.friction": 0.7}
    assert apply_profile(slide, PhysicsProfile("hand", {"wood.friction": 0.7})).physics_overrides == {
        "wood.friction": 0.7}
