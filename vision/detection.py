"""Finding AprilTags (tag36h11) in a grey image with pupil-apriltags, without its destructor's heap corruption.

pupil-apriltags 1.0.4's ``Detector.__del__`` frees the tag family first and then the detector, whose destructor
un-initializes every family it holds: it writes into the freed family, corrupting the heap (valgrind: an invalid
write in ``quick_decode_uninit`` under ``apriltag_detector_destroy``). The process then aborts later, anywhere
("malloc(): mismatching next->prev_size"), in about one test run in eight. :class:`TagDetector` frees them in the
right order: the detector (which un-initializes the families), then the families.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vision.errors import VisionError
from vision.tags import TAG_FAMILY

__all__ = ["MAX_FRAME_PIXELS", "MIN_FRAME_SIDE", "FoundTag", "TagDetector", "detect_tags", "frame_size_problem"]

#: The smallest side of a frame given to the detector, in pixels. pupil-apriltags reads outside the image, and the
#: process dies (SIGSEGV, no message), when the image it searches for quads has fewer than 3 rows: a frame 1-2 px
#: high, 4 px at the half size quads are searched at. No tag36h11 (10 cells across with its white border) is
#: readable in fewer pixels than this anyway.
MIN_FRAME_SIDE = 20
#: The largest frame, in pixels: 50 megapixels holds a 48 MP phone photo (8000x6000). Decoding a larger image takes
#: gigabytes (a 20000x20000 PNG is 1.2 GB as RGB) and a detection of minutes; Pillow itself refuses images over
#: 179 MP as decompression bombs.
MAX_FRAME_PIXELS = 50_000_000


@dataclass(frozen=True)
class FoundTag:
    """A decoded tag: its id, centre and corners in pixels (x right, y down, pixel edges at integers; the first
    corner is the tag's lower-left as printed, then counter-clockwise as seen)."""

    tag_id: int
    center: np.ndarray
    corners: np.ndarray
    hamming: int


def _detector_class():
    from pupil_apriltags import Detector  # deferred: a native library, loaded only where a frame is searched

    class SafeDetector(Detector):
        def __del__(self) -> None:
            pointer = getattr(self, "tag_detector_ptr", None)
            if pointer is None:
                return
            self.tag_detector_ptr = None
            self.libc.apriltag_detector_destroy.restype = None
            self.libc.apriltag_detector_destroy(pointer)  # un-initializes the families it holds: free them after
            for family, handle in self.tag_families.items():
                destroy = getattr(self.libc, f"{family}_destroy")
                destroy.restype = None
                destroy(handle)
            self.tag_families = {}

    return SafeDetector


class TagDetector:
    """A tag36h11 detector that can be made and freed any number of times.

    Parameters
    ----------
    quad_decimate : float
        Detect quads on an image this many times smaller (faster, corners still refined on the full image).
    threads : int
        Threads the detector uses.
    """

    def __init__(self, quad_decimate: float = 1.0, threads: int = 1) -> None:
        self._decimate = float(quad_decimate)
        self._detector = _detector_class()(families=TAG_FAMILY, nthreads=int(threads), quad_decimate=self._decimate)

    def detect(self, gray: np.ndarray) -> list[FoundTag]:
        """The tags found in a grey uint8 image (2-D), in the detector's order.

        Raises
        ------
        VisionError
            Not a 2-D uint8 array, or of a size :func:`frame_size_problem` refuses (checked here, before the
            detector: a frame too small for it kills the process).
        """
        image = np.asarray(gray)
        if image.ndim != 2 or image.dtype != np.uint8:
            raise VisionError(f"tag detection: expected a grey image (2-D uint8 array), got {image.dtype} "
                                 f"{image.shape}")
        problem = frame_size_problem(image.shape[1], image.shape[0], self._decimate)
        if problem is not None:
            raise VisionError(f"tag detection: {problem}")
        return [FoundTag(int(d.tag_id), np.array(d.center, dtype=float), np.array(d.corners, dtype=float),
                         int(d.hamming))
                for d in self._detector.detect(np.ascontiguousarray(image))]


def frame_size_problem(width: int, height: int, quad_decimate: float = 1.0) -> str | None:
    """What is wrong with a frame of ``width`` x ``height`` pixels for tag detection, or None.

    A side under :data:`MIN_FRAME_SIDE` (or under 4 quad-search pixels at ``quad_decimate``), or more than
    :data:`MAX_FRAME_PIXELS` in all. Image readers ask this of a file's header before decoding it, so that every
    frame, from a file or a camera, meets the same rule.
    """
    smallest = max(MIN_FRAME_SIDE, math.ceil(4 * quad_decimate))
    if min(width, height) < smallest:
        return (f"{width}x{height} pixels is too small; expected at least {smallest}x{smallest} "
                "(a smaller frame holds no readable tag)")
    if width * height > MAX_FRAME_PIXELS:
        return (f"{width}x{height} pixels ({width * height / 1e6:.0f} MP) is too large; expected at most "
                f"{MAX_FRAME_PIXELS / 1e6:.0f} megapixels (a camera frame or a phone photo)")
    return None


def detect_tags(gray: np.ndarray, quad_decimate: float = 1.0) -> list[FoundTag]:
    """The tags found in a grey uint8 image, with a detector made for the call and freed after it."""
    return TagDetector(quad_decimate).detect(gray)
