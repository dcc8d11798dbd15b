"""Choosing a ROS domain nobody else uses, and processes that die with their parent."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from splitter_msgs_py import domains
from splitter_msgs_py.domains import (
    CHOSEN,
    NAMED_BY_ENV,
    NAMED_BY_OPTION,
    NoFreeDomainError,
    choose_domain,
    domain_ports,
    hold_domains,
    user_domain_id,
)

# candidates of these tests: high in the safe range (1-100), away from the test suite's
# own domains (conftest holds them anyway) and checked free before each test
CANDIDATES = (97, 98, 99)


@pytest.fixture(autouse=True)
def private_locks(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Lock files of this test only (the machine's real runs never see them)."""
    monkeypatch.setenv(domains.LOCK_DIR_ENV, str(tmp_path / "locks"))


def free_candidates() -> tuple[int, ...]:
    ports = domains.bound_udp_ports()
    free = tuple(d for d in CANDIDATES if not domains.sockets_on_domain(d, ports))
    if len(free) < 2:
        pytest.skip(f"domains {CANDIDATES} in use on this machine")
    return free


def test_the_rtps_port_block_of_a_domain() -> None:
    assert domain_ports(0) == range(7400, 7650)
    assert domain_ports(7)[10] == 9160  # a participant's metatraffic port, seen bound
    assert domains.auto_domains()[0] == 1
    assert domain_ports(domains.auto_domains()[-1])[-1] < domains.ephemeral_port_low()


def test_a_named_domain_wins_the_option_before_the_environment() -> None:
    env = {"ROS_DOMAIN_ID": "17"}
    with choose_domain(23, env) as choice:
        assert (choice.domain_id, choice.named_by) == (23, NAMED_BY_OPTION)
    with choose_domain(None, env) as choice:
        assert (choice.domain_id, choice.named_by) == (17, NAMED_BY_ENV)
    assert user_domain_id({"ROS_DOMAIN_ID": " "}) is None
    with pytest.raises(ValueError, match="integer"):
        user_domain_id({"ROS_DOMAIN_ID": "forty"})
    with pytest.raises(ValueError, match="0, 232"):
        choose_domain(233, {})


def test_two_runs_choosing_at_once_never_share_a_domain() -> None:
    free = free_candidates()
    with (
        choose_domain(None, {}, candidates=free) as first,
        choose_domain(None, {}, candidates=free) as second,
    ):
        assert first.named_by == second.named_by == CHOSEN
        assert first.domain_id != second.domain_id
        assert f"ROS_DOMAIN_ID={first.domain_id}" in first.describe()
    with choose_domain(None, {}, candidates=free) as again:  # released: free again
        assert again.domain_id in free


def test_a_domain_someone_named_or_binds_is_not_chosen() -> None:
    free = free_candidates()
    with hold_domains([free[0]]):
        with choose_domain(None, {}, candidates=free) as choice:
            assert choice.domain_id != free[0]
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.bind(("127.0.0.1", domain_ports(free[1])[10]))  # a participant of another tool
        with choose_domain(None, {}, candidates=free[:2]) as choice:
            assert choice.domain_id == free[0]
        with pytest.raises(NoFreeDomainError, match="in use"):
            choose_domain(None, {}, candidates=[free[1]])
    finally:
        sock.close()


def test_a_killed_run_gives_its_domain_back(tmp_path: Path) -> None:
    free = free_candidates()
    script = textwrap.dedent(
        f"""
        import time
        from splitter_msgs_py.domains import choose_domain
        choice = choose_domain(None, {{}}, candidates={free[:1]!r})
        print(choice.domain_id, flush=True)
        time.sleep(60)
        """
    )
    holder = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    try:
        assert int(holder.stdout.readline()) == free[0]
        with pytest.raises(NoFreeDomainError):
            choose_domain(None, {}, candidates=free[:1])
    finally:
        holder.kill()
        holder.wait()
    with choose_domain(None, {}, candidates=free[:1]) as choice:
        assert choice.domain_id == free[0]


def test_a_child_dies_with_its_parent_however_the_parent_ends() -> None:
    """A parent starts a child that asks for the parent-death signal; SIGKILL the parent."""
    child = textwrap.dedent(
        """
        import os, sys, time
        from splitter_msgs_py.lifetime import die_with_parent_from_env
        assert die_with_parent_from_env()
        print(os.getpid(), flush=True)
        time.sleep(60)
        """
    )
    parent = textwrap.dedent(
        f"""
        import os, subprocess, sys, time
        env = dict(os.environ, SPLITTER_PARENT_PID=str(os.getpid()))
        child = subprocess.Popen([sys.executable, "-c", {child!r}], env=env,
                                 start_new_session=True)
        time.sleep(60)
        """
    )
    proc = subprocess.Popen([sys.executable, "-c", parent], stdout=subprocess.PIPE, text=True)
    try:
        child_pid = int(proc.stdout.readline())
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        deadline = time.monotonic() + 2.0
        while Path(f"/proc/{child_pid}").exists() and time.monotonic() < deadline:
            time.sleep(0.02)
        alive = Path(f"/proc/{child_pid}").exists()
        if alive:
            os.kill(child_pid, signal.SIGKILL)
        assert not alive, "the child outlived its parent's SIGKILL by 2 s"
    finally:
        if proc.poll() is None:
            proc.kill()


def test_a_child_whose_parent_is_already_gone_exits() -> None:
    code = subprocess.run(
        [
            sys.executable,
            "-c",
            "from splitter_msgs_py.lifetime import die_with_parent; die_with_parent(1)",
        ],
        check=False,
        timeout=30,
    ).returncode
    assert code == 1
