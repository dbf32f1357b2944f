"""Tiling a guide over sheets: coverage, overlap, labels, orientation, and refusing an absurd guide."""

from __future__ import annotations

import dataclasses
import itertools

import pytest

from projector.errors import ProjectorError
from projector.samples import sample_guide, tiny_guide
from projector.tiling import PAPERS, column_letters, page_format, sheet_format, tile


def areas(guide):
    """Each page's drawing area on the guide plane."""
    result = []
    for page in guide.pages:
        x0, y0, x1, y1 = page_format(page).drawing_box
        result.append((page.origin_mm[0] + x0, page.origin_mm[1] + y0, page.origin_mm[0] + x1,
                       page.origin_mm[1] + y1))
    return result


def with_extent(extent):
    return dataclasses.replace(tiny_guide(), extent_mm=extent)


@pytest.mark.parametrize("paper", sorted(PAPERS))
@pytest.mark.parametrize("extent", [(0, 0, 10, 10), (-80, -60, 390, 277), (0, 0, 1200, 150), (-500, 0, 0, 900)])
def test_the_sheets_cover_the_extent_and_overlap(paper, extent):
    guide = tile(with_extent(extent), paper)
    boxes = areas(guide)
    # Covered with the 10 mm margin: every point of the grown extent is in some drawing area (checked on a grid).
    u0, v0, u1, v1 = extent[0] - 10, extent[1] - 10, extent[2] + 10, extent[3] + 10
    for k, j in itertools.product(range(21), range(21)):
        u, v = u0 + (u1 - u0) * k / 20, v0 + (v1 - v0) * j / 20
        assert any(b[0] - 1e-6 <= u <= b[2] + 1e-6 and b[1] - 1e-6 <= v <= b[3] + 1e-6 for b in boxes)
    columns = len({p.label.rstrip("0123456789") for p in guide.pages})
    for page, box in zip(guide.pages, boxes):
        assert page.paper == paper and sorted(page.size_mm) == sorted(PAPERS[paper])
        row, column = divmod(page.index, columns)
        assert page.label == f"{column_letters(column)}{row + 1}"
        if column + 1 < columns:  # the right neighbour's area starts 15 mm before this one's ends, same rows
            right = boxes[page.index + 1]
            assert box[2] - right[0] == pytest.approx(15.0) and right[1] == pytest.approx(box[1])
        if page.index + columns < len(boxes):  # the row below (reading order: rows go down the plane)
            below = boxes[page.index + columns]
            assert below[3] - box[1] == pytest.approx(15.0) and below[0] == pytest.approx(box[0])


def test_sheets_are_centred_on_the_extent():
    guide = tile(with_extent((0, 0, 10, 10)), "a4")
    (box,) = areas(guide)
    assert (box[0] + box[2]) / 2 == pytest.approx(5.0) and (box[1] + box[3]) / 2 == pytest.approx(5.0)


def test_the_orientation_needing_fewer_sheets_is_chosen():
    wide = tile(with_extent((0, 0, 400, 120)), "a4")
    assert {p.size_mm for p in wide.pages} == {(297.0, 210.0)} and len(wide.pages) == 2  # portrait would need 3
    tall = tile(with_extent((0, 0, 120, 400)), "a4")
    assert {p.size_mm for p in tall.pages} == {(210.0, 297.0)} and len(tall.pages) == 2
    forced = tile(with_extent((0, 0, 120, 400)), "a4", orientation="landscape")
    assert {p.size_mm for p in forced.pages} == {(297.0, 210.0)} and len(forced.pages) == 3


def test_the_sample_guide_takes_six_a4_sheets_labelled_like_a_map():
    guide = tile(sample_guide(), "a4")
    assert [p.label for p in guide.pages] == ["A1", "B1", "C1", "A2", "B2", "C2"]
    assert [p.index for p in guide.pages] == list(range(6))
    assert guide.manifest()["pages"][4] == {"index": 4, "label": "B2", "paper": "a4", "size_mm": [210.0, 297.0],
                                            "origin_mm": list(guide.pages[4].origin_mm)}


def test_an_absurd_guide_is_refused_with_its_extent_and_what_to_do():
    with pytest.raises(ProjectorError) as error:
        tile(with_extent((0, 0, 3000, 2000)), "a4")
    message = str(error.value)
    assert "extent is 3000 x 2000 mm" in message and "at most 60" in message and "--paper a3" in message
    assert "\n" not in message
    assert len(tile(with_extent((0, 0, 3000, 2000)), "a3", max_sheets=100).pages) <= 100


@pytest.mark.parametrize(("call", "message"), [
    (lambda: tile(tiny_guide(), "a5"), "paper: expected one of a4, letter, a3, got 'a5'"),
    (lambda: tile(tiny_guide(), "a4", orientation="sideways"), "orientation: expected portrait or landscape"),
    (lambda: tile(tiny_guide(), "a4", overlap_mm=-3), "overlap_mm: expected a number of millimetres from 0 to 50"),
    (lambda: tile(with_extent((0, 0, float("nan"), 1)), "a4"), "guide extent_mm: expected (u_min, v_min, u_max"),
    (lambda: tile(with_extent((5, 0, 1, 1)), "a4"), "guide extent_mm: expected"),
])
def test_bad_input_is_one_line(call, message):
    with pytest.raises(ProjectorError) as error:
        call()
    assert str(error.value).startswith(message)


def test_column_letters():
    assert [column_letters(i) for i in (0, 1, 25, 26, 27, 51, 52)] == ["A", "B", "Z", "AA", "AB", "AZ", "BA"]


def test_sheet_format_leaves_room_for_the_footer():
    fmt = sheet_format("letter", "landscape")
    assert fmt.size_mm == (279.4, 215.9)
    x0, y0, x1, y1 = fmt.drawing_box
    assert (x0, x1, y1) == (10.0, 269.4, 205.9) and y0 > 30.0
