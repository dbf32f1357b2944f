"""One interface to run simulations: in-process, local worker processes or a Dask cluster, with a disk cache.

:class:`SimulationExecutor` maps a batch of normalized layouts to per-event success booleans. It

- looks every layout up in a :class:`SimulationCache` first (SQLite, keyed by the scenario's content hash, the
  revision of the code that simulates it when the problem names one (``cache_revision``, :func:`cache_scope`) and the
  layout), so a repeated or interrupted run re-simulates nothing it already knows;
- sends the rest to a backend: ``"inline"`` (this process, for cheap synthetic problems), ``"processes"`` (local
  worker processes, one per core by default) or ``"dask"`` (a ``distributed`` cluster given by scheduler address
  or client); each worker prepares the problem once (``prepare_worker``: a contraption's pybullet client and world)
  and keeps it for every task, and a batch goes out in a few tasks per worker (see ``chunk_size``);
- stores each task's results as soon as they arrive (an interruption loses at most the tasks still running);
- calls ``on_result(n_new)`` after each arrival (progress), and asks its reporter between arrivals whether to stop
  (a TUI's Stop button): a stop raises :class:`common.progress.Cancelled`, Ctrl-C raises ``KeyboardInterrupt``;
  both keep the cache.

A problem may return numbers instead of booleans (simulator calibration wants event times): it says so with an
``outcome_dtype = float`` attribute and ``n_outputs`` (the length of what ``simulate`` returns); the cache stores
such a row as a JSON array (NaN as null).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import signal
import sqlite3
import sys
import threading
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

import numpy as np

from common.progress import Reporter
from design.robust.problem import LayoutProblem, RobustError, as_layout_batch


class SchedulerUnreachable(RobustError):
    """The Dask scheduler given by address cannot be reached (or the address is malformed)."""


#: Seconds to wait for a Dask scheduler to answer: long enough for a cluster on a slow network, short enough that a
#: wrong address is reported at once (distributed's own default is 30 s, with a traceback per retry loop).
SCHEDULER_CONNECT_TIMEOUT = 5.0


#: Tasks per worker a batch is cut into when no chunk size is given: enough for the workers to finish together
#: (simulations differ in length), few enough that sending them is a small part of the time.
TASKS_PER_WORKER = 4
#: The most layouts in one automatic task: progress and a stop request are seen at least this often.
MAX_CHUNK = 32

#: How long a cache write waits for another process's (seconds): SQLite's busy timeout.
CACHE_BUSY_SECONDS = 60.0


def layout_key(u: np.ndarray) -> str:
    """Cache key of one normalized layout: its values rounded to 12 decimals (exact repeats hit)."""
    return ",".join(f"{v:.12f}" for v in np.asarray(u, dtype=float))


def cache_scope(problem) -> str:
    """What ``problem``'s outcomes are filed under in a :class:`SimulationCache`: its content hash, followed by its
    ``cache_revision`` (the simulating code's) when it has one."""
    revision = getattr(problem, "cache_revision", None)
    return problem.content_hash if revision is None else f"{problem.content_hash}@{revision}"


class SimulationCache:
    """Simulation outcomes on disk, keyed by scope (:func:`cache_scope`: the scenario's content hash, and the
    simulator's revision) and layout.

    Parameters
    ----------
    path : path or None
        SQLite file; ``None`` keeps the cache in memory (nothing survives the process).
    """

    def __init__(self, path: str | Path | None) -> None:
        self.path = Path(path) if path is not None else None
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        self._lock = threading.Lock()
        # several processes share the file (two `station trial log` predicting at once): a writer waits for another
        # rather than failing with "database is locked"
        self._connection = sqlite3.connect(str(self.path) if self.path else ":memory:", check_same_thread=False,
                                           timeout=CACHE_BUSY_SECONDS)
        self._connection.execute(
            "CREATE TABLE IF NOT EXISTS simulations (scenario TEXT NOT NULL, layout TEXT NOT NULL, "
            "events TEXT NOT NULL, PRIMARY KEY (scenario, layout))"
        )
        self._connection.commit()

    def get_many(self, scenario: str, keys: list[str]) -> dict[str, np.ndarray]:
        """The known outcomes among ``keys``."""
        found: dict[str, np.ndarray] = {}
        with self._lock:
            for start in range(0, len(keys), 500):
                chunk = keys[start : start + 500]
                marks = ",".join("?" * len(chunk))
                rows = self._connection.execute(
                    f"SELECT layout, events FROM simulations WHERE scenario = ? AND layout IN ({marks})",
                    [scenario, *chunk],
                ).fetchall()
                for layout, events in rows:
                    found[layout] = _decode(events)
        return found

    def put(self, scenario: str, key: str, events: np.ndarray) -> None:
        """Store one outcome (committed at once, so an interruption keeps it)."""
        self.put_many(scenario, [(key, events)])

    def put_many(self, scenario: str, rows: list[tuple[str, np.ndarray]]) -> None:
        """Store outcomes ``(key, events)`` in one transaction (one commit for a task's layouts)."""
        values = [(scenario, key, _encode(events)) for key, events in rows]
        with self._lock:
            self._connection.executemany(
                "INSERT OR REPLACE INTO simulations (scenario, layout, events) VALUES (?, ?, ?)", values
            )
            self._connection.commit()

    def count(self, scenario: str | None = None) -> int:
        """Number of stored outcomes (of one scenario, or all)."""
        with self._lock:
            if scenario is None:
                return self._connection.execute("SELECT COUNT(*) FROM simulations").fetchone()[0]
            return self._connection.execute(
                "SELECT COUNT(*) FROM simulations WHERE scenario = ?", (scenario,)
            ).fetchone()[0]

    def close(self) -> None:
        with self._lock:
            self._connection.close()


def _encode(events) -> str:
    """A cached row: one ``0``/``1`` per event, or a JSON array of numbers (NaN as null)."""
    events = np.asarray(events)
    if events.dtype == bool:
        return "".join("1" if e else "0" for e in events)
    return json.dumps([None if not math.isfinite(v) else v for v in events.astype(float).tolist()])


def _decode(text: str) -> np.ndarray:
    """A cached row: ``"0110"`` (one boolean per event) or a JSON array of numbers (null: NaN)."""
    if text.startswith("["):
        return np.array([np.nan if v is None else v for v in json.loads(text)], dtype=float)
    return np.array([c == "1" for c in text], dtype=bool)


def outcome_dtype(problem) -> type:
    """What ``problem.simulate`` returns per layout: booleans (the optimizer's problems) or numbers."""
    return getattr(problem, "outcome_dtype", bool)


def _outcomes(problem, U: np.ndarray) -> np.ndarray:
    dtype = outcome_dtype(problem)
    return np.stack([np.asarray(problem.simulate(u), dtype=dtype) for u in U])


@contextlib.contextmanager
def usable_std_streams():
    """Put the process's real stdout/stderr back while starting worker processes, if they were replaced.

    multiprocessing passes ``sys.stderr.fileno()`` to the processes it starts; under a Textual app that is -1 and
    starting a worker fails ("bad value(s) in fds_to_keep").
    """
    def unusable(stream) -> bool:
        try:
            return stream.fileno() < 0
        except (AttributeError, OSError, ValueError):
            return True

    saved = sys.stdout, sys.stderr
    swap = unusable(sys.stderr) or unusable(sys.stdout)
    if swap:
        sys.stdout, sys.stderr = sys.__stdout__, sys.__stderr__
    try:
        yield
    finally:
        if swap:
            sys.stdout, sys.stderr = saved


# --- worker-side state: one prepared problem per process (one pybullet client per process) ---------------------
_WORKER_PROBLEMS: dict[str, LayoutProblem] = {}


def _init_process_worker(problem: LayoutProblem, parent_pid: int | None = None) -> None:
    # Ctrl-C is the parent's business: it cancels and keeps the cache; workers just get terminated.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if parent_pid is not None:
        threading.Thread(target=_exit_when_orphaned, args=(parent_pid,), daemon=True,
                         name="orphan watchdog").start()
    problem.prepare_worker()
    _WORKER_PROBLEMS[problem.content_hash] = problem


def _exit_when_orphaned(parent_pid: int, interval: float = 0.5) -> None:
    """End this worker once the process that owns the pool is gone.

    A parent killed without clean-up (``kill -9``, a crash, SIGTERM in a script without a handler) leaves forkserver
    workers running its queued simulations for nobody, at full CPU, until they are killed by hand.
    """
    while True:
        time.sleep(interval)
        if _process_gone(parent_pid):
            os._exit(1)


def _process_gone(pid: int) -> bool:
    """Whether ``pid`` has exited: it no longer exists, or it is a zombie that its own parent has not reaped."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except PermissionError:  # it exists, it is just not ours to signal
        return False
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] == "Z"
    except (OSError, IndexError):  # no /proc (macOS): a zombie parent keeps its workers until it is reaped
        return False


def _simulate_in_worker(content_hash: str, U: np.ndarray) -> np.ndarray:
    return _outcomes(_WORKER_PROBLEMS[content_hash], U)


def _simulate_on_dask_worker(problem: LayoutProblem, U: np.ndarray) -> np.ndarray:
    # Dask workers are long-lived: prepare each scenario once per worker process and keep it.
    prepared = _WORKER_PROBLEMS.get(problem.content_hash)
    if prepared is None:
        problem.prepare_worker()
        _WORKER_PROBLEMS[problem.content_hash] = prepared = problem
    return _outcomes(prepared, U)


class SimulationExecutor:
    """Runs a problem's simulations with a cache; use as a context manager (it owns worker processes).

    Parameters
    ----------
    problem : LayoutProblem
        The scenario.
    backend : {"auto", "inline", "processes", "dask"}
        ``"auto"``: Dask when ``scheduler`` is given, else worker processes when ``workers`` > 1, else inline.
    workers : int or None
        Local worker processes (``None``: one per core).
    scheduler : str or distributed.Client or None
        A Dask scheduler address (``tcp://HOST:PORT``) or an existing client.
    cache_path : path or None
        SQLite cache file; ``None`` for an in-memory cache.
    chunk_size : int or None
        Layouts per task sent to a worker. ``None`` (default): a batch is cut into about
        :data:`TASKS_PER_WORKER` tasks per worker (at most :data:`MAX_CHUNK` layouts each), so the messages between
        processes stay a small part of the time while the workers still finish together.
    connect_timeout : float
        Seconds to wait for a scheduler given by address (see :meth:`connect`).
    """

    def __init__(
        self,
        problem: LayoutProblem,
        backend: str = "auto",
        workers: int | None = None,
        scheduler=None,
        cache_path: str | Path | None = None,
        chunk_size: int | None = None,
        connect_timeout: float | None = None,
    ) -> None:
        if backend not in {"auto", "inline", "processes", "dask"}:
            raise RobustError(f"executor: backend must be one of auto, inline, processes, dask, got {backend!r}")
        if workers is not None and (int(workers) != workers or workers < 1):
            raise RobustError(f"executor: workers must be a positive integer, got {workers!r}")
        if chunk_size is not None and (int(chunk_size) != chunk_size or chunk_size < 1):
            raise RobustError(f"executor: chunk_size must be a positive integer, got {chunk_size!r}")
        self.problem = problem
        self.scope = cache_scope(problem)  #: what its outcomes are filed under in the cache
        self.workers = int(workers) if workers is not None else (os.cpu_count() or 1)
        if backend == "auto":
            backend = "dask" if scheduler is not None else ("processes" if self.workers > 1 else "inline")
        if backend == "dask" and scheduler is None:
            raise RobustError("executor: the dask backend needs a scheduler address or client")
        self.backend = backend
        self.scheduler = scheduler
        self.chunk_size = None if chunk_size is None else int(chunk_size)
        self.n_tasks = 0  # tasks sent to workers (one per chunk of layouts)
        self.connect_timeout = SCHEDULER_CONNECT_TIMEOUT if connect_timeout is None else float(connect_timeout)
        self.cache = SimulationCache(cache_path)
        self.n_simulated = 0  # new simulations actually run
        self.n_cache_hits = 0
        self._pool: ProcessPoolExecutor | None = None
        self._client = None
        self._owns_client = False
        self._remote_problem = None
        self._inline_prepared = False

    # -- lifecycle ------------------------------------------------------------------------------------------
    def __enter__(self) -> SimulationExecutor:
        return self

    def __exit__(self, *exc) -> None:
        self.close(kill=exc[0] is not None)

    def close(self, kill: bool = False) -> None:
        """Stop worker processes (``kill`` terminates running simulations) and close the cache."""
        self._stop_pool(kill)
        self._remote_problem = None
        if self._client is not None and self._owns_client:
            self._client.close()
        self._client = None
        self.cache.close()

    def _stop_pool(self, kill: bool) -> None:
        """Shut the worker pool down, dropping its queued simulations; ``kill`` also ends the running ones.

        Queued futures are cancelled by the pool's own manager thread (``cancel_futures=True``), never from this
        thread: a worker terminated while a future cancelled here is still among the pool's pending items makes the
        manager thread set an exception on that cancelled future, and it dies printing ``InvalidStateError`` (Python
        3.11's ``terminate_broken``). Shutting down first, then terminating, leaves every cancellation to it.
        """
        pool, self._pool = self._pool, None
        if pool is None:
            return
        processes = list((getattr(pool, "_processes", None) or {}).values())
        pool.shutdown(wait=not kill, cancel_futures=True)
        if kill:
            for process in processes:
                process.terminate()

    def _ensure_pool(self) -> ProcessPoolExecutor:
        if self._pool is None:
            import multiprocessing

            # forkserver/spawn: never fork a process that runs threads (the TUI) or holds a pybullet client.
            method = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
            self._pool = ProcessPoolExecutor(
                max_workers=self.workers,
                mp_context=multiprocessing.get_context(method),
                initializer=_init_process_worker,
                initargs=(self.problem, os.getpid()),
            )
        return self._pool

    def connect(self) -> None:
        """Reach the Dask scheduler now (no-op for the other backends), so a wrong address fails before any work.

        Raises
        ------
        SchedulerUnreachable
            No answer within ``connect_timeout`` seconds, or an address distributed cannot parse.
        """
        if self.backend == "dask":
            self._ensure_client()

    def _ensure_client(self):
        if self._client is None:
            if isinstance(self.scheduler, str):
                from distributed import Client

                problem = None
                try:
                    self._client = Client(self.scheduler, timeout=self.connect_timeout)
                except ValueError as error:  # e.g. "missing port number in address"
                    problem = f"Dask scheduler {self.scheduler!r}: {error} (expected tcp://HOST:PORT)"
                except (OSError, TimeoutError):
                    problem = (f"no Dask scheduler answered at {self.scheduler} within {self.connect_timeout:g} s: "
                               "check the address and port, and that `dask scheduler` runs there with workers "
                               "(`dask worker ADDRESS`)")
                if problem is not None:
                    # outside the except block: its traceback no longer holds the half-built client
                    _finalize_failed_clients()
                    raise SchedulerUnreachable(problem)
                self._owns_client = True
            else:
                self._client = self.scheduler
        return self._client

    # -- running --------------------------------------------------------------------------------------------
    def count_new(self, U: np.ndarray) -> int:
        """How many simulations :meth:`run` of ``U`` would run: its distinct layouts the cache does not know."""
        U = as_layout_batch(self.problem, U)
        keys = list(dict.fromkeys(layout_key(u) for u in U))
        return len(keys) - len(self.cache.get_many(self.scope, keys))

    def run(
        self,
        U: np.ndarray,
        on_result: Callable[[int], None] | None = None,
        report: Reporter | None = None,
    ) -> np.ndarray:
        """Per-event success ``(n, n_events)`` of each normalized layout of ``U`` (all must be valid); for a problem
        of numbers (``outcome_dtype = float``), its ``(n, n_outputs)`` numbers.

        ``report`` is asked between arrivals whether to stop: a stop raises :class:`common.progress.Cancelled`,
        every finished simulation cached.
        """
        report = Reporter.of(report)
        U = as_layout_batch(self.problem, U)
        n_outputs = getattr(self.problem, "n_outputs", len(self.problem.event_names))
        out = np.zeros((len(U), n_outputs), dtype=outcome_dtype(self.problem))
        if len(U) == 0:
            return out
        keys = [layout_key(u) for u in U]
        known = self.cache.get_many(self.scope, keys)
        todo: dict[str, list[int]] = {}
        for i, key in enumerate(keys):
            if key in known:
                out[i] = known[key]
            else:
                todo.setdefault(key, []).append(i)
        self.n_cache_hits += len(U) - sum(len(v) for v in todo.values())
        if todo:
            for _key, rows, events in self._simulate(U, todo, report, on_result):
                out[rows] = events
        return out

    def _chunk_size(self, n: int) -> int:
        """Layouts per task for a batch of ``n`` new layouts."""
        if self.chunk_size is not None:
            return self.chunk_size
        if self.backend == "inline":
            return 1  # no messages to amortize; a stop is seen after every simulation
        slots = self.workers
        if self.backend == "dask":
            slots = sum(self._ensure_client().nthreads().values()) or 1
        return max(1, min(MAX_CHUNK, math.ceil(n / (slots * TASKS_PER_WORKER))))

    def _simulate(self, U, todo, report: Reporter, on_result):
        """Yield ``(key, rows, events)`` for every new layout, storing each in the cache first."""
        items = list(todo.items())
        size = self._chunk_size(len(items))
        chunks = [items[i : i + size] for i in range(0, len(items), size)]
        self.n_tasks += len(chunks)

        def finish(chunk, results):
            self.cache.put_many(self.scope, [(key, events) for (key, _rows), events in zip(chunk, results)])
            self.n_simulated += len(chunk)
            if on_result is not None:
                on_result(len(chunk))
            return [(key, rows, events) for (key, rows), events in zip(chunk, results)]

        if self.backend == "inline":
            if not self._inline_prepared:
                self.problem.prepare_worker()
                self._inline_prepared = True
            for chunk in chunks:
                report.check()
                results = _outcomes(self.problem, U[[rows[0] for _, rows in chunk]])
                yield from finish(chunk, results)
            return

        if self.backend == "processes":
            with usable_std_streams():  # submitting may start worker processes
                pool = self._ensure_pool()
                known_as = self.problem.content_hash  # the workers' name for the problem (not its cache scope)
                futures = {
                    pool.submit(_simulate_in_worker, known_as, U[[rows[0] for _, rows in chunk]]): chunk
                    for chunk in chunks
                }
        else:
            client = self._ensure_client()
            if self._remote_problem is None:
                # Scattered once per executor and kept: re-scattering the same object can drop its data.
                self._remote_problem = client.scatter(self.problem, broadcast=True, hash=False)
            remote_problem = self._remote_problem
            futures = {
                client.submit(
                    _simulate_on_dask_worker, remote_problem, U[[rows[0] for _, rows in chunk]], pure=False
                ): chunk
                for chunk in chunks
            }
        pending = set(futures)
        try:
            while pending:
                report.check()
                if self.backend == "processes":
                    done, pending = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
                else:
                    from distributed import wait as dask_wait

                    try:
                        result = dask_wait(list(pending), timeout=0.5, return_when="FIRST_COMPLETED")
                    except TimeoutError:
                        continue  # ask about a stop again
                    done, pending = set(result.done), set(result.not_done)
                for future in done:
                    try:
                        results = future.result()
                    except BrokenProcessPool:
                        raise RobustError(
                            f"{self.problem.name}: a simulation worker process died (out of memory, killed, or a "
                            "script without an `if __name__ == '__main__':` guard, which worker processes "
                            "re-import); finished simulations are cached, run again to continue"
                        ) from None
                    yield from finish(futures[future], results)
        except BaseException:
            # A stopped, interrupted or failed run ends its simulations: queued ones would keep the workers busy
            # for nobody. The pool is rebuilt on the next run.
            if self.backend == "processes":
                self._stop_pool(kill=True)
            else:
                for future in pending:
                    future.cancel()
            raise


def _finalize_failed_clients() -> None:
    """Finalize, now, the half-built ``distributed.Client`` a failed connection leaves behind.

    Its ``__del__`` closes its loop runner under a lock that every ``LoopRunner`` shares. Left to the garbage
    collector, it can run inside another thread's start-up while a new client holds that lock and waits for the
    thread: a deadlock (seen in the suite: the process hung in ``Thread.start``). Collected here, no lock is held.
    """
    import gc

    gc.collect()
