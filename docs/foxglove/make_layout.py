"""Write ``docs/foxglove/splitter_layout.json`` with the foxglove-sdk layout builder.

    .venv/bin/python docs/foxglove/make_layout.py

A 3D panel (the simulator's markers and the bridge's scene arrows, world frame)
beside plots of the angular velocity, the principal inertia against its setpoint,
the gait phase and the contact forces; every plot on the messages' header stamps
(simulated time), so a bag and a live graph look the same.
"""

from __future__ import annotations

from pathlib import Path

import foxglove.layouts as fl

OUT = Path(__file__).with_name("splitter_layout.json")
AXES = "xyz"
COLORS = ("#e5484d", "#30a46c", "#0091ff")  # x, y, z


def series(path: str, label: str, color: str, dashed: bool = False) -> fl.PlotSeries:
    return fl.PlotSeries(
        value=path,
        label=label,
        color=color,
        enabled=True,
        timestamp_method="headerStamp",
        line_style="dashed" if dashed else "solid",
    )


def plot(title: str, paths: list[fl.PlotSeries], y_label: str) -> fl.PlotPanel:
    return fl.PlotPanel(
        title=title,
        config=fl.PlotConfig(
            paths=paths, show_legend=True, legend_display="top", y_axis_label=y_label
        ),
    )


def layout() -> fl.Layout:
    scene = fl.ThreeDeePanel(
        title="SPLITTER (world)",
        config=fl.ThreeDeeConfig(
            follow_tf="world",
            topics={
                "/splitter/markers": fl.BaseRendererRosMarkerTopicSettings(visible=True),
                "/splitter/scene": fl.BaseRendererRosMarkerTopicSettings(visible=True),
            },
        ),
    )
    w = plot(
        "angular velocity w (body)",
        [
            series(f"/splitter/imu.angular_velocity.{a}", f"w_{a}", c)
            for a, c in zip(AXES, COLORS, strict=True)
        ],
        "rad/s",
    )
    inertia = plot(
        "principal inertia and setpoint",
        [
            s
            for a, c in zip(AXES, COLORS, strict=True)
            for s in (
                series(f"/splitter/inertia.vector.{a}", f"I_{a}{a}", c),
                series(f"/splitter/inertia_setpoint.vector.{a}", f"I_{a}{a} setpoint", c, True),
            )
        ],
        "kg m^2",
    )
    phase = fl.StateTransitionsPanel(
        title="gait phase",
        config=fl.StateTransitionsConfig(
            paths=[
                fl.StateTransitionsSeries(
                    value="/splitter/gait_phase.data", label="phase", timestamp_method="receiveTime"
                )
            ]
        ),
    )
    contact = plot(
        "contact forces (world)",
        [
            series(f"/splitter/hemi_{h}/contact_wrench.wrench.force.{a}", f"F_{h},{a}", c, h == "b")
            for h in "ab"
            for a, c in zip(AXES, COLORS, strict=True)
        ],
        "N",
    )
    plots = fl.SplitContainer(
        direction="column",
        items=[fl.SplitItem(content=p) for p in (w, inertia, phase, contact)],
    )
    return fl.Layout(
        content=fl.SplitContainer(
            direction="row",
            items=[
                fl.SplitItem(proportion=1.2, content=scene),
                fl.SplitItem(proportion=1.0, content=plots),
            ],
        )
    )


# panel type of the SDK builder -> panel id prefix of the app's layout files
APP_PANEL_TYPES = {"ThreeDee": "3D", "Plot": "Plot", "StateTransitions": "StateTransitions"}


def app_layout(sdk: dict) -> dict:
    """The builder's layout as the Foxglove app imports it (Layouts > Import from file).

    Panels go to ``configById`` (ids ``<type>!<name>``); splits become the app's
    binary mosaic tree (``first``/``second``, ``direction``, ``splitPercentage``).
    """
    config_by_id: dict[str, dict] = {}

    def node(content: dict) -> str | dict:
        if content["type"] == "panel":
            kind = APP_PANEL_TYPES[content["panelType"]]
            panel_id = f"{kind}!splitter{len(config_by_id)}"
            config_by_id[panel_id] = {**content.get("config", {}), "title": content["title"]}
            return panel_id
        items = content["items"]
        first, rest = items[0], items[1:]
        if not rest:
            return node(first["content"])
        total = sum(i.get("proportion", 1) for i in items)
        tail = {"type": "split", "direction": content["direction"], "items": rest}
        return {
            "first": node(first["content"]),
            "second": node(tail),
            "direction": content["direction"],
            "splitPercentage": round(100.0 * first.get("proportion", 1) / total, 1),
        }

    tree = node(sdk["content"])
    return {
        "configById": config_by_id,
        "globalVariables": {},
        "userNodes": {},
        "playbackConfig": {"speed": 1.0},
        "layout": tree,
    }


if __name__ == "__main__":
    import json

    text = json.dumps(app_layout(json.loads(layout().to_json())), indent=2)
    OUT.write_text(text + "\n", encoding="utf-8")
    print(f"wrote {OUT}")
