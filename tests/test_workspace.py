"""The workspace builds with colcon inside the virtual environment and its scripts start.

Two builds, the two the README gives: its ``make colcon`` block (``colcon build
--symlink-install`` through the Makefile, then a node from the install space), run as
written on a clean copy of the tree, and a plain ``colcon build`` (the full ROS 2
install's command).
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from splitter_msgs_py.environment import loopback_profile_path, ros_environment

ROOT = Path(__file__).resolve().parents[1]
WORKSPACE = ROOT / "splitter_ws"
COLCON = Path(sys.executable).with_name("colcon")
PACKAGES = (
    "splitter_msgs_py",
    "splitter_model",
    "splitter_bag",
    "splitter_sim",
    "splitter_mpc",
    "splitter_ik",
    "splitter_bringup",
    "splitter_tools",
)
# What a clone holds that `make colcon` reads: the Makefile, the pins and the workspace.
CLONE_PATHS = ("Makefile", "requirements.txt", "splitter_ws")
# The Makefile's install stamp (`$(STAMP)`, inside the virtual environment).
STAMP = ".venv/.splitter-installed"
NODE_READY_S = 60.0  # [s] wall limit for the simulator's "ready" log line

# One installed console script per package: (package, script, extra args, runs until stopped)
SCRIPTS = [
    ("splitter_bringup", "splitter", ["--help"], False),
    ("splitter_sim", "simulator", ["--ros-args", "-p", "mode:=real_time"], True),
    ("splitter_mpc", "gait_phase_manager", [], True),
    ("splitter_ik", "ik_tether_allocator", [], True),
    ("splitter_bag", "recorder", [], True),
]


@pytest.fixture(scope="module")
def colcon_install(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if not COLCON.exists():
        pytest.fail(f"colcon is not installed in the virtual environment ({COLCON})")
    base = tmp_path_factory.mktemp("colcon")
    result = subprocess.run(
        [
            str(COLCON),
            "--log-base",
            str(base / "log"),
            "build",
            "--build-base",
            str(base / "build"),
            "--install-base",
            str(base / "install"),
        ],
        cwd=WORKSPACE,
        env=ros_environment(),
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    assert f"{len(PACKAGES)} packages finished" in result.stdout
    return base / "install"


def test_colcon_installs_data_files(colcon_install: Path) -> None:
    site = next(colcon_install.glob("splitter_bringup/lib/python3*/site-packages"))
    assert (site / "splitter_bringup/scenarios/spin_stabilization.yaml").is_file()
    dds = next(colcon_install.glob("splitter_msgs_py/lib/python3*/site-packages"))
    assert (dds / "splitter_msgs_py/dds/fastdds_loopback.xml").is_file()
    for package in (
        "splitter_msgs_py",
        "splitter_model",
        "splitter_bag",
        "splitter_sim",
        "splitter_mpc",
        "splitter_ik",
    ):
        marker = colcon_install / package / "share/ament_index/resource_index/packages" / package
        assert marker.exists(), marker


@pytest.mark.parametrize(("package", "script", "args", "long_running"), SCRIPTS)
def test_installed_console_script_starts(
    colcon_install: Path,
    package: str,
    script: str,
    *,
    args: list[str],
    long_running: bool,
    tmp_path: Path,
) -> None:
    path = colcon_install / package / "lib" / package / script
    assert path.exists(), f"{path} not installed"
    env = ros_environment()
    site_dirs = [str(p) for p in colcon_install.glob("*/lib/python3*/site-packages")]
    env["PYTHONPATH"] = os.pathsep.join(site_dirs)
    if not long_running:
        out = subprocess.run(
            [str(path), *args], env=env, capture_output=True, text=True, timeout=60, check=False
        )
        assert out.returncode == 0, out.stderr
        assert "usage" in out.stdout.lower()
        return
    proc = subprocess.Popen(
        [str(path), *args],
        env=env,
        cwd=tmp_path,  # a recorder writes its default bag folder here
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        time.sleep(4.0)
        assert proc.poll() is None, (
            f"{script} exited early:\n{proc.stdout.read() if proc.stdout else ''}"
        )
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            output, _ = proc.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            output, _ = proc.communicate()
    assert proc.returncode == 0, output
    assert "Traceback" not in output, output


# --- `make colcon`, the README's commands, on a clean copy of the tree ----------------------


def readme_make_colcon_block() -> list[str]:
    """The README's shell block that starts with ``make colcon``, one command per line."""
    blocks = re.findall(r"^```bash\n(.*?)^```", (ROOT / "README.md").read_text(), re.S | re.M)
    for block in blocks:
        lines = [re.sub(r"\s+#\s.*$", "", line).strip() for line in block.splitlines()]
        lines = [line for line in lines if line]
        if lines and lines[0] == "make colcon":
            return lines
    pytest.fail("README.md has no ```bash block starting with `make colcon`")


def _clean_copy(dest: Path) -> None:
    """Copy what a clone of the working tree holds (tracked and new files, nothing ignored)."""
    listed = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard", "--", *CLONE_PATHS],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split("\0")
    for name in filter(None, listed):
        source = ROOT / name
        if source.is_file():  # a tracked file deleted in the working tree is not copied
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, dest / name)


def _user_bash(script: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """``script`` in bash, in a user's shell environment (:func:`_user_environment`)."""
    return subprocess.run(
        ["bash", "-c", script],
        cwd=cwd,
        env=_user_environment(),
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )


def _user_environment() -> dict[str, str]:
    """A shell's environment without what the Makefile or the test suite exported for ROS.

    The ROS domain stays the test run's own.
    """
    env = dict(os.environ)
    for variable in (
        "MAKEFLAGS",  # when the suite runs under make
        "MAKELEVEL",
        "MFLAGS",
        "AMENT_PREFIX_PATH",
        "PYTHONPATH",
        "FASTRTPS_DEFAULT_PROFILES_FILE",
        "FASTDDS_DEFAULT_PROFILES_FILE",
        "ROS_AUTOMATIC_DISCOVERY_RANGE",
    ):
        env.pop(variable, None)
    return env


@pytest.fixture(scope="module")
def make_colcon(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """The README's `make colcon` in a clean copy of the tree; the copy's root and output.

    The copy's ``.venv`` is this virtual environment (a fresh clone would create and fill
    one, minutes of pip: ``make`` does that part for every other target too). ``-o`` keeps
    make from reinstalling the packages of the copy into it; the colcon command line is the
    Makefile's own.
    """
    make = shutil.which("make")
    if make is None:
        pytest.fail("make is not installed")
    assert readme_make_colcon_block()[0] == "make colcon"
    clone = tmp_path_factory.mktemp("clone")
    _clean_copy(clone)
    workspace = clone / "splitter_ws"
    assert (workspace / "src").is_dir()
    assert not any((workspace / d).exists() for d in ("build", "install", "log"))
    (clone / ".venv").symlink_to(sys.prefix, target_is_directory=True)
    planned = subprocess.run(
        [make, "-n", "-o", STAMP, "colcon"],
        cwd=clone,
        env=_user_environment(),
        capture_output=True,
        text=True,
        check=True,
    ).stdout.splitlines()
    # nothing but the colcon build (no pip into this venv)
    assert len(planned) == 1 and "colcon build --symlink-install" in planned[0], planned
    result = subprocess.run(
        [make, "-o", STAMP, "colcon"],
        cwd=clone,
        env=_user_environment(),
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    output = result.stdout + result.stderr
    assert result.returncode == 0, output[-6000:]
    return clone, output


def test_make_colcon_builds_every_package(make_colcon: tuple[Path, str]) -> None:
    clone, output = make_colcon
    assert re.search(rf"^Summary: {len(PACKAGES)} packages finished", output, re.MULTILINE), output[
        -3000:
    ]
    for package in PACKAGES:
        assert re.search(rf"^Finished <<< {package} ", output, re.MULTILINE), package
    # A symlink install indeed, not colcon's fallback to a copy when setuptools lacks
    # `develop --editable` (colcon-core >= 0.21 copies, with only an INFO line in its log).
    colcon_log = (clone / "splitter_ws/log/latest_build/logger_all.log").read_text()
    assert "falling back" not in colcon_log
    install = clone / "splitter_ws" / "install"
    for package in PACKAGES:
        links = list(install.glob(f"{package}/lib/python3*/site-packages/*.egg-link"))
        assert len(links) == 1, f"{package}: no develop link in {install / package}"


def test_make_colcon_install_space_imports_the_sources(make_colcon: tuple[Path, str]) -> None:
    """Sourced, the install space imports each package from the copy's sources (symlinked)."""
    clone, _ = make_colcon
    workspace = clone / "splitter_ws"
    imports = "; ".join(f"import {p}; print({p}.__file__)" for p in PACKAGES)
    located = _user_bash(
        f'source install/setup.bash && exec "{sys.executable}" -c "{imports}"', workspace
    )
    assert located.returncode == 0, located.stderr
    files = [Path(line).resolve() for line in located.stdout.split()]
    for package, file in zip(PACKAGES, files, strict=True):
        # the source file itself, so an edit needs no rebuild
        assert file.is_relative_to((workspace / "src" / package).resolve()), (package, file)


def test_readme_node_starts_from_the_install_space(
    make_colcon: tuple[Path, str], tmp_path: Path
) -> None:
    """The README's lines after `make colcon`, as written: the simulator starts on loopback DDS."""
    clone, _ = make_colcon
    commands = readme_make_colcon_block()[1:]
    assert commands, "the README starts no node after `make colcon`"
    setup, start = "\n".join(["set -e", *commands[:-1]]), commands[-1]
    # Before any node runs: the environment the lines before it leave is loopback-only.
    printed = _user_bash(setup + "\nenv -0", clone)
    assert printed.returncode == 0, printed.stderr
    environ = dict(item.split("=", 1) for item in printed.stdout.split("\0") if "=" in item)
    profile = Path(environ.get("FASTRTPS_DEFAULT_PROFILES_FILE", "/nonexistent"))
    assert profile.is_file(), environ.get("FASTRTPS_DEFAULT_PROFILES_FILE")
    assert profile.resolve().is_relative_to(clone.resolve()), profile
    assert profile.read_bytes() == loopback_profile_path().read_bytes()
    assert environ.get("FASTDDS_DEFAULT_PROFILES_FILE") == str(profile)
    assert environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE") == "SUBNET"

    log = tmp_path / "node.log"
    with log.open("w") as sink:
        proc = subprocess.Popen(
            ["bash", "-c", setup + "\nexec " + start],
            cwd=clone,
            env=_user_environment(),
            stdout=sink,
            stderr=subprocess.STDOUT,
        )
    try:
        deadline = time.monotonic() + NODE_READY_S
        while "simulator ready" not in log.read_text() and proc.poll() is None:
            assert time.monotonic() < deadline, f"no 'simulator ready' in {NODE_READY_S} s"
            time.sleep(0.2)
        assert proc.poll() is None, f"the node exited early:\n{log.read_text()}"
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    output = log.read_text()
    assert proc.returncode == 0, output
    assert "Traceback" not in output, output
