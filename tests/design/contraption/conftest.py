"""Shared fixtures of the contraption tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from design.contraption import load_scenario

SCENARIOS = Path(__file__).resolve().parents[3] / "examples" / "scenarios"


@pytest.fixture(scope="session")
def scenarios_dir() -> Path:
    return SCENARIOS


@pytest.fixture(scope="session")
def simple():
    return load_scenario(SCENARIOS / "simple.toml")
