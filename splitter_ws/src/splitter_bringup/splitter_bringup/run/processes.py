"""Supervise the node graph's processes: start, stream output, stop cleanly, report deaths.

ROS-free. Each node runs as its own process (DESIGN.md section 2); the
supervisor prefixes their output, stops every child on Ctrl-C or SIGTERM
(SIGINT first so recorders finish their bags, then SIGTERM, then SIGKILL),
and tells the caller which process ended and how.
"""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

LOG = logging.getLogger(__name__)


@dataclass(frozen=True)
class ProcessSpec:
    """One child process: a name for logs, its command line and environment."""

    name: str
    argv: tuple[str, ...]
    env: Mapping[str, str]
    # A process whose exit ends the run normally (the simulator at the end of the scenario).
    ends_run: bool = False
    # Stopped only after every other child has exited (the recorder: it takes the last
    # messages the others sent before they stopped).
    stops_last: bool = False


def node_argv(entry: str, params_file: Path | None, extra_ros_args: Sequence[str] = ()) -> tuple:
    """Command line running ``module:function`` as a ROS node with a parameter file."""
    argv = [sys.executable, "-m", "splitter_bringup.run.node_runner", entry, "--ros-args"]
    if params_file is not None:
        argv += ["--params-file", str(params_file)]
    argv += list(extra_ros_args)
    return tuple(argv)


@dataclass
class RunningProcess:
    """A started child and the thread forwarding its output."""

    spec: ProcessSpec
    popen: subprocess.Popen
    reader: threading.Thread
    lines: list[str] = field(default_factory=list)


class Supervisor:
    """Start children, forward their output line by line, stop them in order."""

    def __init__(
        self,
        on_line: Callable[[str, str], None] | None = None,
        log_dir: Path | None = None,
    ) -> None:
        self._on_line = on_line or (lambda name, line: print(f"[{name}] {line}", flush=True))
        self._log_dir = log_dir
        self.children: list[RunningProcess] = []
        self._stop_requested = threading.Event()
        self._failure: str | None = None

    def start(self, spec: ProcessSpec) -> RunningProcess:
        """Start ``spec`` in its own process group, output forwarded to ``on_line``."""
        popen = subprocess.Popen(
            spec.argv,
            env=dict(spec.env),
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            text=True,
            bufsize=1,
            start_new_session=True,
        )
        child = RunningProcess(spec, popen, threading.Thread())
        log_file = None
        if self._log_dir is not None:
            self._log_dir.mkdir(parents=True, exist_ok=True)
            log_file = (self._log_dir / f"{spec.name}.log").open("w", encoding="utf-8")

        if popen.stdout is None:
            raise RuntimeError(f"{spec.name}: no output pipe")

        def forward() -> None:
            try:
                for raw in popen.stdout:
                    line = raw.rstrip("\n")
                    child.lines.append(line)
                    if log_file is not None:
                        log_file.write(raw)
                        log_file.flush()
                    self._on_line(spec.name, line)
            finally:
                if log_file is not None:
                    log_file.close()

        child.reader = threading.Thread(target=forward, name=f"out-{spec.name}", daemon=True)
        child.reader.start()
        self.children.append(child)
        LOG.info("started %s (pid %d)", spec.name, popen.pid)
        return child

    def request_stop(self) -> None:
        """Ask :meth:`wait` to return (signal handlers call this)."""
        self._stop_requested.set()

    def fail(self, outcome: str) -> None:
        """Make :meth:`wait` return ``(outcome, None)`` (a watchdog found the run stuck)."""
        self._failure = outcome
        self._stop_requested.set()

    def wait(
        self,
        timeout_s: float | None = None,
        poll_s: float = 0.05,
        ignore: Collection[str] = (),
    ) -> tuple[str, int | None]:
        """Block until a child exits, a stop is requested or ``timeout_s`` passes.

        Returns ``("ended", code)`` when a process with ``ends_run`` exited,
        ``("died:<name>", code)`` when any other child exited (but those in
        ``ignore``), ``("stopped", None)`` on a stop request, the outcome given to
        :meth:`fail`, and ``("timeout", None)`` when time ran out.
        """
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        while True:
            for child in self.children:
                code = child.popen.poll()
                if code is not None and child.spec.name not in ignore:
                    if child.spec.ends_run:
                        return "ended", code
                    return f"died:{child.spec.name}", code
            if self._stop_requested.is_set():
                return self._failure or "stopped", None
            if deadline is not None and time.monotonic() > deadline:
                return "timeout", None
            time.sleep(poll_s)

    def stop_all(self, grace_s: float = 10.0) -> dict[str, int | None]:
        """Stop every child: SIGINT, then SIGTERM, then SIGKILL.

        Children with ``stops_last`` are stopped only once all the others have exited, so a
        recorder receives everything they published until their end. Returns each child's
        exit code.
        """
        first = [c for c in reversed(self.children) if not c.spec.stops_last]
        last = [c for c in reversed(self.children) if c.spec.stops_last]
        for group in (first, last):
            self._stop_group(group, grace_s)
        for child in self.children:
            child.reader.join(timeout=2.0)
        return {c.spec.name: c.popen.returncode for c in self.children}

    def _stop_group(self, children: list[RunningProcess], grace_s: float) -> None:
        for child in children:
            self._signal(child, signal.SIGINT)
        self._wait_children(grace_s, children)
        for child in children:
            if child.popen.poll() is None:
                LOG.warning(
                    "%s did not stop on SIGINT within %.0f s: SIGTERM", child.spec.name, grace_s
                )
                self._signal(child, signal.SIGTERM)
        self._wait_children(grace_s / 2, children)
        for child in children:
            if child.popen.poll() is None:
                LOG.error("%s did not stop on SIGTERM: SIGKILL", child.spec.name)
                self._signal(child, signal.SIGKILL)
                child.popen.wait()

    def stop_one(self, name: str, grace_s: float = 10.0) -> int | None:
        """Stop one child with SIGINT (SIGKILL after ``grace_s``); its exit code."""
        for child in self.children:
            if child.spec.name == name:
                self._signal(child, signal.SIGINT)
                try:
                    return child.popen.wait(timeout=grace_s)
                except subprocess.TimeoutExpired:
                    self._signal(child, signal.SIGKILL)
                    return child.popen.wait()
        raise KeyError(name)

    def _wait_children(
        self, timeout_s: float, children: list[RunningProcess] | None = None
    ) -> None:
        deadline = time.monotonic() + timeout_s
        for child in self.children if children is None else children:
            remaining = max(0.0, deadline - time.monotonic())
            try:
                child.popen.wait(timeout=remaining)
            except subprocess.TimeoutExpired:
                pass

    @staticmethod
    def _signal(child: RunningProcess, sig: signal.Signals) -> None:
        if child.popen.poll() is None:
            try:
                os.killpg(child.popen.pid, sig)
                if sig != signal.SIGKILL:  # a stopped (SIGSTOP) process handles it once continued
                    os.killpg(child.popen.pid, signal.SIGCONT)
            except ProcessLookupError:
                pass


def install_stop_handlers(supervisor: Supervisor) -> Callable[[], None]:
    """Route SIGINT and SIGTERM to ``supervisor.request_stop``; returns a restore function."""
    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}

    def handler(signum: int, _frame: object) -> None:
        LOG.info("received %s: stopping every node", signal.Signals(signum).name)
        supervisor.request_stop()

    for sig in previous:
        signal.signal(sig, handler)

    def restore() -> None:
        for sig, old in previous.items():
            signal.signal(sig, old)

    return restore
