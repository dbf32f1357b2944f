"""A candidate database's build reports the one common Progress and stops when asked; nothing is printed."""

from __future__ import annotations

import pytest

from common.progress import Cancelled, Progress, Reporter
from design.machines import get_machine
from design.sketch import SketchRetriever, make_sketch
from design.sketch.candidates import DatabaseSettings, build_database, cache_path, load_database, version_key

TINY = DatabaseSettings(max_radius=4, values_per_dimension=2, harmonics=24, points=128)


def test_build_reports_grid_then_curves_as_common_progress(capsys):
    seen: list[Progress] = []
    database = build_database(get_machine("spirograph"), TINY, seen.append)
    assert all(isinstance(p, Progress) for p in seen)
    stages = [p.stage for p in seen]
    assert stages[0] == "grid" and stages[-1] == "curves" and stages == sorted(stages, key=["grid", "curves"].index)
    grid = [p for p in seen if p.stage == "grid"]
    assert [p.done for p in grid] == list(range(1, len(grid) + 1)) and grid[-1].total == len(grid)
    assert seen[-1].done == seen[-1].total == len(database) and seen[-1].fraction == 1.0
    assert seen[-1].message == f"spirograph: curves {len(database)}/{len(database)}"
    assert capsys.readouterr() == ("", "")  # design prints nothing


def test_load_says_it_builds_once_then_reads_the_cache_silently(tmp_path):
    machine = get_machine("spirograph")
    seen: list[Progress] = []
    load_database(machine, tmp_path, TINY, seen.append)
    assert seen[0].stage == "build" and seen[0].total is None and "building candidate database" in seen[0].message
    assert cache_path(tmp_path, "spirograph", version_key(machine, TINY)).exists()
    again: list[Progress] = []
    load_database(machine, tmp_path, TINY, again.append)
    assert again == []


def test_cancel_stops_the_build_and_caches_nothing(tmp_path):
    machine = get_machine("spirograph")
    seen: list[Progress] = []
    with pytest.raises(Cancelled):
        load_database(machine, tmp_path, TINY, Reporter(seen.append, stop=lambda: len(seen) >= 3))
    assert len(seen) == 3
    assert not cache_path(tmp_path, "spirograph", version_key(machine, TINY)).exists()
    # the retriever passes its reporter's stop down to the build
    retriever = SketchRetriever(["spirograph"], cache_dir=tmp_path, settings={"spirograph": TINY},
                                report=Reporter(stop=lambda: True))
    sketch = make_sketch([[(0, 0), (1, 0), (1, 1), (0, 1)]], symmetry=1, source="square")
    with pytest.raises(Cancelled):
        retriever.query(sketch)
