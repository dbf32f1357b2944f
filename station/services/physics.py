"""Physics profiles as a service: read one named by ``--physics`` and apply it to a scenario or a layout problem.

Used by ``station simulate``, ``optimize``, ``robustness``, ``compare``, ``guide``, ``tolerances``, ``predict`` and
(wired by the lead) ``check``. A profile's values replace those of the scenario's materials it names (see
:mod:`design.contraption.physics_profile`); the simulations then have another content hash, so nothing cached for
the scenario's own values is reused for the profile's.
"""

from __future__ import annotations

from pathlib import Path

from design.contraption.physics_profile import PhysicsProfile, apply_profile, load_profile
from design.contraption.scenario import Scenario
from station.errors import ServiceError, station_errors


@station_errors
def read_profile(path: str | Path) -> PhysicsProfile:
    """The physics profile at ``path``; a missing file is a :class:`ServiceError` naming ``physics``.

    A malformed file raises :class:`~design.contraption.physics_profile.PhysicsProfileError` (file, field,
    expectation).
    """
    path = Path(path)
    if not path.is_file():
        raise ServiceError(f"physics profile {path}: no such file (expected a .toml physics profile, e.g. the --out "
                           "of `station calibrate sim`)", field="physics", value=str(path))
    return load_profile(path)


@station_errors
def scenario_with_physics(scenario: Scenario, path: str | Path | None) -> Scenario:
    """``scenario`` under the profile at ``path`` (``scenario`` itself when ``path`` is None)."""
    if path is None:
        return scenario
    return apply_profile(scenario, read_profile(path), str(path))


@station_errors
def problem_with_physics(problem, path: str | Path | None):
    """A robust-layout problem of a scenario file under the profile at ``path`` (``problem`` itself when None).

    Only a scenario's problem (:class:`~design.robust.contraption.ContraptionProblem`) has materials; another one
    (a synthetic problem of the tests) with a profile is refused.
    """
    if path is None:
        return problem
    from design.robust.contraption import ContraptionProblem  # heavy: pybullet, scipy

    if not isinstance(problem, ContraptionProblem):
        raise ServiceError(f"{problem.name}: has no materials; a physics profile applies to a scenario file",
                           field="physics", value=str(path))
    return ContraptionProblem(problem.path, scenario_with_physics(problem.scenario, path))


@station_errors
def physics_note(scenario: Scenario) -> str | None:
    """What a command says about the physics it simulated: None for the scenario's own values."""
    if not scenario.physics_overrides:
        return None
    values = ", ".join(f"{k} = {v:g}" for k, v in scenario.physics_overrides.items())
    return f"physics: {values} (profile)"
