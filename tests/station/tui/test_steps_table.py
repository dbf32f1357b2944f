"""The Assemble screen's parts table gives each part where the steps put it."""

import asyncio

from textual.app import App, ComposeResult

from projector.guide import where_text
from station.services.guide import GuideRequest, make_guide
from station.tui.widgets.assemble_guide import StepsTable


class _Table(App):
    def compose(self) -> ComposeResult:
        yield StepsTable()


def test_a_run_of_pieces_is_listed_where_its_step_says():
    guide = make_guide(GuideRequest("causalityswitch_ball", None, tolerances=False)).guide
    stem = next(p for p in guide.parts if p.name == "stem")
    assert where_text(stem).startswith("around")  # a run of pieces, whose frame origin is elsewhere

    async def run() -> str:
        app = _Table()
        async with app.run_test():
            table = app.query_one(StepsTable)
            table.load(guide)
            return str(table.get_row("stem")[4])

    cell = asyncio.run(run())
    assert cell == where_text(stem).removeprefix("around ").removesuffix(" mm")
    assert cell != "({:.1f}, {:.1f})".format(*stem.center_mm)
