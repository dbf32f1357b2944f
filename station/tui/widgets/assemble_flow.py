"""The Assemble screen's forecast, always in view: :class:`ForecastStatus` shows where the attempt is (guide, check,
run, log, done), the predicted physical success and the expected attempts (the last
:class:`station.services.assemble.Forecast`), and what the keys do next. (The run's outcomes are ticked in a
:class:`station.tui.widgets.outcomes.OutcomeTable`, as on the Trials screen.)
"""

from __future__ import annotations

from rich.text import Text
from textual.widgets import Static

from station.services.outlook import attempts_words

#: What to do next at each stage, in keys.
NEXT = {
    None: "pick a scenario and a layout, press Enter",
    "guide": "n/p: steps; place the parts, then c: check them",
    "check": "c: check again; f: moved as it says (check again); a: accept as placed, go to the run",
    "run": "r: run (a simulated world runs it; otherwise say what happened: y/n/u per event)",
    "log": "l: log the trial",
    "done": "g: another attempt; k: calibrate the physics on the log; o: re-optimize with it",
}


class ForecastStatus(Static):
    """The attempt's stage, its forecast and the next keys (updated after every check and every logged trial)."""

    DEFAULT_CSS = "ForecastStatus { height: auto; border: round $accent; padding: 0 1; }"

    def show(self, stage: str | None, attempt: int | None = None, forecast=None, busy: str = "",
             extra: str = "") -> None:
        text = Text()
        if stage is not None:
            text.append(f"attempt {attempt} · {stage}\n", style="bold")
        if forecast is not None:
            # the station's headline (station.services.outlook), split over lines to fit the narrow column
            p = forecast.prediction
            text.append("physical success on the table ")
            text.append(f"{p.probability:.2f}", style="bold green" if p.probability >= 0.8 else "bold yellow")
            text.append(f" (95 %: {p.interval[0]:.2f}-{p.interval[1]:.2f})\n")
            text.append(attempts_words(p.attempts, p.attempts_interval), style="bold")
            words = forecast.record_words()
            if words:
                text.append(f"\n{words}")
            text.append(f"\n{forecast.when}\n", style="dim")
        else:
            text.append("physical success: -\n", style="dim")
        if busy:
            text.append(f"{busy}\n", style="italic")
        if extra:
            text.append(f"{extra}\n")
        text.append(NEXT.get(stage, ""), style="dim")
        self.update(text)
