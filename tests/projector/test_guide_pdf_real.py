"""The guides of real example scenarios, printed: the builder's output through the PDF writer, read back as a maker
would (rasterized and decoded, the text of the sheets), not through the code that drew them."""

from __future__ import annotations

import io

import numpy as np
import pypdfium2 as pdfium
import pytest

from design.contraption import load_scenario
from design.contraption.catalog import resolve_scenario_path
from projector.build import build_guide, steps_text
from projector.pdf import write_pdf
from vision.detection import detect_tags

from .test_pdf import raster, scale_bar_mm, text, to_guide_mm


def printed(name: str, view: str):
    scenario = load_scenario(resolve_scenario_path(name))
    guide = build_guide(scenario, view=view)
    stream = io.BytesIO()
    guide = write_pdf(guide, stream, paper="a4", steps=steps_text(guide))
    return guide, pdfium.PdfDocument(stream.getvalue())


@pytest.mark.parametrize("name, view", [("ballrun", "side"), ("causalityswitch_ball", "top"),
                                        ("causalityswitch_ball", "side")])
def test_every_part_is_on_the_sheets_with_its_number_and_the_ball_is_last(name, view):
    guide, document = printed(name, view)
    sheets = "\n".join(text(document, page.index) for page in guide.pages)
    words = set(sheets.split())
    for part in guide.parts:
        assert part.name in sheets, f"{part.name} is on no sheet"
        assert str(part.step) in words, f"step {part.step} ({part.name}) is on no sheet"
    placed = [part.name for part in guide.parts]
    assert "ball" in placed[-2:]  # the ball rolls: placed last (CAUSALITYSWITCH's starter, the trigger, after it)
    lists = "".join(text(document, i) for i in range(len(guide.pages), len(document)))
    assert all(line.split(":")[0] in lists for line in steps_text(guide))
    document.close()


def test_ballruns_sheets_measure_true_and_its_reference_tags_decode_where_the_manifest_says():
    guide, document = printed("ballrun", "side")
    manifest = {t["id"]: t for t in guide.manifest()["reference_tags"]}
    found_on = {tag_id: [] for tag_id in manifest}
    for page in guide.pages:
        grey = raster(document, page.index)
        assert scale_bar_mm(grey) == pytest.approx(100.0, rel=0.005), page.label
        for tag in detect_tags(grey):
            assert tag.tag_id in manifest, f"sheet {page.label}: a decodable tag {tag.tag_id} that is no reference tag"
            centre = to_guide_mm(page, tag.center)
            assert np.abs(centre - manifest[tag.tag_id]["center_mm"]).max() <= 0.5, (page.label, tag.tag_id)
            found_on[tag.tag_id].append(page.label)
    assert all(found_on.values()), found_on  # each reference tag is whole on some sheet and decodes there
    document.close()


def test_the_parts_list_the_steps_and_the_frames_give_a_run_of_dominoes_the_same_point():
    # SIMPLE's run of three dominoes: its frame's origin is x = 20 mm, the middle of its outlines 35 mm. The steps,
    # the printed parts list and the projected step frame all say "around (35.0, 0.0)".
    from projector.frames import detail_caption

    guide, document = printed("simple", "top")
    dominoes = guide.part("dominoes")
    step = steps_text(guide)[dominoes.step - 1]
    assert "around (35.0, 0.0) mm" in step and "around (35.0, 0.0) mm" in detail_caption(dominoes)
    lists = " ".join("".join(text(document, i) for i in range(len(guide.pages), len(document))).split())
    assert "around (35.0, 0.0)" in lists and "(20.0, 0.0)" not in lists
    document.close()
