"""Chain-reaction contraptions as a service: load a scenario, choose a layout, simulate it, check it, render it.

Used by ``station simulate``, ``station scenario check`` and the Contraptions screen. Scenario and layout files
are read by :mod:`design.contraption` (a bad one is a :class:`~design.contraption.errors.ScenarioFormatError`
naming the file, the field and what was expected).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from common.progress import Reporter
from design.contraption.catalog import EXAMPLES_DIR, resolve_scenario_path
from design.contraption.catalog import example_names as catalog_examples
from design.contraption.catalog import shown_path as catalog_shown_path
from design.contraption.layout_io import LoadedLayout, default_layout, resolve_layout, values_layout
from design.contraption.scenario import Scenario, load_scenario
from station.errors import station_errors
from station.services.physics import scenario_with_physics

if TYPE_CHECKING:  # pybullet loads only when something is simulated
    from design.contraption.simulation import SimulationResult, ValidityProblem
    from design.contraption.world import World

#: Called after each change of the events' states: simulated time, every event's state, the world (to draw it).
StateCallback = Callable[[float, dict[str, str], "World"], None]


@station_errors
def example_names() -> list[str]:
    """The scenarios shipped as examples: a face may name one instead of a file."""
    return catalog_examples()


@station_errors
def example_files() -> list[tuple[str, Path]]:
    """(name, file) of each example scenario, in :func:`example_names`'s order (a face offers them to choose)."""
    files = []
    for name in catalog_examples():
        found = next((EXAMPLES_DIR / f"{name}{suffix}" for suffix in (".toml", ".json")
                      if (EXAMPLES_DIR / f"{name}{suffix}").exists()), None)
        if found is not None:
            files.append((name, found))
    return files


@station_errors
def shown_path(path: str | Path) -> str:
    """How a face names a scenario file: an example as ``example simple.toml``, any other file as given."""
    return catalog_shown_path(path)


@station_errors
def open_scenario(text: str, physics: str | Path | None = None) -> Scenario:
    """A scenario by file path or example name (``simple``, ``ballrun``...), validated; under the physics profile
    at ``physics`` when given (:mod:`station.services.physics`).

    Raises
    ------
    design.contraption.errors.ScenarioNotFoundError
        Neither a file nor an example.
    design.contraption.errors.ScenarioFormatError
        The file is malformed (the message names the file, the field and what was expected).
    """
    scenario = load_scenario(resolve_scenario_path(text))
    if physics is None:
        return scenario

    return scenario_with_physics(scenario, physics)


@station_errors
def choose_layout(scenario: Scenario, *, values: list[float] | None = None, layout: str | None = None,
                  what: str = "values") -> LoadedLayout:
    """The layout to simulate: ``values`` in design-space order (``what`` names where they came from in messages),
    else ``layout`` (a layout file or a layout named in the scenario), else the scenario's own transforms."""
    if values is not None:
        return values_layout(scenario, values, what=what)
    if layout is not None:
        return resolve_layout(layout, scenario)
    return default_layout(scenario)


@station_errors
@dataclass
class SimulationOutcome:
    """One simulated layout: the physical problems that stopped it, or the causal graph's result.

    Attributes
    ----------
    scenario : Scenario
    x : ndarray
        The layout's values (real units, design-space order).
    problems : list of ValidityProblem
        Why the layout is physically impossible; empty for a valid one (then ``result`` is set).
    result : SimulationResult or None
        The run's outcome, None when the layout was impossible.
    """

    scenario: Scenario
    x: np.ndarray
    problems: list[ValidityProblem] = field(default_factory=list)
    result: SimulationResult | None = None

    @property
    def valid(self) -> bool:
        return not self.problems

    @property
    def success(self) -> bool:
        return self.result is not None and self.result.success

    def to_dict(self, layout: LoadedLayout | None = None) -> dict[str, Any]:
        """What ``station simulate --json`` prints; ``layout`` adds where the layout came from."""
        data: dict[str, Any] = {"scenario": self.scenario.name, "valid": self.valid}
        if not self.valid:
            data["success"] = False
        data["layout"] = self.scenario.design_space.as_dict(self.x)
        if layout is not None:
            data["layout_source"] = layout.to_dict()
        if self.scenario.physics_overrides:
            data["physics"] = dict(self.scenario.physics_overrides)
        if not self.valid:
            data["problems"] = [{"kind": p.kind, "objects": list(p.objects), "amount": p.amount, "message": p.message}
                                for p in self.problems]
            return data
        return {**data, **self.result.to_dict()}


@station_errors
def simulate(scenario: Scenario, x: np.ndarray, *, early_stop: bool = True, record: bool = False,
             on_change: StateCallback | None = None, report: Reporter | None = None,
             client=None) -> SimulationOutcome:
    """Check a layout's physical validity, then simulate it under the causal graph.

    Parameters
    ----------
    scenario, x
        The scenario and the layout's values (see :func:`choose_layout`).
    early_stop : bool
        Stop once the causal graph's outcome is known (else run to the scenario's max duration).
    record : bool
        Keep the start and end states (for :func:`render` or a picture of the end).
    on_change : callable, optional
        ``on_change(t, states, world)`` after each change of the events' states (the TUI animates with it).
    report : Reporter, optional
        Told once, stage ``"simulate"`` (no total), when a valid layout starts to run.
    client : pybullet client, optional
        One to reuse (the TUI keeps one); a new one by default.
    """
    from design.contraption.simulation import Simulator  # pybullet: loaded only when a layout is simulated

    report = Reporter.of(report)
    with Simulator(scenario, client=client) as sim:
        problems = sim.check_validity(x)
        if problems:
            return SimulationOutcome(scenario, x, list(problems))
        report("simulate", 0, None,
               f"simulating {scenario.name} ({len(scenario.objects)} objects, {len(scenario.events)} events)...")
        hook = None if on_change is None else (lambda t, states: on_change(t, states, sim.world))
        result = sim.run(x, early_stop=early_stop, record=record, on_change=hook)
    return SimulationOutcome(scenario, x, [], result)


@station_errors
def render(outcome: SimulationOutcome, path: str | Path) -> Path:
    """Top and side views at the start and the end of a recorded run (``record=True``), as a PNG."""
    from design.contraption.render import render_result  # heavy: PIL, scipy

    render_result(outcome.scenario, outcome.result, str(path))
    return Path(path)


# -- what a face draws of a world ---------------------------------------------------------------------------------
@station_errors
def physics_client():
    """A pybullet client without a window, for a face to keep across its simulations (they run one at a time)."""
    from design.contraption.bullet import direct_client  # pybullet: loaded only when something is simulated

    return direct_client()


@station_errors
def world_ropes(world: World) -> list[np.ndarray]:
    """Each rope's path now (end, guides, end) as an (n, 3) array."""
    return [np.asarray(world.rope_path(rope)[0]) for rope in world.ropes]


@station_errors
def layout_view(scenario: Scenario, x: np.ndarray, client=None) -> tuple[list, list[np.ndarray]]:
    """The bodies of ``scenario`` built at layout ``x``, before anything moves: the world's snapshot (label, name,
    pose, spec of each body) and the ropes' paths."""
    from design.contraption.simulation import Simulator  # pybullet: loaded only when something is simulated

    with Simulator(scenario, client=client) as sim:
        world = sim.build(x)
        return world.snapshot(), world_ropes(world)


@station_errors
def side_view(scenario: Scenario, snapshot, ropes=()) -> list[tuple[str, np.ndarray]]:
    """A side view (x, z) of a world's snapshot: each body part's closed outline with its object's primitive type
    (``"Ball"``, ``"Track"``...; "" for a body of no object), then each rope's path with the type ``"rope"``."""
    from scipy.spatial import ConvexHull, QhullError  # scipy: loaded when a view is drawn, not for --help

    kinds = {o.name: o.type for o in scenario.objects}
    view = []
    for _label, name, pose, spec in snapshot:
        for part in spec.parts:
            if part.kind == "plane":
                continue
            points = pose.apply(part.surface_points(16))[:, [0, 2]]
            try:
                hull = points[ConvexHull(points).vertices]
            except QhullError:
                hull = points[[np.argmin(points[:, 0]), np.argmax(points[:, 0])]]
            view.append((kinds.get(name, ""), np.vstack([hull, hull[:1]])))
    view.extend(("rope", np.asarray(path, dtype=float)[:, [0, 2]]) for path in ropes)
    return view


@station_errors
def scenario_summary(scenario: Scenario) -> dict[str, Any]:
    """What ``station scenario check --json`` prints: objects, causal graph, design space, named layouts."""
    space = scenario.design_space
    return {
        "scenario": scenario.name,
        "file": scenario.source,
        "valid": True,
        "content_hash": scenario.content_hash,
        "objects": [{"name": o.name, "type": o.type, "parent": o.parent} for o in scenario.objects],
        "events": [
            {"name": e.name, "type": e.type, "after": list(e.after), "join": e.join, "label": e.label}
            for e in scenario.event_specs
        ],
        "design_space": [
            {"name": n, "lower": lo, "upper": hi, "default": d}
            for n, lo, hi, d in zip(space.names, space.lower, space.upper, space.default)
        ],
        "layouts": {k: space.as_dict(v) for k, v in scenario.layouts.items()},
    }
