"""A process that ends with the process that started it, however that one ends.

ROS-free, Linux. A launcher that dies (SIGKILL, an OOM kill, a CI timeout) cannot
stop its children; the kernel can: ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` makes it
kill this process when its parent ends. The request is made by the child after it
started, so a parent that died in between is caught by comparing ``os.getppid()``
with the parent's pid the launcher passed (:data:`PARENT_PID_ENV`). The MPC's solver
worker does the same towards its node (``splitter_mpc.core.solver_worker``), so a
whole graph ends with its launcher.

Linux sends the signal when the parent *thread* that started the child ends: the
launcher starts its nodes from the thread that waits for them.
"""

from __future__ import annotations

import ctypes
import logging
import os
import signal
from collections.abc import Mapping

LOG = logging.getLogger(__name__)
PARENT_PID_ENV = "SPLITTER_PARENT_PID"  # set by the launcher for each node it starts
_PR_SET_PDEATHSIG = 1  # prctl option (linux/prctl.h)


def die_with_parent(parent_pid: int, sig: int = signal.SIGKILL) -> bool:
    """Have the kernel send ``sig`` to this process when its parent ends.

    Exits at once (code 1) when the parent is already gone (``os.getppid()`` is no
    longer ``parent_pid``). False when the platform has no ``prctl`` (the process then
    outlives a killed parent).
    """
    try:
        libc = ctypes.CDLL("libc.so.6", use_errno=True)
    except OSError as exc:
        LOG.warning("no parent-death signal on this platform (%s)", exc)
        return False
    if libc.prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0) != 0:
        errno = ctypes.get_errno()
        raise OSError(errno, f"prctl(PR_SET_PDEATHSIG): {os.strerror(errno)}")
    if os.getppid() != parent_pid:  # the parent died before the request took effect
        os._exit(1)
    return True


def die_with_parent_from_env(env: Mapping[str, str] | None = None) -> bool:
    """:func:`die_with_parent` towards the pid in :data:`PARENT_PID_ENV`, when it is set."""
    env = os.environ if env is None else env
    text = env.get(PARENT_PID_ENV, "").strip()
    if not text:
        return False
    return die_with_parent(int(text))
