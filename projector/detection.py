"""Finding AprilTags (tag36h11) in a grey image with pupil-apriltags, without its destructor's heap corruption.

pupil-apriltags 1.0.4's ``Detector.__del__`` frees the tag family first and then the detector, whose destructor
un-initializes every family it holds: it writes into the freed family, corrupting the heap (valgrind: an invalid
write in ``quick_decode_uninit`` under ``apriltag_detector_destroy``). The process then aborts later, anywhere
("malloc(): mismatching next->prev_size"), in about one test run in eight. :class:`TagDetector` frees them in the
right order: the detector (which un-initializes the families), then the families.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from projector.errors import ProjectorError
from projector.guide import TAG_FAMILY

__all__ = ["FoundTag", "TagDetector", "detect_tags"]


@dataclass(frozen=True)
class FoundTag:
    """A decoded tag: its id, centre and corners in pixels (x right, y down, pixel edges at integers; the first
    corner is the tag's lower-left as printed, then counter-clockwise as seen)."""

    tag_id: int
    center: np.ndarray
    corners: np.ndarray
    hamming: int


def _detector_class():
    from pupil_apriltags import Detector

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
        self._detector = _detector_class()(families=TAG_FAMILY, nthreads=int(threads),
                                           quad_decimate=float(quad_decimate))

    def detect(self, gray: np.ndarray) -> list[FoundTag]:
        """The tags found in a grey uint8 image (2-D), in the detector's order."""
        image = np.asarray(gray)
        if image.ndim != 2 or image.dtype != np.uint8:
            raise ProjectorError(f"tag detection: expected a grey image (2-D uint8 array), got {image.dtype} "
                                 f"{image.shape}")
        return [FoundTag(int(d.tag_id), np.array(d.center, dtype=float), np.array(d.corners, dtype=float),
                         int(d.hamming))
                for d in self._detector.detect(np.ascontiguousarray(image))]


def detect_tags(gray: np.ndarray, quad_decimate: float = 1.0) -> list[FoundTag]:
    """The tags found in a grey uint8 image, with a detector made for the call and freed after it."""
    return TagDetector(quad_decimate).detect(gray)
