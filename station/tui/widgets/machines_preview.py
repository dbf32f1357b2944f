"""The Machines screen's job preview: what a G-code job draws (:mod:`station.services.job_preview`), and while it
runs, what is done (green) and what is left (grey). A multi-pen plot is drawn in its pens' colours (what is done in
them, the rest grey while it runs), with its pen-up travel as dim lines.
"""

from __future__ import annotations

from station.errors import StationError
from station.services.job_preview import PreviewRun, preview_runs, run_pens, split_at_line, travel_segments
from station.tui.widgets.canvas import PatternCanvas

__all__ = ["JobPreview"]


class JobPreview(PatternCanvas):
    """A :class:`PatternCanvas` that shows a job's drawing.

    The drawings of the last few jobs shown are kept: a running job's preview is redrawn every half second, and
    queueing another job meanwhile shows that one.
    """

    #: How many jobs' drawings are kept.
    KEEP = 16

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self._drawings: dict[int, tuple[object, list[PreviewRun]]] = {}  # by id(job); the job is kept, so is its id

    def runs_of(self, job) -> list[PreviewRun]:
        """:func:`preview_runs` of ``job``, computed once; none for a job whose G-code cannot be read (it is
        refused with its line when it starts)."""
        kept = self._drawings.get(id(job))
        if kept is not None and kept[0] is job:
            return kept[1]
        try:
            runs = preview_runs(job)
        except StationError:
            runs = []
        if len(self._drawings) >= self.KEEP:
            self._drawings.pop(next(iter(self._drawings)))
        self._drawings[id(job)] = (job, runs)
        return runs

    def show_job(self, job, current_line: int | None = None) -> None:
        """Draw ``job``; with ``current_line`` (0-based), what is done in green (a multi-pen plot: in its pens'
        colours) and the rest in grey."""
        runs = self.runs_of(job)
        pens = run_pens(job, runs)
        if pens is None:
            self.set_polylines(*split_at_line(runs, current_line))
            return
        polylines, colors = split_at_line(runs, current_line, pens)
        travel = travel_segments(job)
        self.set_polylines(travel + polylines, ["grey27"] * len(travel) + colors)
