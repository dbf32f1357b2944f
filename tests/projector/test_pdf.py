"""The printed guide, measured on its raster (pypdfium2) and read by a tag detector, not from the drawing code.

What a guide must meet: every page's scale bar measures 100 mm +-0.5 %; the reference tags decode at their manifest
positions +-0.5 mm; overlapping sheets show the same drawing at the same guide-plane point; the last page lists
every part, step and tolerance.
"""

from __future__ import annotations

import io

import numpy as np
import pypdfium2 as pdfium
import pytest
from scipy import ndimage

from projector.errors import ProjectorError
from projector.guide import REFERENCE_TAG_IDS
from projector.pdf import write_pdf
from projector.samples import sample_guide, tiny_guide
from projector.tiling import page_format
from vision.detection import detect_tags

DPI = 200
PX_PER_MM = DPI / 25.4
STEPS = ["1. Lay floor_plank along the bottom edge", "2. Fix support_post", "3. Place top_track: centre (70.0, "
         "170.0) mm, roll -8.0 deg", "4. Place catch_cup", "5. Place lever & <arm>", "6. Stand the domino_run",
         "7. Put the ball on the track last"]


def raster(document, index: int) -> np.ndarray:
    """Page ``index`` rendered grey at DPI, as an array of its own: a bitmap's numpy or PIL view shares the bitmap's
    memory, which pdfium frees with the bitmap."""
    page = document[index]
    bitmap = page.render(scale=DPI / 72, grayscale=True)
    array = bitmap.to_numpy().copy()
    bitmap.close()
    page.close()
    return array


def text(document, index: int) -> str:
    page = document[index]
    textpage = page.get_textpage()
    result = textpage.get_text_range()
    textpage.close()
    page.close()
    return result


@pytest.fixture(scope="module")
def rendered():
    """The sample guide's PDF: its guide with pages, every page as a grey raster at DPI, its text, and the tags a
    detector finds on each page (``{id: (centre, corners)}`` in pixels)."""
    stream = io.BytesIO()
    guide = write_pdf(sample_guide(), stream, paper="a4", steps=STEPS)
    document = pdfium.PdfDocument(stream.getvalue())
    pages = [raster(document, i) for i in range(len(document))]
    texts = [text(document, i) for i in range(len(document))]
    document.close()
    tags = [{t.tag_id: (t.center, t.corners) for t in detect_tags(r)} for r in pages]  # pupil-apriltags
    return guide, pages, texts, tags


def test_one_pdf_page_per_sheet_then_the_lists(rendered):
    guide, pages, _, _ = rendered
    assert len(guide.pages) == 6 and len(pages) == len(guide.pages) + 1
    for page, raster in zip(guide.pages, pages):
        assert raster.shape == (round(page.size_mm[1] * PX_PER_MM), round(page.size_mm[0] * PX_PER_MM))


def scale_bar_mm(raster: np.ndarray) -> float:
    """The length of the widest dark blob in the page's bottom 45 mm (the scale bar, ticks on top of it), in mm.

    Measured to a fraction of a pixel: the ink summed along a row through the bar's body (a grey edge pixel counts
    for the part of it that is black).
    """
    band = raster[-int(45 * PX_PER_MM):]
    labels, _ = ndimage.label(band < 110)
    best = max(ndimage.find_objects(labels), key=lambda sl: sl[1].stop - sl[1].start)
    height = (best[0].stop - best[0].start) / PX_PER_MM
    assert 2.0 <= height <= 5.0, f"the widest dark blob is {height:.1f} mm tall, not a scale bar"
    row = band[best[0].stop - int(1.2 * PX_PER_MM), best[1].start - 3:best[1].stop + 3].astype(float)
    return float(np.sum(1.0 - row / 255.0)) / PX_PER_MM


def test_every_page_has_a_scale_bar_of_100_mm(rendered):
    _, pages, _, _ = rendered
    for raster in pages:
        assert scale_bar_mm(raster) == pytest.approx(100.0, rel=0.005)


def to_guide_mm(page, xy_px) -> np.ndarray:
    """A raster pixel position (x right, y down, pixel edges at integers) as a guide-plane point through the page's
    origin_mm: the sheet point (x, H - y) mm plus origin_mm."""
    x_mm = np.asarray(xy_px)[..., 0] / PX_PER_MM
    y_mm = page.size_mm[1] - np.asarray(xy_px)[..., 1] / PX_PER_MM
    return np.stack([page.origin_mm[0] + x_mm, page.origin_mm[1] + y_mm], axis=-1)


def test_reference_tags_decode_at_their_manifest_positions(rendered):
    guide, _, _, tags = rendered
    manifest = {t["id"]: t for t in guide.manifest()["reference_tags"]}
    assert sorted(manifest) == list(REFERENCE_TAG_IDS)
    seen = {tag_id: 0 for tag_id in manifest}
    for page in guide.pages:
        x0, y0, x1, y1 = page_format(page).drawing_box
        area = (page.origin_mm[0] + x0, page.origin_mm[1] + y0, page.origin_mm[0] + x1, page.origin_mm[1] + y1)
        found = tags[page.index]
        # The parts' tags are marked where they go, but never decodable: the camera must find them on the parts.
        assert set(found) <= set(manifest), f"sheet {page.label} shows a decodable part tag: {sorted(found)}"
        for tag_id, tag in manifest.items():
            (u, v), half = tag["center_mm"], tag["size_mm"] * 0.625  # with its white border
            whole = area[0] <= u - half and u + half <= area[2] and area[1] <= v - half and v + half <= area[3]
            if not whole:
                continue
            assert tag_id in found, f"reference tag {tag_id} is whole on sheet {page.label} but does not decode"
            centre = to_guide_mm(page, found[tag_id][0])
            assert np.abs(centre - [u, v]).max() <= 0.5
            corners = to_guide_mm(page, found[tag_id][1])
            expected = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * tag["size_mm"] / 2 + [u, v]
            assert np.abs(corners - expected).max() <= 0.5  # its size, and first corner lower-left: not mirrored
            seen[tag_id] += 1
    assert all(seen.values()), seen


def overlap_strips(guide, pages, a: int, b: int, shift_mm: float = 0.0):
    """The raster strips of sheets ``a`` (left) and ``b`` (right) over their shared band, away from the band's
    edges and from the rows of grid labels (which are written at each sheet's own edge)."""
    pa, pb = guide.pages[a], guide.pages[b]
    fa, fb = page_format(pa), page_format(pb)
    u0 = pb.origin_mm[0] + fb.drawing_box[0] + 3.0
    u1 = pa.origin_mm[0] + fa.drawing_box[2] - 3.0
    v0 = max(pa.origin_mm[1] + fa.drawing_box[1], pb.origin_mm[1] + fb.drawing_box[1]) + 6.0
    v1 = min(pa.origin_mm[1] + fa.drawing_box[3], pb.origin_mm[1] + fb.drawing_box[3]) - 6.0
    assert u1 - u0 > 5 and v1 - v0 > 100
    strips = []
    for page, raster, du in ((pa, pages[a], 0.0), (pb, pages[b], shift_mm)):
        # Pixel (column, row) of guide (u, v): round to the nearest pixel of each raster.
        c0 = int(round((u0 + du - page.origin_mm[0]) * PX_PER_MM))
        c1 = c0 + int(round((u1 - u0) * PX_PER_MM))
        r0 = int(round((page.size_mm[1] - (v1 - page.origin_mm[1])) * PX_PER_MM))
        r1 = r0 + int(round((v1 - v0) * PX_PER_MM))
        strips.append(raster[r0:r1, c0:c1].astype(float))
    vs = v1 - (np.arange(strips[0].shape[0]) + 0.5) / PX_PER_MM
    keep = (np.mod(vs, 50.0) > 4.0) & (np.mod(vs, 50.0) < 49.0)  # the "v 150" labels sit just above each 50 mm line
    return strips[0][keep], strips[1][keep]


def test_overlapping_sheets_show_the_same_drawing(rendered):
    guide, pages, _, _ = rendered
    labels = [p.label for p in guide.pages]
    pairs = [(i, i + 1) for i in range(len(labels) - 1) if labels[i][1:] == labels[i + 1][1:]]  # same row
    assert len(pairs) == 4
    for a, b in pairs:
        left, right = overlap_strips(guide, pages, a, b)
        assert left.std() > 10, "the band should hold some drawing (grid, marks, parts)"
        different = np.mean(np.abs(left - right) > 96)
        assert different < 0.005, (guide.pages[a].label, guide.pages[b].label, different)
        # The check can fail: the same band 1.5 mm off on one sheet does not match.
        left, shifted = overlap_strips(guide, pages, a, b, shift_mm=1.5)
        assert np.mean(np.abs(left - shifted) > 96) > 5 * max(different, 0.002)


def test_the_last_page_lists_every_part_step_and_tolerance(rendered):
    guide, _, texts, _ = rendered
    lists = " ".join(texts[len(guide.pages):]).replace("\r", "").replace("\n", " ")
    for part in guide.parts:
        assert part.name in lists
        for tolerance in part.tolerances:
            assert tolerance.parameter in lists
    for step in STEPS:
        assert " ".join(step.split()) in " ".join(lists.split())
    assert "from the layout's success model" in lists


def test_every_sheet_says_which_it_is(rendered):
    guide, _, texts, _ = rendered
    for page, text in zip(guide.pages, texts):
        assert f"sheet {page.label} of 3 x 2" in text
        assert "check: this bar must measure 100 mm" in text


@pytest.mark.parametrize(("tolerance", "expected"), [(True, "from the layout's success model"),
                                                      (False, "No tolerances: the layout carries no fitted")])
def test_the_lists_say_where_the_tolerances_come_from(tmp_path, tolerance, expected):
    path = tmp_path / "tiny.pdf"
    guide = write_pdf(tiny_guide(tolerance=tolerance), path, paper="letter")
    assert [p.paper for p in guide.pages] == ["letter"]
    document = pdfium.PdfDocument(path)
    assert len(document) == 2
    assert expected in text(document, 1).replace("\r\n", " ")
    document.close()


@pytest.mark.parametrize("name", ["a <b> & </i> c", "茶壶 ✂ naïve", "x" * 120, "<para>"])
def test_any_part_name_prints(name):
    guide = tiny_guide()
    part = guide.parts[0]
    guide = type(guide)(**{**guide.__dict__, "parts": (type(part)(**{**part.__dict__, "name": name}),)})
    stream = io.BytesIO()
    write_pdf(guide, stream, steps=[f"1. Place {name}"])
    document = pdfium.PdfDocument(stream.getvalue())
    written = text(document, 1)
    document.close()
    if name.isascii():
        assert name[:60] in written.replace("\r\n", "")


def test_a_bad_paper_is_one_line():
    with pytest.raises(ProjectorError, match="paper: expected one of a4, letter, a3, got 'a5'"):
        write_pdf(tiny_guide(), io.BytesIO(), paper="a5")


def vertical_strips(guide, pages, a: int, b: int, shift_mm: float = 0.0):
    """The raster strips of sheets ``a`` (above) and ``b`` (below it) over their shared band, away from its edges
    and from the grid's labels at each sheet's left edge."""
    above, below = guide.pages[a], guide.pages[b]
    box = page_format(above).drawing_box
    v0 = above.origin_mm[1] + box[1] + 3.0  # the band: from the bottom of the upper sheet's area ...
    v1 = below.origin_mm[1] + box[3] - 3.0  # ... to the top of the lower one's
    u0, u1 = above.origin_mm[0] + box[0] + 12.0, above.origin_mm[0] + box[2] - 3.0
    assert v1 - v0 > 5
    strips = []
    for page, raster, dv in ((above, pages[a], 0.0), (below, pages[b], shift_mm)):
        c0 = int(round((u0 - page.origin_mm[0]) * PX_PER_MM))
        r0 = int(round((page.size_mm[1] - (v1 + dv - page.origin_mm[1])) * PX_PER_MM))
        rows, columns = int(round((v1 - v0) * PX_PER_MM)), int(round((u1 - u0) * PX_PER_MM))
        strips.append(raster[r0:r0 + rows, c0:c0 + columns].astype(float))
    return strips


def test_sheets_above_each_other_join_too(rendered):
    guide, pages, _, _ = rendered
    for a, b in ((0, 3), (1, 4), (2, 5)):
        top, bottom = vertical_strips(guide, pages, a, b)
        assert top.std() > 5
        different = np.mean(np.abs(top - bottom) > 96)
        assert different < 0.005, (guide.pages[a].label, guide.pages[b].label, different)
        top, shifted = vertical_strips(guide, pages, a, b, shift_mm=1.5)
        assert np.mean(np.abs(top - shifted) > 96) > 5 * max(different, 0.002)
