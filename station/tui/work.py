"""One way to run a screen's long work: a thread worker that reports back only through typed messages.

:func:`run_work` runs ``call(report)`` in a Textual thread worker. ``report`` is a
:class:`~station.services.reporting.Reporter`: each progress it is given reaches the target widget as a
:class:`~station.tui.messages.ProgressReported`, and its stop check is true once the screen asks the work to stop
(:meth:`Work.stop`, a Stop button) or the worker is cancelled. When the call returns, raises one of the user errors or
stops, the target gets one :class:`~station.tui.messages.WorkEnded` (of the subclass the screen names)::

    def action_generate(self) -> None:
        self.work = run_work(self, lambda report: fabricate(request, report=report), FabricationEnded,
                             group="fabricate")

    def on_progress_reported(self, message: ProgressReported) -> None:
        self.query_one(ProgressPanel).show(message.progress)

    def on_fabrication_ended(self, message: FabricationEnded) -> None:
        ...  # message.result, or message.error, or message.stopped

The thread never touches a widget and never waits for the UI: messages are posted (safe from any thread, and they
arrive in the order posted, so the end comes after every progress of the same run).

Work in an exclusive group is replaced by the next run of that group: Textual cancels the older worker, whose stop
check then says stop, and whatever it still reports or returns is dropped, so a screen only hears from its newest
run. Any exception other than a user error is a bug: it ends the worker as Textual does (the app shows it).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from textual.message_pump import MessagePump
from textual.worker import Worker, get_current_worker

from station.errors import USER_ERRORS
from station.services.reporting import Cancelled, Progress, Reporter
from station.tui.messages import ProgressReported, WorkEnded

__all__ = ["Work", "run_work"]


class Work:
    """A long piece of work started by :func:`run_work`.

    Attributes
    ----------
    worker : textual.worker.Worker
        The thread worker running it.
    """

    def __init__(self, worker: Worker) -> None:
        self.worker = worker
        self._stop = threading.Event()

    def stop(self) -> None:
        """Ask the work to stop at its next check; it then ends with ``stopped=True`` (what it kept is its own
        business: a robust run keeps its simulations in the cache)."""
        self._stop.set()

    @property
    def stop_asked(self) -> bool:
        """Whether :meth:`stop` was called."""
        return self._stop.is_set()

    @property
    def running(self) -> bool:
        """Whether the worker has not ended yet."""
        return not self.worker.is_finished


def run_work(target: MessagePump, call: Callable[[Reporter], Any], ended: type[WorkEnded] = WorkEnded, *,
             group: str, exclusive: bool = True, errors: tuple[type[BaseException], ...] = USER_ERRORS) -> Work:
    """Run ``call(report)`` in a thread worker of ``target`` (a screen or a widget); see the module notes.

    Parameters
    ----------
    target : MessagePump
        Where the messages go, and whose worker it is (the screen, or a panel that handles its own).
    call : callable
        ``call(report) -> result``: the service call, given the reporter to pass on as ``report=``.
    ended : type
        The :class:`WorkEnded` subclass the end is posted as.
    group : str
        The worker group; with ``exclusive`` a new run cancels the group's older one.
    errors : tuple of exception types
        The errors said in one line (``ended(error=str(error))``); by default the station's user errors.

    Returns
    -------
    Work
        The handle whose :meth:`Work.stop` asks the work to stop.
    """
    # The thread asks the handle whether a stop was asked: it waits until run_worker has returned the worker the
    # handle wraps.
    holder: list[Work] = []
    started = threading.Event()

    def body() -> None:
        started.wait()
        work, worker = holder[0], get_current_worker()

        def superseded() -> bool:
            # cancelled by Textual (a newer run of the group, the screen or app going away), not by a Stop
            return worker.is_cancelled and not work.stop_asked

        def post(progress: Progress) -> None:
            if not superseded():
                target.post_message(ProgressReported(progress))

        report = Reporter(post, stop=lambda: work.stop_asked or worker.is_cancelled)
        try:
            result = call(report)
        except Cancelled as stop:
            outcome = ended(error=str(stop), stopped=True)
        except errors as error:
            outcome = ended(error=str(error))
        else:
            outcome = ended(result=result)  # finished before it looked at a stop: the answer is whole
        if not superseded():
            target.post_message(outcome)

    worker = target.run_worker(body, name=group, group=group, exclusive=exclusive, thread=True)
    holder.append(Work(worker))
    started.set()
    return holder[0]
