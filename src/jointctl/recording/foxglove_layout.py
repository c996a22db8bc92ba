"""The Foxglove layout jointctl ships: the 3D view beside plots of the joints, the wrench and the events.

:data:`LAYOUT_FILE` (``foxglove_layout.json`` in this package) is :func:`layout` written out; import it in
Foxglove (*Layouts* -> *Import from file*) with a ``run.mcap`` or a live ``--foxglove`` connection:

- the 3D view: the URDF from ``/robot_description`` posed by ``/tf`` in the ``world`` frame, the spawned
  objects (``/jointctl/objects``), a 1 m grid;
- every joint's position [m or rad] with its reference (dashed), one line per joint named by the joint
  (``/jointctl/joint_states`` and ``/jointctl/references``: any robot);
- every joint's effort [N or N·m];
- the force along z [N] of a force-torque sensor named ``ft_sensor`` (the built-in robots'; edit the path
  for another name: ``/jointctl/wrenches.<sensor>.force_z_N``);
- the events (spawns, goals, failures).

``python -m jointctl.recording.foxglove_layout`` writes the file again from :func:`layout`.
"""

from __future__ import annotations

from pathlib import Path

import foxglove.layouts as fl

from jointctl.recording.foxglove_messages import (
    EVENTS, JOINT_STATES, OBJECTS, REFERENCES, ROBOT_DESCRIPTION, TF, WORLD_FRAME, WRENCHES)

LAYOUT_FILE = Path(__file__).resolve().parent / "foxglove_layout.json"
#: The force-torque sensor the force plot shows (the built-in robots').
SENSOR = "ft_sensor"


def _joints_series(topic: str, field: str, *, dashed: bool = False) -> fl.PlotSeries:
    """One line per joint of ``topic``'s ``joints`` array (foxglove.JointStates), named by the joint."""
    return fl.PlotSeries(value=f"{topic}.joints", dynamic_label_field="name", dynamic_value_field=field,
                         line_style="dashed" if dashed else None, timestamp_method="receiveTime")


def _plot(title: str, y_label: str, series: list[fl.PlotSeries]) -> fl.PlotPanel:
    return fl.PlotPanel(title=title, config=fl.PlotConfig(paths=series, y_axis_label=y_label, show_legend=True,
                                                          legend_display="floating", is_synced=True,
                                                          x_axis_val="timestamp"))


def layout() -> fl.Layout:
    """The layout (see the module docstring)."""
    three_d = fl.ThreeDeePanel(title="robot", config=fl.ThreeDeeConfig(
        follow_tf=WORLD_FRAME, fixed_frame=WORLD_FRAME,
        camera_state=fl.ThreeDeeCameraState(distance=4.0, perspective=True, phi=60.0, theta_offset=45.0,
                                            target=(0.0, 0.0, 1.0)),
        scene=fl.BaseRendererSceneSettings(mesh_up_axis="z_up",
                                           transforms=fl.BaseRendererTransforms(show_label=False, axis_size=0.1)),
        topics={ROBOT_DESCRIPTION: fl.BaseRendererUrdfTopicSettings(visible=True, display_mode="auto"),
                OBJECTS: fl.BaseRendererSceneUpdateTopicSettings(visible=True),
                TF: fl.BaseRendererBaseSettings(visible=True)},
        layers={"grid": fl.BaseRendererGridLayerSettings(layer_id="foxglove.Grid", instance_id="grid", visible=True,
                                                         frame_id=WORLD_FRAME, size=10.0, divisions=10.0,
                                                         label="grid, 1 m")},
    ))
    positions = _plot("joint positions and references", "position [m or rad]",
                      [_joints_series(JOINT_STATES, "position"), _joints_series(REFERENCES, "position", dashed=True)])
    efforts = _plot("joint efforts", "effort [N or N·m]", [_joints_series(JOINT_STATES, "effort")])
    force = _plot(f"{SENSOR} force z", "force [N]", [
        fl.PlotSeries(value=f"{WRENCHES}.{SENSOR}.force_z_N", label=f"{SENSOR} force z [N]")])
    events = fl.LogPanel(title="events", config=fl.LogConfig(topic_to_render=EVENTS, show_name=False))
    plots = fl.SplitContainer(direction="column", items=[
        fl.SplitItem(proportion=2, content=positions), fl.SplitItem(proportion=1.5, content=efforts),
        fl.SplitItem(proportion=1.5, content=force), fl.SplitItem(proportion=1, content=events)])
    return fl.Layout(content=fl.SplitContainer(direction="row", items=[
        fl.SplitItem(proportion=1, content=three_d), fl.SplitItem(proportion=1, content=plots)]))


def layout_json() -> str:
    """:func:`layout` as the file's text (indented JSON, a final newline)."""
    import json

    return json.dumps(json.loads(layout().to_json()), indent=2) + "\n"


if __name__ == "__main__":
    LAYOUT_FILE.write_text(layout_json())
    print(f"wrote {LAYOUT_FILE}")
