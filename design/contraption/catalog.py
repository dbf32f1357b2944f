"""The example scenarios shipped in ``examples/scenarios`` and how to name them on a command line."""

from __future__ import annotations

from pathlib import Path

from design.contraption.errors import ScenarioNotFoundError

#: The repository's example scenarios (a source checkout; installed copies look here too).
EXAMPLES_DIR = Path(__file__).resolve().parents[2] / "examples" / "scenarios"


def example_names() -> list[str]:
    """Stems of the example scenario files, sorted."""
    if not EXAMPLES_DIR.is_dir():
        return []
    return sorted(p.stem for p in EXAMPLES_DIR.iterdir() if p.suffix in (".toml", ".json"))


def resolve_scenario_path(text: str) -> Path:
    """A path as given if it exists, else an example by name (``simple``, ``ballrun``...).

    Raises
    ------
    ScenarioNotFoundError
        When ``text`` is neither; its message lists the examples (a typo of a name is the usual cause).
    """
    path = Path(text)
    if path.exists():
        return path
    for suffix in (".toml", ".json"):
        candidate = EXAMPLES_DIR / f"{text.lower()}{suffix}"
        if candidate.exists():
            return candidate
    raise ScenarioNotFoundError(text, example_names())


def shown_path(path: str | Path) -> str:
    """How a screen names a scenario file: an example as ``example simple.toml`` (the same wherever the station is
    installed), any other file as given."""
    path = Path(path)
    try:
        if path.resolve().parent == EXAMPLES_DIR:
            return f"example {path.name}"
    except OSError:
        pass
    return str(path)
