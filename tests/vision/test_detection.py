"""The tag detector wrapper: finds tags like pupil-apriltags does, and can be made and freed without harm."""

from __future__ import annotations

import numpy as np
import pytest

from vision.detection import TagDetector, detect_tags
from vision.errors import VisionError
from vision.tags import tag_image


def test_found_tags_and_their_corners():
    image = np.full((300, 300), 255, dtype=np.uint8)
    image[50:250, 50:250] = tag_image(586, 20)
    (found,) = detect_tags(image)
    assert found.tag_id == 586 and found.hamming == 0
    assert np.round(found.corners).astype(int).tolist() == [[70, 230], [230, 230], [230, 70], [70, 70]]
    assert found.center == pytest.approx([150, 150], abs=0.3)


def test_many_detectors_made_and_freed():
    # pupil-apriltags' own destructor writes into freed memory: made and freed repeatedly, runs aborted now and then.
    image = np.full((120, 120), 255, dtype=np.uint8)
    image[10:110, 10:110] = tag_image(3, 10)
    for _ in range(20):
        assert [t.tag_id for t in TagDetector().detect(image)] == [3]


@pytest.mark.parametrize("image", [np.zeros((4, 4, 3), np.uint8), np.zeros((4, 4), float)])
def test_a_bad_image_is_one_line(image):
    with pytest.raises(VisionError, match="expected a grey image"):
        detect_tags(image)
