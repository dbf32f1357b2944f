"""OpenCV calls whose name changed between its major versions, in one place (OpenCV is imported where used: a
heavy dependency, deferred to the edge that needs it)."""

from __future__ import annotations

import numpy as np

__all__ = ["undistort_points"]


def undistort_points(points, camera_matrix, dist_coeffs, rectification, projection, criteria) -> np.ndarray:
    """Undistorted pixel points, iterated until ``criteria``: ``cv2.undistortPointsIter`` on OpenCV 4, where plain
    ``undistortPoints`` stops after 5 steps; OpenCV 5 removed it and gave ``undistortPoints`` the criteria."""
    import cv2

    if hasattr(cv2, "undistortPointsIter"):
        return cv2.undistortPointsIter(points, camera_matrix, dist_coeffs, rectification, projection, criteria)
    return cv2.undistortPoints(points, camera_matrix, dist_coeffs, R=rectification, P=projection, criteria=criteria)
