"""AprilTag bitmaps (tag36h11) as the upstream library draws them, for sheets, SVGs and projected frames.

OpenCV's ``DICT_APRILTAG_36h11`` holds the same codes as the upstream AprilTag library, but its bitmaps are the
upstream tags rotated by 180 degrees. A tag printed from OpenCV's bitmap still decodes to the right id (detection
tries all four rotations), yet every corner a detector reports comes out half a turn round, and so would every
heading measured from a tag. The station prints the upstream orientation: the tag's first corner (pupil-apriltags'
``corners[0]``) is its lower-left corner as printed, the corners go round counter-clockwise as the maker sees them.

Sizes: a tag's ``size`` is the edge of its black square (8 cells of 10: one white cell of border on each side is part
of the tag, and must be left white around it).
"""

from __future__ import annotations

import numpy as np

from vision.errors import VisionError

__all__ = ["TAG_CELLS", "TAG_COUNT", "TAG_FAMILY", "BLACK_CELLS", "check_tag_id", "tag_cells", "tag_image"]

#: The AprilTag family of every tag the station prints (upstream tag36h11, ids 0..586).
TAG_FAMILY = "tag36h11"
#: Cells across a tag with its white border, and across its black square (whose edge is the tag's size).
TAG_CELLS = 10
BLACK_CELLS = 8
#: Ids of tag36h11.
TAG_COUNT = 587


def check_tag_id(tag_id: object, what: str = "tag id") -> int:
    """``tag_id`` as an int in 0..586, or a :class:`VisionError` naming ``what``."""
    if isinstance(tag_id, bool) or not isinstance(tag_id, (int, np.integer)) or not 0 <= int(tag_id) < TAG_COUNT:
        raise VisionError(f"{what}: expected an integer from 0 to {TAG_COUNT - 1} (tag36h11), got {tag_id!r}")
    return int(tag_id)


def tag_cells(tag_id: int) -> np.ndarray:
    """The tag's 10 x 10 cells (True = white), row 0 at the top as printed, in the upstream orientation."""
    import cv2  # deferred: OpenCV is heavy, and a guide without tags never needs it

    tag_id = check_tag_id(tag_id)
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    black_square = dictionary.generateImageMarker(tag_id, BLACK_CELLS) > 0  # one pixel per cell
    cells = np.ones((TAG_CELLS, TAG_CELLS), dtype=bool)
    cells[1:-1, 1:-1] = np.rot90(black_square, 2)  # OpenCV's bitmap is the upstream tag turned half round
    return cells


def tag_image(tag_id: int, pixels_per_cell: int = 10) -> np.ndarray:
    """The tag as a grey image (uint8, 255 white), with its white border, ``10 * pixels_per_cell`` pixels across."""
    if not isinstance(pixels_per_cell, (int, np.integer)) or pixels_per_cell < 1:
        raise VisionError(f"pixels_per_cell: expected a whole number >= 1, got {pixels_per_cell!r}")
    cells = tag_cells(tag_id).astype(np.uint8) * 255
    return np.kron(cells, np.ones((pixels_per_cell, pixels_per_cell), dtype=np.uint8))
