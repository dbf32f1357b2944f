"""AprilTag bitmaps: the upstream orientation, checked against the upstream code layout and a detector."""

from __future__ import annotations

import numpy as np
import pytest

from vision.detection import detect_tags
from vision.errors import VisionError
from vision.tags import tag_cells, tag_image

# tag36h11 as the upstream library lays it out (tag36h11.c): the codes of two ids and where each of the 36 bits goes
# (x, y in cells of the 8 x 8 black square), most significant bit first. Written down from the upstream source,
# independently of OpenCV's dictionary that tags.py draws from.
UPSTREAM_CODES = {0: 0x0000000D7E00984B, 1: 0x0000000DDA664CA7}
BIT_X = [1, 2, 3, 4, 5, 2, 3, 4, 3, 6, 6, 6, 6, 6, 5, 5, 5, 4, 6, 5, 4, 3, 2, 5, 4, 3, 4, 1, 1, 1, 1, 1, 2, 2, 2, 3]
BIT_Y = [1, 1, 1, 1, 1, 2, 2, 2, 3, 1, 2, 3, 4, 5, 2, 3, 4, 3, 6, 6, 6, 6, 6, 5, 5, 5, 4, 6, 5, 4, 3, 2, 5, 4, 3, 4]


@pytest.mark.parametrize("tag_id", sorted(UPSTREAM_CODES))
def test_cells_are_the_upstream_bitmap(tag_id):
    expected = np.zeros((8, 8), dtype=bool)
    for bit, (x, y) in enumerate(zip(BIT_X, BIT_Y)):
        if UPSTREAM_CODES[tag_id] & (1 << (35 - bit)):
            expected[y, x] = True
    cells = tag_cells(tag_id)
    assert cells.shape == (10, 10)
    assert cells[0].all() and cells[-1].all() and cells[:, 0].all() and cells[:, -1].all()  # white border
    assert (cells[1:-1, 1:-1] == expected).all()


@pytest.mark.parametrize("tag_id", [0, 1, 42, 583, 586])
def test_a_detector_reads_the_id_and_the_first_corner_is_the_lower_left(tag_id):
    image = np.full((300, 300), 255, dtype=np.uint8)
    image[50:250, 50:250] = tag_image(tag_id, 20)
    (found,) = detect_tags(image)  # pupil-apriltags through the detector freed in the right order
    assert found.tag_id == tag_id
    # black square from pixel 70 to 230; image y grows downwards: lower-left, lower-right, upper-right, upper-left
    corners = np.round(found.corners).astype(int).tolist()
    assert corners == [[70, 230], [230, 230], [230, 70], [70, 70]]


@pytest.mark.parametrize("bad", [-1, 587, 3.0, "7", True, None])
def test_a_bad_id_is_one_line(bad):
    with pytest.raises(VisionError, match="expected an integer from 0 to 586"):
        tag_cells(bad)


def test_image_size_and_bad_scale():
    assert tag_image(5, 3).shape == (30, 30)
    with pytest.raises(VisionError, match="pixels_per_cell"):
        tag_image(5, 0)
