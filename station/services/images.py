"""Camera frames from image files: a file whose header gives a frame the tag detector cannot take is refused before it
is decoded (:func:`vision.detection.frame_size_problem`), so that a photo, a folder of calibration views or a laser
card's picture meet the same rule as a camera's frame.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, UnidentifiedImageError

from station.errors import ServiceError, station_errors
from vision.detection import MAX_FRAME_PIXELS, frame_size_problem

__all__ = ["check_frame_size", "check_image_file", "load_image"]


@station_errors
def load_image(path: str | Path) -> np.ndarray:
    """A camera frame from a file (PNG, JPEG...) as RGB uint8; a ServiceError naming ``image`` otherwise (also for a
    frame of a size :func:`vision.detection.frame_size_problem` refuses, found from the header before decoding)."""
    try:
        with Image.open(path) as picture:
            check_frame_size(path, picture.size, "image")
            return np.asarray(picture.convert("RGB"))
    except FileNotFoundError:
        raise ServiceError(f"image {path}: no such file", field="image", value=str(path)) from None
    except Image.DecompressionBombError:
        raise _too_large(path, "image") from None
    except (OSError, UnidentifiedImageError) as error:
        raise ServiceError(f"image {path}: not an image the station can read ({error})", field="image",
                           value=str(path)) from None


@station_errors
def check_image_file(path: str | Path, field: str) -> None:
    """Refuse an image file whose header gives a frame size :func:`vision.detection.frame_size_problem` refuses,
    before a reader decodes it; a file Pillow cannot read is left to the caller's reader."""
    try:
        with Image.open(path) as picture:
            size = picture.size
    except Image.DecompressionBombError:
        raise _too_large(path, field) from None
    except (OSError, UnidentifiedImageError):
        return
    check_frame_size(path, size, field)


@station_errors
def check_frame_size(path: str | Path, size: tuple[int, int], field: str) -> None:
    """A ServiceError naming ``field`` and the file when a frame of ``size`` (width, height) cannot be checked."""
    problem = frame_size_problem(*size)
    if problem is not None:
        raise ServiceError(f"{field} {path}: {problem}", field=field, value=str(path))


def _too_large(path: str | Path, field: str) -> ServiceError:
    return ServiceError(f"{field} {path}: over {2 * Image.MAX_IMAGE_PIXELS / 1e6:.0f} MP, too large; expected at most "
                        f"{MAX_FRAME_PIXELS / 1e6:.0f} megapixels (a camera frame or a phone photo)", field=field,
                        value=str(path))
