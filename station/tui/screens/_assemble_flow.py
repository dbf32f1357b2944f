"""The Assemble screen's attempt, after the guide: place, check, fix, accept, run, outcomes, log; then calibrate the
physics on the log and re-optimize the layout with it (a mixin of the Assemble screen).

Every step is :class:`station.services.assemble.Assembly`'s (the same as ``station assemble``'s prompts); the slow
ones (a check, a forecast, a world's run, the database, a calibration, an optimization) run in thread workers and
report back through ``call_from_thread``; the forecast (physical success, expected attempts) is made again after the
guide, every check and every logged trial, and always shown in :class:`ForecastStatus`.
"""

from __future__ import annotations

import threading
from pathlib import Path

from textual import work
from textual.worker import get_current_worker

from design.errors import DesignError
from drivers.errors import DriverError
from projector.errors import ProjectorError
from station.errors import StationError
from station.services import assemble as flow
from station.services.layout_choice import describe_choice
from station.services.reporting import Cancelled, Reporter
from station.tui.widgets.assemble_flow import NEXT, ForecastStatus
from station.tui.widgets.outcomes import OutcomeTable
from station.tui.widgets.progress import ProgressPanel, post_progress

#: What a worker may fail with, said in one line.
FAILURES = (DesignError, ProjectorError, StationError, DriverError, ValueError, OSError)


class AttemptFlow:
    """Keys f (fix), a (accept), r (run), l (log), g (another attempt), k (calibrate), o (re-optimize), s (stop)."""

    #: Simulations per forecast, and the processes they run in (None: all cores); tests shrink both.
    forecast_samples = flow.DEFAULT_SAMPLES
    simulation_workers: int | None = None
    #: The calibration's sizes (None: the defaults) and the re-optimization's budget; tests shrink them.
    fit_settings = None
    #: k fits every material value, the plain ones within their default ranges (as ``station loop`` does): on a
    #: table the plain numbers are as unknown as the marked ones (a table's friction made one layout fail in two
    #: simulated worlds of five, which no fit of the marked values could learn).
    every_material = True
    optimize_budget = 40
    optimize_settings = None

    def _init_flow(self) -> None:
        self.assembly = None
        self.forecast = None
        self.physics: str | None = None
        self._stop_work = threading.Event()
        self._busy = ""

    # -- what is shown ------------------------------------------------------------------------------------------
    def _show_forecast(self, extra: str = "") -> None:
        a = self.assembly
        self.query_one("#forecast", ForecastStatus).show(None if a is None else a.stage,
                                                         None if a is None else a.attempt, self.forecast,
                                                         self._busy, extra)

    def _set_busy(self, text: str) -> None:
        self._busy = text
        self._show_forecast()

    def _refresh_forecast(self) -> None:
        if self.assembly is None:
            return
        self._set_busy("forecasting the physical success…")
        self._forecast_worker(self.assembly)

    @work(thread=True, exclusive=True, group="forecast")
    def _forecast_worker(self, assembly) -> None:
        worker = get_current_worker()
        try:
            assembly.samples, assembly.workers = self.forecast_samples, self.simulation_workers
            forecast = assembly.forecast(report=Reporter(stop=lambda: worker.is_cancelled))
        except flow.ServiceError as error:
            self.app.call_from_thread(self._forecast_done, None, f"no forecast: {error}")
            return
        except Exception as error:  # noqa: BLE001 - a stopped or failed forecast leaves the last one in view
            self.app.call_from_thread(self._forecast_done, None, f"no forecast: {type(error).__name__}: {error}")
            return
        if not worker.is_cancelled:
            self.app.call_from_thread(self._forecast_done, forecast, "")

    def _forecast_done(self, forecast, error: str) -> None:
        self._busy = ""
        if forecast is not None:
            self.forecast = forecast
        self._show_forecast(error)

    def _attempt_started(self, assembly) -> None:
        """A new attempt (the guide built): the forecast as designed."""
        self.assembly, self.forecast = assembly, None
        self.check = None
        table = self.query_one("#outcomes", OutcomeTable)
        table.display = False
        self._refresh_forecast()

    def _need(self, *stages: str) -> bool:
        """Whether the attempt is at one of ``stages``; says what to do otherwise."""
        if self.assembly is None:
            self._set_status("no guide yet: pick a scenario and a layout, press Enter", "red")
            return False
        if self.assembly.stage not in stages:
            self._set_status(f"the attempt is at {self.assembly.stage!r}: {NEXT[self.assembly.stage]}", "yellow")
            return False
        return True

    # -- check, fix, accept ---------------------------------------------------------------------------------------
    def _check_attempt(self, fix: bool = False):
        """Before a check: the parts placed (a world places them), moved as the last check said when ``fix``."""
        if self.assembly.stage == "guide":
            self.assembly.placed()
        if fix:
            self.assembly.fix()
        return self.assembly.check_parts(report=Reporter(post_progress(self)))

    def action_fix(self) -> None:
        if not self._need("check"):
            return
        if self.assembly.check is None:
            self._set_status("no check yet: c checks the placed parts", "yellow")
            return
        self.query_one("#check-progress", ProgressPanel).start(None, "moved as the check said; checking again…")
        self._check(self.job, True)

    def action_accept(self) -> None:
        if not self._need("check"):
            return
        self.assembly.accept()
        self._set_status("accepted as placed: r runs the contraption")
        self._show_forecast()

    # -- run and outcomes -----------------------------------------------------------------------------------------
    def action_run(self) -> None:
        if self.assembly is not None and self.assembly.stage == "check":
            self.assembly.accept()  # r after a check: the maker accepts the parts as they stand
        if not self._need("run"):
            return
        table = self.query_one("#outcomes", OutcomeTable)
        if self.assembly.world is None:
            table.load(self.assembly.scenario)
            table.display = True
            table.focus()
            self._set_status("run the contraption, then say what happened to each event: y, n, u (not reached); "
                             "l logs")
            self._show_forecast()
            return
        self._set_busy("the world runs the contraption…")
        self._run_worker(self.assembly)

    @work(thread=True, exclusive=True, group="run")
    def _run_worker(self, assembly) -> None:
        try:
            result = assembly.run()
        except FAILURES as error:
            self.app.call_from_thread(self._ran, None, f"cannot run: {error}")
            return
        self.app.call_from_thread(self._ran, result, "")

    def _ran(self, result, error: str) -> None:
        self._busy = ""
        if result is None:
            self._set_status(error, "red")
            self._show_forecast()
            return
        table = self.query_one("#outcomes", OutcomeTable)
        table.load(self.assembly.scenario, self.assembly.outcomes, self.assembly.times)
        table.display = True
        verdict = "a SUCCESS" if self.assembly.success else "a failure"
        self._set_status(f"the world ran it: {verdict}; l logs the trial", "green" if self.assembly.success else "")
        self._show_forecast()

    def outcomes_changed(self, event: OutcomeTable.Changed) -> None:
        """The outcome table's callback: the first problem, or the verdict once every event is said."""
        if self.assembly is None or self.assembly.stage != "run":
            return
        if event.problem:
            self._set_status(event.problem, "yellow")
        elif event.complete:
            self._set_status(f"every event said: {'a success' if event.success else 'a failure'}; l logs it",
                             "green")

    # -- log ------------------------------------------------------------------------------------------------------
    def action_log(self) -> None:
        if self.assembly is not None and self.assembly.stage == "run" and self.assembly.world is None:
            table = self.query_one("#outcomes", OutcomeTable)
            try:
                self.assembly.answer(table.given)
            except flow.ServiceError as error:
                self._set_status(str(error).replace("outcome.", "", 1), "red")
                return
        if not self._need("log"):
            return
        self._set_busy("logging the trial…")
        self._log_worker(self.assembly)

    @work(thread=True, exclusive=True, group="assemble-db")
    def _log_worker(self, assembly) -> None:
        from station.db import database_url
        from station.services.trials import open_store

        try:
            with open_store(database_url()) as store:
                trial_id = assembly.log(store)
        except FAILURES as error:
            self.app.call_from_thread(self._logged, None, f"cannot log: {error}")
            return
        self.app.call_from_thread(self._logged, trial_id, "")

    def _logged(self, trial_id: int | None, error: str) -> None:
        self._busy = ""
        if trial_id is None:
            self._set_status(error, "red")
            self._show_forecast()
            return
        verdict = "success" if self.assembly.success else "failure"
        self._set_status(f"logged trial #{trial_id} ({self.assembly.scenario.name}, {verdict}); g: another "
                         "attempt, k: calibrate the physics on the log, o: re-optimize", "green")
        self._refresh_forecast()

    def action_again(self) -> None:
        """Another attempt of the same layout (or of the re-optimized one, now in the layout field)."""
        if self.assembly is not None and self.assembly.stage not in ("done", "guide"):
            self._set_status(f"this attempt is at {self.assembly.stage!r}; log it first (l), or build again "
                             "(Enter) to drop it", "yellow")
            return
        self.action_build()

    # -- calibrate and re-optimize -------------------------------------------------------------------------------
    def action_calibrate(self) -> None:
        if self.assembly is None:
            self._set_status("no scenario yet: build a guide, log trials, then k", "red")
            return
        self._stop_work.clear()
        self.query_one("#check-progress", ProgressPanel).start(None, "calibrating the physics on the log…")
        self._set_busy("calibrating the simulator on the logged trials (s stops)…")
        self._calibrate_worker(self.assembly.job.scenario)

    @work(thread=True, exclusive=True, group="calibrate")
    def _calibrate_worker(self, scenario) -> None:
        from station.db import database_url
        from station.services.trials import open_store

        try:
            with open_store(database_url()) as store:
                path, result = flow.calibrate_from_log(scenario, store, settings=self.fit_settings,
                                                       workers=self.simulation_workers,
                                                       report=Reporter(post_progress(self),
                                                                       stop=self._stop_work.is_set),
                                                       every_material=self.every_material)
        except Cancelled:
            self.app.call_from_thread(self._calibrated, None, "calibration stopped; its simulations are cached")
            return
        except FAILURES as error:
            self.app.call_from_thread(self._calibrated, None, f"cannot calibrate: {error}")
            return
        values = ", ".join(f"{k} = {v:.3g}" for k, v in result.fit.values().items())
        self.app.call_from_thread(self._calibrated, str(path), f"calibrated: {values}; wrote {path}; o re-optimizes "
                                  "with it, g builds the next attempt with it")

    def _calibrated(self, path: str | None, text: str) -> None:
        self._busy = ""
        self.query_one("#check-progress", ProgressPanel).say(text)
        if path is not None:
            self.physics = path
            self.query_one("#physics").value = path
            self._set_status(text, "green")
        else:
            self._set_status(text, "red")
        self._show_forecast()

    def action_reoptimize(self) -> None:
        if self.assembly is None:
            self._set_status("no scenario yet: build a guide first", "red")
            return
        physics = self.query_one("#physics").value.strip() or None
        self._stop_work.clear()
        self.query_one("#check-progress", ProgressPanel).start(self.optimize_budget, "re-optimizing…")
        self._set_busy(f"re-optimizing the layout{' with ' + Path(physics).name if physics else ''} (s stops)…")
        self._reoptimize_worker(self.assembly.job.scenario.source, physics)

    @work(thread=True, exclusive=True, group="calibrate")
    def _reoptimize_worker(self, scenario: str, physics: str | None) -> None:
        try:
            current = self.query_one("#layout").value.strip() or None
            request = flow.ReoptimizeRequest(scenario, physics, budget=self.optimize_budget,
                                             settings=self.optimize_settings, current=current,
                                             workers=self.simulation_workers)
            path, result, chosen = flow.reoptimize(
                request, report=Reporter(post_progress(self), stop=self._stop_work.is_set))
        except Cancelled:
            self.app.call_from_thread(self._reoptimized, None, "re-optimization stopped; its simulations are cached")
            return
        except (*FAILURES, flow.ServiceError) as error:
            self.app.call_from_thread(self._reoptimized, None, f"cannot re-optimize: {error}")
            return
        self.app.call_from_thread(self._reoptimized, str(path), f"re-optimized: PSP {result.psp:.3f}"
                                  f"{describe_choice(chosen)}; wrote {path}; g builds its guide for the next attempt")

    def _reoptimized(self, path: str | None, text: str) -> None:
        self._busy = ""
        self.query_one("#check-progress", ProgressPanel).say(text)
        if path is not None:
            self.query_one("#layout").value = path
        self._set_status(text, "green" if path else "red")
        self._show_forecast()

    def action_stop(self) -> None:
        self._stop_work.set()
        self._set_status("stopping (finished simulations stay cached)…")
