"""``splitter run`` with the library backend: files, summary beside the paper, bad input."""

from __future__ import annotations

import json

import numpy as np
import yaml

from splitter_bringup.analysis.series import RunSeries
from splitter_bringup.cli.main import main as splitter
from splitter_bringup.scenario.definition import scenario_dir


def short_spin_scenario(tmp_path, duration_s: float = 0.3):
    data = yaml.safe_load((scenario_dir() / "spin_stabilization.yaml").read_text())
    data["duration_s"] = duration_s
    path = tmp_path / "short_spin.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_run_writes_summary_series_and_plots(tmp_path, capsys) -> None:
    scenario = short_spin_scenario(tmp_path)
    out = tmp_path / "out"
    assert splitter(["run", str(scenario), "--out", str(out), "--no-ros", "--no-compile"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["backend"] == "library" and summary["main_variant"] == "mpc"
    assert set(summary["variants"]) == {"mpc", "paper_mpc", "open_loop", "recovery"}
    for key, paper in (("residual_wx", 0.004), ("wy_final", 1.28), ("max_g", 0.47)):
        assert summary["metrics"][key]["paper"] == paper
        assert np.isfinite(summary["metrics"][key]["value"])
    for name in (
        "mpc.npz",
        "open_loop.npz",
        "mpc_flight.png",
        "mpc_quaternion.png",
        "mpc_flight.mp4",  # the 3D animation of each variant
        "open_loop_flight.mp4",
    ):
        assert (out / name).stat().st_size > 0
    series = RunSeries.load_npz(out / "mpc.npz")
    assert len(series) == 61 and series.t_s[-1] == 0.3  # every 5 ms step, both ends
    assert "residual_wz" in capsys.readouterr().out


def test_run_rejects_an_unknown_variant(tmp_path, capsys) -> None:
    scenario = short_spin_scenario(tmp_path)
    code = splitter(["run", str(scenario), "--out", str(tmp_path), "--variant", "nope"])
    assert code == 2
    assert "variant 'nope'" in capsys.readouterr().err


def test_run_checks_the_papers_findings_on_the_variants_it_ran(tmp_path, capsys) -> None:
    data = yaml.safe_load((scenario_dir() / "orientation_tracking.yaml").read_text())
    data["duration_s"] = 0.2
    scenario = tmp_path / "short_orientation.yaml"
    scenario.write_text(yaml.safe_dump(data))
    out = tmp_path / "out"
    args = ["run", str(scenario), "--out", str(out), "--no-ros", "--no-compile", "--no-animation"]
    assert splitter([*args, "--variant", "quaternion_tracking", "--variant", "velocity_only"]) == 0
    findings = json.loads((out / "summary.json").read_text())["findings"]
    assert len(findings) == len(data["findings"])
    ran, not_ran = findings[0], findings[2]  # this project's formulation / the paper's
    assert ran["metric"] == "inertia_range_kg_m2"
    assert set(ran["values"]) == {"quaternion_tracking", "velocity_only"}
    q, v = ran["values"]["quaternion_tracking"], ran["values"]["velocity_only"]
    assert ran["reproduced"] == (q > v)
    assert not_ran["reproduced"] is None and not_ran["values"] == {}
    printed = capsys.readouterr().out
    assert "the paper's findings" in printed and "not run" in printed
    assert (out / "findings.png").stat().st_size > 10_000
