"""A PNG picture in the terminal, drawn with half blocks (the Fabricate sheet, the Robust layouts side views)."""

from __future__ import annotations

import io

from PIL import Image
from rich.style import Style
from rich.text import Text
from textual.widget import Widget


class HalfBlockPicture(Widget):
    """A picture drawn with ``▀`` half blocks: each terminal cell shows two pixels (top: foreground, bottom:
    background), scaled to fit the widget and keep the picture's aspect ratio (cells are twice as tall as wide).

    Parameters
    ----------
    empty : str
        Shown (dim) until a picture is set, e.g. ``"(no sheet yet)"``.
    id : str, optional
        The widget's id.
    """

    DEFAULT_CSS = "HalfBlockPicture { width: 1fr; height: 1fr; }"

    def __init__(self, *, empty: str = "(no picture yet)", id: str | None = None) -> None:
        super().__init__(id=id)
        #: What the widget says while it has no picture (each screen names what it will show).
        self.empty = empty
        self.full: Image.Image | None = None
        self.image: Image.Image | None = None
        self.crop: tuple[float, float, float, float] | None = None

    def set_png(self, png: bytes | None) -> None:
        self.set_image(Image.open(io.BytesIO(png)) if png else None)

    def set_image(self, image: Image.Image | None) -> None:
        """Show ``image`` (a picture already in memory: no PNG to encode and decode again), or nothing."""
        self.full = image.convert("RGB") if image is not None else None
        self.set_crop(self.crop)

    def set_crop(self, crop: tuple[float, float, float, float] | None) -> None:
        """Show only ``(left, top, right, bottom)`` of the picture (fractions), or all of it (None)."""
        self.crop = crop
        if self.full is not None and crop is not None:
            w, h = self.full.size
            box = (int(crop[0] * w), int(crop[1] * h), max(int(crop[2] * w), 1), max(int(crop[3] * h), 1))
            self.image = self.full.crop(box)
        else:
            self.image = self.full
        self.refresh()

    def render(self) -> Text:
        return self.render_text(self.size.width, self.size.height)

    def render_text(self, width: int, height: int) -> Text:
        """The picture as rich text of at most ``width`` × ``height`` cells."""
        if self.image is None or width < 2 or height < 2:
            return Text(self.empty, style="dim")
        image_w, image_h = self.image.size
        fit = min(width / image_w, 2 * height / image_h)
        cols, rows = max(1, int(image_w * fit)), max(2, int(image_h * fit) // 2 * 2)
        pixels = self.image.resize((cols, rows), Image.Resampling.BOX).load()
        text = Text(no_wrap=True, overflow="crop")
        for row in range(0, rows, 2):
            for col in range(cols):
                top, bottom = pixels[col, row], pixels[col, row + 1]
                text.append("▀", Style(color=f"rgb({top[0]},{top[1]},{top[2]})",
                                       bgcolor=f"rgb({bottom[0]},{bottom[1]},{bottom[2]})"))
            if row + 2 < rows:
                text.append("\n")
        return text
