"""Solves bounded in wall time: the back-end runs in a worker process that can be abandoned.

fatrop has no wall-time limit of its own, and a native call that never returns holds
its thread for good (casadi issue #3857 reports fatrop freezing after non-finite
evaluations; 4 of 120 random tumbles froze a solve here, issue 13). Python cannot
interrupt a native call, so :class:`SolverWorker` builds the back-end in a child
process and waits for each answer up to a deadline. A missed deadline kills the
child (SIGKILL, a few milliseconds) and starts a new one at once; the solve is
reported as ``deadline_missed`` and the controller executes its previous plan.

* **Guaranteed bound**: a solve returns at the latest ``deadline_s`` plus the time
  to kill the child after it was sent; the caller's ``abandon()`` (a stop signal)
  is checked every :data:`POLL_PERIOD_S` and ends the wait the same way.
* **Deterministic in lockstep** (``wait_for_start=True``): the deadline counts from
  the moment a ready worker received the problem, so a restart's build time never
  changes which solves miss; a solve that finishes within its deadline returns what
  the back-end in this process would (the same code on the same numbers).
* **Real time** (``wait_for_start=False``): a worker still starting counts against
  the deadline; the solve fails (``worker_starting``) instead of waiting.
* A worker that died (a crash in native code) is restarted the same way.

The child is a fresh interpreter (``python -m splitter_mpc.core.solver_worker``;
forking the multi-threaded ROS process is unsafe, and multiprocessing's spawn
would re-run the parent's main script), talks over two pipes
(:class:`multiprocessing.connection.Connection`: pickled requests and answers),
ignores SIGINT (a Ctrl-C to the process group is the parent's to handle) and dies
with its parent (``PR_SET_PDEATHSIG``). A build loads the solver's compiled code
from the cache that ``splitter build-mpc`` (or the first start) fills.
"""

from __future__ import annotations

import ctypes
import logging
import math
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from multiprocessing.connection import Connection
from typing import Protocol

import numpy as np

from splitter_mpc.core.solvers import Closable, ProblemInstance, SolverResult

_LOG = logging.getLogger(__name__)
POLL_PERIOD_S = 0.05  # [s] how often a waiting solve checks abandon()
START_TIMEOUT_S = 300.0  # [s] a worker's build (the first one compiles the solver code)
STOP_TIMEOUT_S = 2.0  # [s] a worker asked to stop is killed after this long
_PR_SET_PDEATHSIG = 1  # prctl option (linux/prctl.h)

STATUS_DEADLINE_MISSED = "deadline_missed"
STATUS_WORKER_STARTING = "worker_starting"
STATUS_WORKER_DIED = "worker_died"
STATUS_ABANDONED = "abandoned"
STATUS_NON_FINITE_DATA = "non_finite_data"


class Backend(Protocol):
    """What :mod:`.solvers` back-ends offer."""

    name: str

    def solve(self, data: ProblemInstance) -> SolverResult: ...


BackendFactory = Callable[[], Backend]


class WorkerStartError(RuntimeError):
    """The worker could not build its back-end."""


@dataclass(frozen=True)
class FaultInjection:
    """A back-end factory whose back-ends hang or die on chosen solves (fault tests).

    ``hang_solves`` / ``crash_solves``: 1-based numbers of the solves, counted per
    worker process (a restarted worker counts from 1 again), that never return (a
    sleep that ignores SIGINT, as a frozen native call does) or kill the process.
    """

    factory: BackendFactory
    hang_solves: tuple[int, ...] = ()
    crash_solves: tuple[int, ...] = ()

    def __call__(self) -> Backend:
        return _FaultyBackend(self.factory(), self.hang_solves, self.crash_solves)


class _FaultyBackend:
    def __init__(self, inner: Backend, hang: tuple[int, ...], crash: tuple[int, ...]) -> None:
        self.name = inner.name
        self._inner, self._hang, self._crash = inner, hang, crash
        self._solves = 0

    def solve(self, data: ProblemInstance) -> SolverResult:
        self._solves += 1
        if self._solves in self._crash:
            os._exit(70)  # a native crash: no clean-up, no answer
        while self._solves in self._hang:
            time.sleep(3600.0)
        return self._inner.solve(data)


def failed_result(data: ProblemInstance, status: str, elapsed_s: float) -> SolverResult:
    """A solve that produced nothing: the warm start, marked unusable."""
    return SolverResult(
        z=np.array(data.z0, dtype=float),
        lam_g=np.array(data.lam_g0, dtype=float),
        lam_z=np.array(data.lam_z0, dtype=float),
        status=status,
        converged=False,
        usable=False,
        iterations=0,
        solve_time_s=elapsed_s,
        cost=math.nan,
        infeasibility=math.nan,
    )


def non_finite_fields(data: ProblemInstance) -> list[str]:
    """Fields of ``data`` that must not reach a solver: NaN anywhere, inf outside bounds."""
    bad = [
        name
        for name in ("z0", "lam_g0", "lam_z0", "p")
        if not np.all(np.isfinite(getattr(data, name)))
    ]
    bad += [name for name in ("lbz", "ubz", "lbg", "ubg") if np.any(np.isnan(getattr(data, name)))]
    return bad


def _die_with_parent(parent_pid: int) -> None:
    """Ask the kernel to SIGKILL this process when its parent dies (Linux)."""
    try:
        libc = ctypes.CDLL("libc.so.6", use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
    except OSError as exc:  # not Linux: the pipe's EOF still ends an idle worker
        _LOG.debug("PR_SET_PDEATHSIG unavailable: %s", exc)
    if os.getppid() != parent_pid:  # the parent died before the request took effect
        os._exit(0)


def serve(requests: Connection, answers: Connection) -> None:
    """The worker's loop: build the back-end, then answer ("solve", data) until told to stop.

    The first request is ("build", factory); a failed build is answered with
    ("error", text), a good one with ("ready", back-end name).
    """
    try:
        kind, factory = requests.recv()
        if kind != "build":
            raise ValueError(f"expected a build request first, got {kind!r}")
        backend = factory()
    except Exception as exc:  # reported to the parent, which raises it
        answers.send(("error", f"{type(exc).__name__}: {exc}"))
        return
    answers.send(("ready", backend.name))
    while True:
        try:
            kind, payload = requests.recv()
        except EOFError:  # the parent is gone
            return
        if kind == "stop":
            return
        try:
            answers.send(("result", backend.solve(payload)))
        except Exception as exc:  # the parent raises it as a RuntimeError
            answers.send(("error", f"{type(exc).__name__}: {exc}"))


def worker_main(argv: list[str] | None = None) -> int:
    """Entry of a worker process: ``python -m splitter_mpc.core.solver_worker REQ ANS PARENT``."""
    args = sys.argv[1:] if argv is None else argv
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C to the group is the parent's
    requests_fd, answers_fd, parent_pid = (int(a) for a in args)
    _die_with_parent(parent_pid)
    serve(Connection(requests_fd, writable=False), Connection(answers_fd, readable=False))
    return 0


class SolverWorker(Closable):
    """A back-end in a child process; :meth:`solve` bounded by ``deadline_s`` of wall time."""

    def __init__(
        self,
        factory: BackendFactory,
        deadline_s: float,
        *,
        wait_for_start: bool = True,
        start_timeout_s: float = START_TIMEOUT_S,
    ) -> None:
        if not (math.isfinite(deadline_s) and deadline_s > 0.0):
            raise ValueError(f"deadline_s must be finite and > 0, got {deadline_s!r}")
        self.deadline_s = float(deadline_s)
        self.wait_for_start = wait_for_start
        self.start_timeout_s = float(start_timeout_s)
        self.abandon: Callable[[], bool] | None = None  # checked while a solve is waited for
        self.deadline_misses = 0
        self.restarts = 0
        self._factory = factory
        self._process: subprocess.Popen | None = None
        self._requests: Connection | None = None
        self._answers: Connection | None = None
        self._ready = False
        self._started_at = 0.0
        self.name = ""
        self._start()
        self._await_ready(self.start_timeout_s)
        if not self._ready:
            self.close()
            raise WorkerStartError(f"solver worker not ready after {self.start_timeout_s:g} s")

    # --- life cycle ----------------------------------------------------------------------
    def _start(self) -> None:
        """Start a worker (a fresh interpreter: no fork of this multi-threaded process)."""
        req_r, req_w = os.pipe()
        ans_r, ans_w = os.pipe()
        try:
            self._process = subprocess.Popen(
                [sys.executable, "-m", __name__, str(req_r), str(ans_w), str(os.getpid())],
                pass_fds=(req_r, ans_w),
                stdin=subprocess.DEVNULL,
                close_fds=True,
            )
        finally:
            os.close(req_r)
            os.close(ans_w)
        self._requests = Connection(req_w, readable=False)
        self._answers = Connection(ans_r, writable=False)
        self._ready = False
        self._started_at = time.monotonic()
        self._requests.send(("build", self._factory))

    def _await_ready(self, timeout_s: float) -> None:
        """Wait up to ``timeout_s`` for the worker's "ready" (raises if its build failed)."""
        if self._ready:
            return
        if not self._wait_readable(timeout_s):
            return
        try:
            kind, payload = self._answers.recv()
        except EOFError as exc:
            self._kill()
            raise WorkerStartError("solver worker died while building its back-end") from exc
        if kind == "error":
            self._kill()
            raise WorkerStartError(f"solver worker could not build its back-end: {payload}")
        self.name, self._ready = str(payload), True

    def _alive(self) -> bool:
        return self._process is not None and self._process.poll() is None

    def _kill(self) -> None:
        if self._alive():
            self._process.kill()
        if self._process is not None:
            try:
                self._process.wait(STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                _LOG.error("solver worker %d survived SIGKILL", self._process.pid)
        for conn in (self._requests, self._answers):
            if conn is not None:
                conn.close()
        self._process, self._requests, self._answers, self._ready = None, None, None, False

    def _restart(self, reason: str) -> None:
        _LOG.warning("solver worker %s: restarting it", reason)
        self._kill()
        self.restarts += 1
        self._start()

    def close(self) -> None:
        """Stop the worker (asked first, killed after :data:`STOP_TIMEOUT_S`)."""
        if self._process is None:
            return
        try:
            self._requests.send(("stop", None))
            self._process.wait(STOP_TIMEOUT_S)
        except (BrokenPipeError, OSError, subprocess.TimeoutExpired) as exc:
            _LOG.debug("solver worker not stopped by request (%s): killing it", exc)
        self._kill()

    @property
    def pid(self) -> int | None:
        """The worker process id (None between a kill and the next start)."""
        return None if self._process is None else self._process.pid

    # --- solving -------------------------------------------------------------------------
    def _wait_readable(self, timeout_s: float) -> bool:
        """Poll the pipe in slices, ending early when ``abandon()`` says so."""
        end = time.monotonic() + timeout_s
        while True:
            remaining = end - time.monotonic()
            if remaining <= 0.0:
                return False
            if self._answers.poll(min(POLL_PERIOD_S, remaining)):
                return True
            if self.abandon is not None and self.abandon():
                return False

    def solve(self, data: ProblemInstance) -> SolverResult:
        """The back-end's answer, or a failed result (``status`` says why) within the deadline."""
        started = time.monotonic()
        bad = non_finite_fields(data)
        if bad:
            _LOG.warning("non-finite problem data (%s): not solved", ", ".join(bad))
            return failed_result(data, STATUS_NON_FINITE_DATA, 0.0)
        if not self._alive():
            self._restart("died" if self._process is not None else "missing")
        if not self._ready:
            try:
                if self.wait_for_start:
                    self._await_ready(self.start_timeout_s)
                    started = time.monotonic()
                else:
                    self._await_ready(self.deadline_s)
            except WorkerStartError as exc:
                _LOG.error("%s", exc)
                return failed_result(data, STATUS_WORKER_DIED, time.monotonic() - started)
            if not self._ready:
                starting_s = time.monotonic() - self._started_at
                if self.wait_for_start or starting_s > self.start_timeout_s:
                    self._restart(f"not ready after {self.start_timeout_s:g} s")
                return failed_result(data, STATUS_WORKER_STARTING, time.monotonic() - started)
        sent = time.monotonic()
        try:
            self._requests.send(("solve", data))
        except (BrokenPipeError, OSError):
            self._restart("gone")
            return failed_result(data, STATUS_WORKER_DIED, time.monotonic() - started)
        answered = self._wait_readable(self.deadline_s - (sent - started))
        if not answered:
            elapsed = time.monotonic() - started
            abandoned = self.abandon is not None and self.abandon()
            status = STATUS_ABANDONED if abandoned else STATUS_DEADLINE_MISSED
            if not abandoned:
                self.deadline_misses += 1
            _LOG.warning(
                "solve %s after %.3f s (deadline %.3f s): killing the solver worker",
                status,
                elapsed,
                self.deadline_s,
            )
            self._restart(status)
            return failed_result(data, status, time.monotonic() - started)
        try:
            kind, payload = self._answers.recv()
        except EOFError:
            self._restart("died during a solve")
            return failed_result(data, STATUS_WORKER_DIED, time.monotonic() - started)
        if kind == "error":
            raise RuntimeError(f"solver worker: {payload}")
        # the time the caller waited, the transfer to and from the worker included
        return replace(payload, solve_time_s=time.monotonic() - started)


if __name__ == "__main__":
    raise SystemExit(worker_main())
