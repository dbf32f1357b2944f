"""The ChArUco calibration board: its definition, a 1:1 PDF to print, its picture, and finding it in a view.

The default board fits landscape A4: 7 x 5 squares of 30 mm (210 x 150 mm) with 22 mm ArUco markers of
``DICT_5X5_100``, a family of its own: the station's AprilTags (tag36h11) never decode as one of its markers nor the
other way round, so a board left on the table does not disturb a check. Board coordinates are OpenCV's: millimetres
from the board's top-left corner, x right, y down (as the picture is printed).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np

from calibration.errors import CalibrationError

__all__ = ["BoardSpec", "CharucoView", "board_image", "detect_charuco", "write_board_pdf"]

_PAPERS = {"a4": (297.0, 210.0), "letter": (279.4, 215.9), "a3": (420.0, 297.0)}


@dataclass(frozen=True)
class BoardSpec:
    """A ChArUco board: squares across and down, their edge, the markers' edge (mm) and the marker dictionary."""

    squares_x: int = 7
    squares_y: int = 5
    square_mm: float = 30.0
    marker_mm: float = 22.0
    dictionary: str = "DICT_5X5_100"

    @property
    def size_mm(self) -> tuple[float, float]:
        """The board's width and height."""
        return self.squares_x * self.square_mm, self.squares_y * self.square_mm

    def describe(self) -> str:
        return (f"ChArUco {self.squares_x}x{self.squares_y} squares of {self.square_mm:g} mm, "
                f"{self.marker_mm:g} mm markers ({self.dictionary})")

    def board(self):
        """The board as a ``cv2.aruco.CharucoBoard`` (millimetre units)."""
        return _board(self)


@cache
def _board(spec: BoardSpec):
    import cv2

    if spec.squares_x < 2 or spec.squares_y < 2 or not 0 < spec.marker_mm < spec.square_mm:
        raise CalibrationError(f"ChArUco board: expected >= 2 x 2 squares and 0 < marker < square, got "
                               f"{spec.squares_x}x{spec.squares_y}, {spec.marker_mm:g} / {spec.square_mm:g} mm")
    code = getattr(cv2.aruco, spec.dictionary, None)
    if code is None or not spec.dictionary.startswith("DICT_") or "APRILTAG" in spec.dictionary:
        raise CalibrationError(f"ChArUco board: dictionary {spec.dictionary!r}: expected an ArUco dictionary such "
                               "as DICT_5X5_100 (not an AprilTag one: it would clash with the station's tags)")
    dictionary = cv2.aruco.getPredefinedDictionary(code)
    return cv2.aruco.CharucoBoard((spec.squares_x, spec.squares_y), float(spec.square_mm), float(spec.marker_mm),
                                  dictionary)


def _black_squares(spec: BoardSpec) -> np.ndarray:
    """(squares_y, squares_x) booleans, True for a black square, read from OpenCV's own picture of the board (its
    pattern changed between versions; reading it keeps the PDF and the detector in step)."""
    scale = 4.0  # px per mm: 1 mm inside a square's corner lies outside its marker
    picture = spec.board().generateImage((int(round(spec.size_mm[0] * scale)), int(round(spec.size_mm[1] * scale))),
                                         marginSize=0, borderBits=1)
    rows = ((np.arange(spec.squares_y) * spec.square_mm + 1.0) * scale).astype(int)
    cols = ((np.arange(spec.squares_x) * spec.square_mm + 1.0) * scale).astype(int)
    return picture[np.ix_(rows, cols)] < 128


def _marker_cells(spec: BoardSpec) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per marker: its top-left corner (board mm) and its cells with border (True = black), row 0 at the top."""
    board = spec.board()
    dictionary = board.getDictionary()
    cells = dictionary.markerSize + 2
    out = []
    for marker_id, corners in zip(board.getIds().ravel(), board.getObjPoints()):
        bitmap = dictionary.generateImageMarker(int(marker_id), cells, borderBits=1) < 128
        out.append((np.asarray(corners, dtype=float)[0, :2], bitmap))
    return out


def board_image(spec: BoardSpec | None = None, px_per_mm: float = 8.0, margin_mm: float = 0.0) -> np.ndarray:
    """The board as a grey uint8 picture, row 0 at its top, ``px_per_mm`` pixels per millimetre (plus a white
    margin of ``margin_mm`` all round): what the camera twin draws as an :class:`ImageItem`."""
    spec = spec or BoardSpec()
    width, height = spec.size_mm
    margin = int(round(margin_mm * px_per_mm))
    size = (int(round(width * px_per_mm)) + 2 * margin, int(round(height * px_per_mm)) + 2 * margin)
    return spec.board().generateImage(size, marginSize=margin, borderBits=1)


def write_board_pdf(path: str | Path, spec: BoardSpec | None = None, paper: str = "a4") -> Path:
    """Write the board at exactly 1:1 as a one-page vector PDF (landscape ``paper``), with a caption.

    Raises
    ------
    CalibrationError
        An unknown paper, or a board larger than the paper with a 10 mm margin.
    """
    from reportlab.lib.units import mm
    from reportlab.pdfgen import canvas

    spec = spec or BoardSpec()
    if paper not in _PAPERS:
        raise CalibrationError(f"paper: expected one of {', '.join(_PAPERS)}, got {paper!r}")
    page_w, page_h = _PAPERS[paper]
    width, height = spec.size_mm
    if width > page_w - 20 or height > page_h - 30:
        raise CalibrationError(f"ChArUco board: {width:g} x {height:g} mm does not fit {paper} landscape "
                               f"({page_w:g} x {page_h:g} mm) with margins")
    left = (page_w - width) / 2.0
    top = (page_h + height) / 2.0  # PDF y runs up: the board's y (down) is top - y

    path = Path(path)
    pdf = canvas.Canvas(str(path), pagesize=(page_w * mm, page_h * mm))
    pdf.setTitle(spec.describe())
    pdf.setFillGray(0.0)
    pdf.setStrokeGray(0.0)

    def cell(x0: float, y0: float, w: float, h: float) -> None:  # a black rectangle in board mm (y down)
        pdf.rect((left + x0) * mm, (top - y0 - h) * mm, w * mm, h * mm, stroke=0, fill=1)

    black = _black_squares(spec)
    for row, col in zip(*np.nonzero(black)):
        cell(col * spec.square_mm, row * spec.square_mm, spec.square_mm, spec.square_mm)
    for origin, bits in _marker_cells(spec):
        step = spec.marker_mm / bits.shape[0]
        for row in range(bits.shape[0]):
            # runs of black cells in a row as one rectangle: no hairline seams between neighbours in a viewer
            line = np.concatenate([[False], bits[row], [False]]).astype(np.int8)
            edges = np.flatnonzero(np.diff(line))
            for start, stop in zip(edges[::2], edges[1::2]):
                cell(origin[0] + start * step, origin[1] + row * step, (stop - start) * step, step)
    pdf.setFont("Helvetica", 9)
    pdf.drawString(left * mm, (top - height - 8) * mm,
                   f"{spec.describe()}. Print at 100% (no 'fit to page'); check that a square measures "
                   f"{spec.square_mm:g} mm. Lay it flat.")
    pdf.drawString(left * mm, (top + 4) * mm, "chaos-station calibration board: this side up")
    pdf.showPage()
    pdf.save()
    return path


@dataclass(frozen=True)
class CharucoView:
    """The board corners found in one view: pixels (OpenCV's pixel centres), their ids and board points (mm)."""

    corners: np.ndarray        # (n, 2)
    ids: np.ndarray            # (n,)
    object_points: np.ndarray  # (n, 3) board mm, z = 0


def detect_charuco(gray: np.ndarray, spec: BoardSpec | None = None) -> CharucoView | None:
    """The board's inner corners found in a grey image (None when no marker is found)."""
    import cv2

    spec = spec or BoardSpec()
    board = spec.board()
    detector = cv2.aruco.CharucoDetector(board)
    corners, ids, _marker_corners, _marker_ids = detector.detectBoard(np.ascontiguousarray(gray))
    if ids is None or len(ids) == 0:
        return None
    ids = np.asarray(ids, dtype=int).ravel()
    points = np.asarray(board.getChessboardCorners(), dtype=float)[ids]
    return CharucoView(np.asarray(corners, dtype=float).reshape(-1, 2), ids, points)
