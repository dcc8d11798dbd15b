"""The workspace builds with colcon inside the virtual environment and its scripts start."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from splitter_msgs_py.environment import ros_environment

ROOT = Path(__file__).resolve().parents[1]
WORKSPACE = ROOT / "splitter_ws"
COLCON = Path(sys.executable).with_name("colcon")

# One installed console script per package: (package, script, extra args, runs until stopped)
SCRIPTS = [
    ("splitter_bringup", "splitter", ["--help"], False),
    ("splitter_sim", "simulator", ["--ros-args", "-p", "mode:=real_time"], True),
    ("splitter_mpc", "gait_phase_manager", [], True),
    ("splitter_ik", "ik_tether_allocator", [], True),
    ("splitter_msgs_py", "recorder", [], True),
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
    assert "6 packages finished" in result.stdout
    return base / "install"


def test_colcon_installs_data_files(colcon_install: Path) -> None:
    site = next(colcon_install.glob("splitter_bringup/lib/python3*/site-packages"))
    assert (site / "splitter_bringup/scenarios/spin_stabilization.yaml").is_file()
    dds = next(colcon_install.glob("splitter_msgs_py/lib/python3*/site-packages"))
    assert (dds / "splitter_msgs_py/dds/fastdds_loopback.xml").is_file()
    for package in (
        "splitter_msgs_py",
        "splitter_model",
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
