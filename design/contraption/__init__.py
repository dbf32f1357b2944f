"""Chain-reaction contraptions (thesis chapter 4): scenario files, primitives, events, causal-graph supervision.

Public API (used by the robust-layout helper and the station)::

    from design.contraption import load_scenario, simulate, check_validity, Simulator
    scenario = load_scenario("examples/scenarios/simple.toml")
    space = scenario.design_space          # .names .lower .upper .dim .to_normalized() .from_normalized()
    scenario.content_hash                  # sha256 of the canonical content (cache key)
    scenario.events                        # event names, file order
    scenario.uncertain_parameters()        # {"wood.friction": (0.6, (0.3, 0.9))}: what simulator calibration fits
    with_physics(scenario, {"wood.friction": 0.42})  # other material values (validated; another content hash)
    problems = check_validity(scenario, x) # [] means physically valid
    clearances(scenario, x)                # signed margins per close pair / rope (>= 0: valid), for optimizers
    layout = resolve_layout("success", scenario)   # or a file: LAYOUT.json, {"x": [...]}, {"parameters": {...}}
    layout.x, layout.describe(), layout.defaulted  # values (real units), where they came from, what was defaulted
    result = simulate(scenario, x)         # .success .n_successful_events .events[name].state/.time .duration .steps
    with Simulator(scenario) as sim:       # one pybullet DIRECT client reused across many runs
        results = [sim.run(x) for x in layouts]
"""

from design.lazy import lazy_exports

# Names are imported on first use (PEP 562), so ``design.contraption.catalog`` or ``.errors`` can be imported
# without pybullet and scipy: the CLI builds its parser (and answers --help) without loading the simulator.
_SOURCES = {
    "errors": ("LayoutError", "ScenarioFormatError", "ScenarioNotFoundError", "SimulationError"),
    "layout_io": ("LoadedLayout", "layout_from_data", "load_layout", "read_layout", "resolve_layout"),
    "scenario": (
        "EVENTS", "PRIMITIVES", "DesignSpace", "EventSpec", "ObjectSpec", "Scenario", "Settings", "Transform",
        "load_scenario", "scenario_from_data", "with_physics",
    ),
    "simulation": (
        "ASLEEP", "AWAKE", "FAILURE", "SUCCESS", "Clearance", "EventOutcome", "SimulationResult", "Simulator",
        "ValidityProblem", "check_validity", "clearances", "simulate",
    ),
}
__getattr__, __dir__, _MODULE_OF = lazy_exports(__name__, _SOURCES)

__all__ = [
    "ASLEEP",
    "AWAKE",
    "EVENTS",
    "FAILURE",
    "PRIMITIVES",
    "SUCCESS",
    "Clearance",
    "DesignSpace",
    "EventOutcome",
    "EventSpec",
    "LayoutError",
    "LoadedLayout",
    "ObjectSpec",
    "Scenario",
    "ScenarioFormatError",
    "ScenarioNotFoundError",
    "Settings",
    "SimulationError",
    "SimulationResult",
    "Simulator",
    "Transform",
    "ValidityProblem",
    "check_validity",
    "clearances",
    "layout_from_data",
    "load_layout",
    "load_scenario",
    "read_layout",
    "resolve_layout",
    "scenario_from_data",
    "simulate",
    "with_physics",
]
