"""Which ROS domain a graph runs on: the one the user named, or one nobody else uses.

ROS-free. The rule (README "Networking"):

* a domain the user names is used as it is: ``--domain-id N`` first, else a
  non-empty ``ROS_DOMAIN_ID`` in the environment (a test, a shell, a CI job that
  exports it on purpose);
* otherwise the run chooses a domain in :func:`auto_domains` that no other graph on
  this machine uses, and holds it for its lifetime.

"Uses" is judged two ways, so that two runs started at the same instant never pick
the same domain and a graph started by any other tool is seen too:

* a lock file per domain (``<lock dir>/domain-<N>.lock``, :func:`lock_dir`) held
  with ``flock`` for the run's life: exclusive by a run that chose it, shared by a
  user who named it (runs pinned to one domain may share it; a chooser skips it).
  The kernel drops the lock when its process ends, however it ends;
* the UDP ports of the domain's RTPS port block (``7400 + 250 N`` and the 250
  above it, :func:`domain_ports`): any socket bound there (``/proc/net/udp``,
  ``/proc/net/udp6``) is a DDS participant on that domain.
"""

from __future__ import annotations

import fcntl
import logging
import os
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

LOG = logging.getLogger(__name__)

PORT_BASE = 7400  # [port] RTPS port mapping PB (DDSI-RTPS 2.x, section 9.6.1.1)
DOMAIN_GAIN = 250  # [ports] DG: the port block of one domain
MAX_DOMAIN_ID = 232  # above it Fast DDS exits: "port number is too high"
FIRST_AUTO_DOMAIN = 1  # 0 is ROS's default domain, where every unconfigured tool lands
LOCK_DIR_ENV = "SPLITTER_DOMAIN_LOCK_DIR"
DEFAULT_EPHEMERAL_LOW = 32768  # [port] Linux default of net.ipv4.ip_local_port_range
UDP_TABLES = (Path("/proc/net/udp"), Path("/proc/net/udp6"))

NAMED_BY_OPTION = "--domain-id"
NAMED_BY_ENV = "ROS_DOMAIN_ID"
CHOSEN = "chosen"


class NoFreeDomainError(RuntimeError):
    """Every domain a run may choose is in use."""


def domain_ports(domain_id: int) -> range:
    """UDP ports of the RTPS port block of ``domain_id``."""
    start = PORT_BASE + DOMAIN_GAIN * domain_id
    return range(start, start + DOMAIN_GAIN)


def ephemeral_port_low(path: Path = Path("/proc/sys/net/ipv4/ip_local_port_range")) -> int:
    """Lowest port the kernel hands out to unbound sockets (their send sockets, anyone's)."""
    try:
        return int(path.read_text().split()[0])
    except (OSError, ValueError, IndexError) as exc:
        LOG.debug("%s unreadable (%s): assuming %d", path, exc, DEFAULT_EPHEMERAL_LOW)
        return DEFAULT_EPHEMERAL_LOW


def auto_domains() -> range:
    """Domains a run may choose: 1 up to the last whose port block ends below the ephemeral
    range (1-100 on a default Linux; ROS documents 0-101 as safe)."""
    last = (ephemeral_port_low() - PORT_BASE) // DOMAIN_GAIN - 1
    return range(FIRST_AUTO_DOMAIN, min(last, MAX_DOMAIN_ID) + 1)


def bound_udp_ports(tables: Sequence[Path] = UDP_TABLES) -> set[int]:
    """Local ports of every UDP socket on this machine (empty where /proc/net is missing)."""
    ports: set[int] = set()
    for table in tables:
        try:
            lines = table.read_text().splitlines()[1:]
        except OSError as exc:
            LOG.debug("%s unreadable (%s): its sockets are not probed", table, exc)
            continue
        for line in lines:
            fields = line.split()
            if len(fields) > 1 and ":" in fields[1]:
                ports.add(int(fields[1].rsplit(":", 1)[1], 16))
    return ports


def sockets_on_domain(domain_id: int, ports: Iterable[int]) -> list[int]:
    """The ``ports`` in the port block of ``domain_id``."""
    block = domain_ports(domain_id)
    return sorted(p for p in ports if p in block)


def lock_dir() -> Path:
    """Folder of the per-domain lock files (``$SPLITTER_DOMAIN_LOCK_DIR``, else one in the
    system's temporary folder shared by every user: sticky and world-writable, as /tmp)."""
    override = os.environ.get(LOCK_DIR_ENV)
    if override:
        return Path(override)
    return Path(tempfile.gettempdir()) / "splitter-ros-domains"


def _open_lock(directory: Path, domain_id: int) -> int:
    if not directory.is_dir():
        directory.mkdir(parents=True, exist_ok=True)
        try:
            directory.chmod(0o1777)
        except PermissionError:  # made by another user in the same instant: theirs to set
            pass
    return os.open(directory / f"domain-{domain_id}.lock", os.O_RDONLY | os.O_CREAT, 0o644)


def _try_lock(directory: Path, domain_id: int, operation: int) -> int | None:
    """An open descriptor holding ``operation`` on the domain's lock file, or None when held."""
    fd = _open_lock(directory, domain_id)
    try:
        fcntl.flock(fd, operation | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        return None
    return fd


def user_domain_id(env: Mapping[str, str] | None = None) -> int | None:
    """The domain ``env``'s ``ROS_DOMAIN_ID`` names (None when unset or empty)."""
    env = os.environ if env is None else env
    text = env.get(NAMED_BY_ENV, "").strip()
    if not text:
        return None
    try:
        value = int(text)
    except ValueError as exc:
        raise ValueError(f"ROS_DOMAIN_ID must be an integer, got {text!r}") from exc
    _check(value)
    return value


def _check(domain_id: int) -> None:
    if not 0 <= domain_id <= MAX_DOMAIN_ID:
        raise ValueError(f"ROS domain id must be in [0, {MAX_DOMAIN_ID}], got {domain_id}")


@dataclass
class DomainChoice:
    """The domain a run uses and the lock that marks it used; release it at the run's end."""

    domain_id: int
    named_by: str  # NAMED_BY_OPTION, NAMED_BY_ENV or CHOSEN
    _fds: list[int] = field(default_factory=list, repr=False)

    def describe(self) -> str:
        """One line for the user: which domain, why, and how to join it."""
        why = (
            "chosen: no other graph on this machine uses it"
            if self.named_by == CHOSEN
            else f"named by {self.named_by}"
        )
        return f"ROS domain {self.domain_id} ({why}); join it with ROS_DOMAIN_ID={self.domain_id}"

    def release(self) -> None:
        """Give the domain back (closing the lock files drops their locks)."""
        while self._fds:
            os.close(self._fds.pop())

    def __enter__(self) -> DomainChoice:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def hold_domains(domain_ids: Iterable[int], named_by: str = NAMED_BY_ENV) -> DomainChoice:
    """Mark ``domain_ids`` used by this process (shared locks): runs choosing a domain skip
    them. The first one is the choice's ``domain_id``. A domain another run chose (its
    exclusive lock) is used anyway, with a warning: the user named it."""
    ids = list(domain_ids)
    if not ids:
        raise ValueError("no domain to hold")
    directory = lock_dir()
    choice = DomainChoice(ids[0], named_by)
    for domain_id in ids:
        _check(domain_id)
        fd = _try_lock(directory, domain_id, fcntl.LOCK_SH)
        if fd is None:
            LOG.warning(
                "ROS domain %d (named by %s) is in use by a graph that chose it: "
                "the two will see each other",
                domain_id,
                named_by,
            )
        else:
            choice._fds.append(fd)
    return choice


def choose_domain(
    requested: int | None = None,
    env: Mapping[str, str] | None = None,
    candidates: Iterable[int] | None = None,
) -> DomainChoice:
    """The domain of a run (module doc): ``requested`` (``--domain-id``), else ``env``'s
    ``ROS_DOMAIN_ID``, else a free one from ``candidates`` (default :func:`auto_domains`,
    tried from a start that depends on this process's id), locked until
    :meth:`DomainChoice.release`. Raises :class:`NoFreeDomainError` when none is free."""
    if requested is not None:
        _check(requested)
        named: tuple[int, str] | None = (requested, NAMED_BY_OPTION)
    else:
        from_env = user_domain_id(env)
        named = None if from_env is None else (from_env, NAMED_BY_ENV)
    if named is not None:
        domain_id, named_by = named
        busy = sockets_on_domain(domain_id, bound_udp_ports())
        if busy:
            LOG.info(
                "ROS domain %d (named by %s): %d UDP sockets are already bound in its "
                "port block (another participant on it: the graph reports foreign publishers)",
                domain_id,
                named_by,
                len(busy),
            )
        return hold_domains([domain_id], named_by)
    order = list(auto_domains() if candidates is None else candidates)
    if not order:
        raise NoFreeDomainError("no ROS domain to choose from")
    start = os.getpid() % len(order)
    order = order[start:] + order[:start]
    directory = lock_dir()
    for domain_id in order:
        fd = _try_lock(directory, domain_id, fcntl.LOCK_EX)
        if fd is None:
            continue
        # probed after taking the lock: a run that locked it first is seen by its lock, one
        # that started before us (or a graph of any other tool) by its sockets
        if sockets_on_domain(domain_id, bound_udp_ports()):
            os.close(fd)
            continue
        return DomainChoice(domain_id, CHOSEN, [fd])
    raise NoFreeDomainError(
        f"every ROS domain in {min(order)}..{max(order)} is in use on this machine: "
        "name one with --domain-id or ROS_DOMAIN_ID"
    )
