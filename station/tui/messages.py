"""The typed messages a screen's long work sends back to it: one way for a worker thread to talk to the UI.

Long work runs in a thread worker (:func:`station.tui.work.run_work`); the thread never touches a widget. It posts
messages (``post_message`` is safe from any thread, and messages from one thread arrive in the order posted):

- :class:`ProgressReported` for each :class:`common.progress.Progress` the work reports;
- one :class:`WorkEnded` when it ends: its result, or the one-line error that refused it, or that it was stopped.

Each kind of work ends with its own subclass of :class:`WorkEnded`, named for what it did, so that a screen
handles it with an ``on_<name>`` method (Textual names the handler after the class). Work that shows more than its
progress while it runs (a simulation's event states) posts a message of its own, also defined here, so that every
message a worker sends is in this one module.
"""

from __future__ import annotations

from typing import Any

from textual.message import Message

from station.services.reporting import Progress

__all__ = [
    "CameraCalibrated", "CandidatesFound", "DeviceProbed", "ExplorerBuilt", "ExplorerChanged", "FabricationEnded",
    "OptimizationEnded", "OutlookPredicted", "PatternComputed", "PlaneChecked", "PreviewMoved", "ProgressReported",
    "ProjectorCalibrated", "SimulationEnded", "SimulationStepped", "SimulatorCalibrated", "TestCardMade",
    "TrialLogged", "TrialsExported", "TrialsListed", "WorkEnded",
    # Assemble
    "AttemptForecast", "AttemptLogged", "AttemptRan", "GuideBuilt", "GuideExported", "JigsMade", "LayoutReoptimized",
    "PartsChecked", "PhysicsCalibrated", "StepProjected",
    # Machines
    "BedFrameGrabbed", "BedRegistered", "ConsoleReplied", "DesignPlotted", "JobEnding", "JobSent", "JobVerified",
    "MachineConnected", "MachineSaid", "SendAsked",
]


class ProgressReported(Message):
    """Long work reported ``progress`` (the panel of the screen or widget that started it shows it)."""

    def __init__(self, progress: Progress) -> None:
        super().__init__()
        self.progress = progress


class WorkEnded(Message):
    """Long work ended: with ``result``, or refused (``error``, one line for a person), or ``stopped`` on request.

    Parameters
    ----------
    result : object, optional
        What the work returned (None when it failed or stopped).
    error : str
        Why the work has no result, one line for a person: the refusal, or what the stop said it kept ("" when the
        work ran to its end).
    stopped : bool
        The work was asked to stop and stopped between two units of work.
    """

    def __init__(self, result: Any = None, error: str = "", stopped: bool = False) -> None:
        super().__init__()
        self.result, self.error, self.stopped = result, error, stopped

    @property
    def ok(self) -> bool:
        """Whether the work ran to its end (``result`` is its answer)."""
        return not self.error and not self.stopped


# -- what each screen's work ends with ---------------------------------------------------------------------------
class DeviceProbed(WorkEnded):
    """A device was probed: its name and the state the probe found (Home)."""


class PatternComputed(WorkEnded):
    """A drawing machine's pattern was sampled (Drawing screen)."""


class ExplorerBuilt(WorkEnded):
    """An exploration session was started on a design: its points of interest found (Explore)."""


class ExplorerChanged(WorkEnded):
    """The exploration session changed: an invariant kept or dropped, a slider released, a step undone (Explore)."""


class PreviewMoved(WorkEnded):
    """A slider's move was previewed without changing the session (Explore)."""


class CandidatesFound(WorkEnded):
    """A sketch search ranked its candidates (Sketch retrieval)."""


class FabricationEnded(WorkEnded):
    """The parts, nesting and laser job of a design were made (Fabricate)."""


class TestCardMade(WorkEnded):
    """A laser test card was made and written (Fabricate)."""


class SimulationStepped(Message):
    """A running simulation changed state (Contraptions): the time, each event's state, the bodies and ropes."""

    def __init__(self, t: float, states: dict[str, str], snapshot: Any, ropes: list) -> None:
        super().__init__()
        self.t, self.states, self.snapshot, self.ropes = t, states, snapshot, ropes


class SimulationEnded(WorkEnded):
    """A scenario's simulation ended (Contraptions)."""


class OptimizationEnded(WorkEnded):
    """A robust optimization ended (Robust layouts)."""


class CameraCalibrated(WorkEnded):
    """The camera's intrinsics were solved and saved (Calibrate)."""


class PlaneChecked(WorkEnded):
    """The plane was checked against the guide's reference tags (Calibrate)."""


class ProjectorCalibrated(WorkEnded):
    """The projector's mapping was measured and saved (Calibrate)."""


class SimulatorCalibrated(WorkEnded):
    """The simulator's material values were fitted to the trial log (Calibrate)."""


class TrialLogged(WorkEnded):
    """A trial was logged (Trials)."""


class OutlookPredicted(WorkEnded):
    """The physical success of a logged trial's layout was predicted (Trials)."""


class TrialsListed(WorkEnded):
    """The trial log was read (Trials)."""


class TrialsExported(WorkEnded):
    """Trials were exported to a file (Trials)."""


# -- Assemble: one attempt, then what the log teaches ----------------------------------------------------------------
class GuideBuilt(WorkEnded):
    """An attempt began (Assemble): ``(assembly, frames, what the projector does)``."""


class StepProjected(WorkEnded):
    """A step (or the calibrate frame) was shown on the projector (Assemble)."""


class GuideExported(WorkEnded):
    """The guide's 1:1 PDF sheets and SVG were written (Assemble): ``(pdf, svg, sheets)``."""


class JigsMade(WorkEnded):
    """The layout's laser-cut jigs were planned and written (Assemble): ``(result, folder)``."""


class PartsChecked(WorkEnded):
    """The placed parts were checked with the camera (Assemble): ``(check, picture, what the projector said)``."""


class AttemptForecast(WorkEnded):
    """The attempt's physical success was forecast (Assemble): a :class:`station.services.assemble.Forecast`."""


class AttemptRan(WorkEnded):
    """The simulated world ran the attempt (Assemble)."""


class AttemptLogged(WorkEnded):
    """The attempt's trial was logged (Assemble): its id."""


class PhysicsCalibrated(WorkEnded):
    """The physics was calibrated on the scenario's logged trials (Assemble): ``(profile path, calibration)``."""


class LayoutReoptimized(WorkEnded):
    """The layout was optimized again under the physics and the surest option written (Assemble): ``(path,
    result, chosen)``."""


# -- Machines: the GRBL machines and their jobs (MachineSessions) ----------------------------------------------------
class MachineConnected(WorkEnded):
    """A machine's connection opened (Machines): ``(device name, connection)``; an error names the device."""


class JobSent(WorkEnded):
    """A send ended and is recorded (Machines): its :class:`~station.services.machine_sessions.JobResult`."""


class JobEnding(Message):
    """A send ended and is about to be recorded (Machines): the screen shows the end, then sets ``shown`` so that the
    sending thread records it (whoever reads the job's state then finds the screen saying it)."""

    def __init__(self, result: Any, progress: Any, shown: Any) -> None:
        super().__init__()
        self.result, self.progress, self.shown = result, progress, shown


class SendAsked(Message):
    """A send asks the person at the machine a yes/no ``question`` (Machines): the screen asks it in a dialog and
    calls ``answer(bool)``; the sending thread waits for it."""

    def __init__(self, question: str, answer: Any) -> None:
        super().__init__()
        self.question, self.answer = question, answer


class MachineSaid(Message):
    """Something to show in the Machines screen's message line and console: a machine's event (an alarm, a
    ``[MSG:]``, a line of its log) or a send's question answered elsewhere (a pen change); ``status`` asks for the
    status panel to be drawn again."""

    def __init__(self, text: str = "", style: str = "", *, console_only: bool = False, status: bool = False) -> None:
        super().__init__()
        self.text, self.style, self.console_only, self.status = text, style, console_only, status


class ConsoleReplied(WorkEnded):
    """A console line was answered (Machines): the controller's feedback lines."""


class DesignPlotted(WorkEnded):
    """A drawing-machine design became a plot job (Machines): ``(device name, G-code, title)``."""


class JobVerified(WorkEnded):
    """A job was run on its machine's twin (Machines, bed placement): its
    :class:`~station.services.job_verify.JobVerification`."""


class BedFrameGrabbed(WorkEnded):
    """The bed camera's picture was taken (bed placement): the frame."""


class BedRegistered(WorkEnded):
    """The bed was registered by its engraved marks (bed placement): the calibration."""
