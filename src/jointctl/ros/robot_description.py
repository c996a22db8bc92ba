"""The robot in rviz, as the book's launch files show it: ``robot_description``, TF and the objects.

- ``/robot_description`` (parameter, global as the book's launch files load it): the robot's URDF,
  xacro expanded exactly as jointctl loaded it (:func:`robot_description_text`). ROS's
  ``robot_state_publisher`` reads it and turns jointctl's joint states into TF; rviz's RobotModel
  display draws it.
- jointctl publishes joint states under the robot's namespace only (``/<ns>/joint_states``; with
  ``--hardware industrial`` also ROS-I's global ``/joint_states``), never a second global copy:
  ``robot_state_publisher`` is started with the remap the book's launch files use,
  ``joint_states:=/<ns>/joint_states`` (:func:`robot_state_publisher_command`).
- :data:`OBJECT_MARKERS_TOPIC` (visualization_msgs/MarkerArray, :data:`MARKERS_RATE_HZ` while
  someone listens): per spawned object (scenario objects, ``/gazebo/spawn_*_model``, the tuning
  page's weight) its collision shape (cylinder, box or sphere, full sizes in m; namespace
  :data:`MARKERS_NAMESPACE`) at the shape's live pose and its name (a text above it, namespace
  :data:`LABELS_NAMESPACE`, the same id), in the frame of the URDF's root link (the simulated
  world's frame), stamped with the loop time of the cycle it was read in (the same clock as
  ``joint_states``). The pose is the object's body, which sits at its collision shape: ``/gazebo/model_states`` reports the *model*
  frame, the same pose unless the model file puts its collision away from its model frame. A
  removed object's markers are deleted (``DELETE``) in the next message. Simulation only.
- ``serve --rviz`` (:class:`Viewers`): starts ``robot_state_publisher`` (with the remap) and
  ``rviz -d`` with the shipped configuration (:data:`RVIZ_CONFIG`, fixed frame set to the URDF's root
  link, window sized to the screen and view fitted to the robot where the node starts:
  :mod:`jointctl.ros.rviz_layout`) as child processes, stopped with SIGINT when the node stops.
  Whatever cannot start (not installed, no display) is said in one line on stderr and the node
  serves on.
"""

from __future__ import annotations

import glob
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

import mujoco
import numpy as np
import rospy
import yaml
from geometry_msgs.msg import Point, Quaternion
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from jointctl.control.joint_state_controller import JointStateController
from jointctl.model.loader import description_text
from jointctl.model.mjcf import compile_robot
from jointctl.ros.rviz_layout import RvizLayout, apply_layout, rviz_layout, screen_size_px
from jointctl.sim.scene_bounds import drawn_bounds, robot_bodies

ROBOT_DESCRIPTION_PARAM = "/robot_description"
OBJECT_MARKERS_TOPIC = "/jointctl/object_markers"
MARKERS_RATE_HZ = 50.0
MARKERS_NAMESPACE = "spawned_objects"  # Marker.ns of the shapes
LABELS_NAMESPACE = "spawned_object_names"  # Marker.ns of the names (the same id as the shape's)
#: Colour of the objects' markers and of their names (RGBA, 0..1).
MARKER_COLOR = (0.95, 0.55, 0.1, 1.0)
LABEL_COLOR = (1.0, 1.0, 1.0, 1.0)
LABEL_HEIGHT_M = 0.1  # height of a name's letters
RVIZ_CONFIG = Path(__file__).resolve().parent / "rviz" / "jointctl.rviz"
#: Where Debian (and catkin installs) keep the robot_state_publisher executable; PATH is searched first.
ROBOT_STATE_PUBLISHER_PATHS = ("/usr/lib/robot_state_publisher/robot_state_publisher",
                               "/opt/ros/*/lib/robot_state_publisher/robot_state_publisher")
STOP_TIMEOUT_S = 5.0

_SHAPES = {"cylinder": Marker.CYLINDER, "box": Marker.CUBE, "sphere": Marker.SPHERE}


def robot_description_text(robot, package_path: tuple[str, ...] = ()) -> str:
    """The URDF of ``robot`` (a RobotModel) as jointctl loaded it: its ``source`` file, xacro
    expanded with the same ``$(find)`` resolution (``package_path``, then JOINTCTL_PACKAGE_PATH,
    ROS_PACKAGE_PATH and jointctl's robots), or read as it is when it is plain URDF."""
    return description_text(robot, package_path)


def joint_states_topic(node) -> str | None:
    """The topic robot_state_publisher should listen to for ``node`` (a RosNode): the namespaced
    ``joint_states`` when a joint state controller runs, else ROS-I's global one, else None."""
    if any(isinstance(c, JointStateController) for c in node.session.manager.active):
        return f"/{node.namespace}/joint_states"
    if getattr(node, "industrial", None) is not None:
        return "/joint_states"
    return None


class RobotDescription:
    """``/robot_description`` and the spawned objects' markers of one node (a RosNode)."""

    def __init__(self, node) -> None:
        session = node.session
        self.robot = session.robot
        self.root_link = self.robot.root_link
        #: The URDF text on ``/robot_description``.
        self.urdf = robot_description_text(self.robot)
        rospy.set_param(ROBOT_DESCRIPTION_PARAM, self.urdf)
        self.joint_states_topic = joint_states_topic(node)
        #: The robot's drawn box [m] as the node starts (rviz's view is fitted to it).
        self.bounds = robot_bounds(session)
        self.markers = None
        if session.hardware.simulation is not None:
            self.markers = ObjectMarkers(session.hardware.simulation, session.loop, node.clock, self.root_link)


class ObjectMarkers:
    """Publishes :data:`OBJECT_MARKERS_TOPIC` from the loop (see the module docstring)."""

    def __init__(self, sim, loop, clock, frame_id: str, rate_hz: float = MARKERS_RATE_HZ) -> None:
        self.sim = sim
        self.clock = clock
        self.frame_id = frame_id
        self._ids: dict[str, int] = {}  # object name -> marker id, stable while jointctl runs
        self._shown: dict[str, tuple[Marker, Marker, float]] = {}  # name -> shape, label, label height [m]
        self._deleted: list[int] = []  # ids of objects removed since the last message
        self._track()
        sim.on_rebuild(self._track)
        self._publisher = rospy.Publisher(OBJECT_MARKERS_TOPIC, MarkerArray, queue_size=1)
        # Counting cycles from the loop's first, as model_states does: at a rate dividing its 100 Hz,
        # every marker message is read in a cycle that model_states is also read in.
        self._every = max(1, round(1.0 / (rate_hz * loop.period_s)))
        self._count = 0
        loop.add_observer(self._publish)

    def _track(self) -> None:
        """The spawned objects' markers (at start and whenever the world is rebuilt; loop thread)."""
        shown = {}
        for obj in self.sim.spawned:
            shown[obj.name] = self._shown.get(obj.name) or self._markers(obj)
        self._deleted += [shape.id for name, (shape, _, _) in self._shown.items() if name not in shown]
        self._shown = shown

    def _markers(self, obj) -> tuple[Marker, Marker, float]:
        """The shape's marker, its name's (a text above it) and the name's height above the centre [m]."""
        marker_id = self._ids.setdefault(obj.name, len(self._ids))
        shape = Marker(ns=MARKERS_NAMESPACE, id=marker_id, type=_SHAPES[obj.shape], action=Marker.ADD,
                       color=ColorRGBA(*MARKER_COLOR))
        size = obj.size_m
        if obj.shape == "cylinder":  # radius, length -> diameters and length
            shape.scale.x = shape.scale.y = 2.0 * size[0]
            shape.scale.z = size[1]
        elif obj.shape == "box":
            shape.scale.x, shape.scale.y, shape.scale.z = size
        else:
            shape.scale.x = shape.scale.y = shape.scale.z = 2.0 * size[0]
        label = Marker(ns=LABELS_NAMESPACE, id=marker_id, type=Marker.TEXT_VIEW_FACING, action=Marker.ADD,
                       color=ColorRGBA(*LABEL_COLOR), text=obj.name)
        label.scale.z = LABEL_HEIGHT_M
        label.pose.orientation.w = 1.0
        for marker in (shape, label):
            marker.header.frame_id = self.frame_id
        above = 0.5 * max(shape.scale.x, shape.scale.y, shape.scale.z) + LABEL_HEIGHT_M
        return shape, label, above

    def _publish(self, time_s: float) -> None:
        self._count += 1
        if self._count % self._every:
            return
        if not self._publisher.get_num_connections():
            self._deleted.clear()  # nobody saw them
            return
        if not self._shown and not self._deleted:
            return
        stamp = self.clock.ros_time(time_s)
        msg = MarkerArray()
        for marker_id in self._deleted:
            for ns in (MARKERS_NAMESPACE, LABELS_NAMESPACE):
                gone = Marker(ns=ns, id=marker_id, action=Marker.DELETE)
                gone.header.frame_id, gone.header.stamp = self.frame_id, stamp
                msg.markers.append(gone)
        self._deleted.clear()
        for name, (shape, label, above) in self._shown.items():
            position, quat = self.sim.body_state(name)[:2]
            shape.header.stamp = label.header.stamp = stamp
            shape.pose.position = Point(*position)
            shape.pose.orientation = Quaternion(x=quat[1], y=quat[2], z=quat[3], w=quat[0])
            label.pose.position = Point(position[0], position[1], position[2] + above)
            msg.markers.extend((shape, label))
        self._publisher.publish(msg)


def find_robot_state_publisher() -> str | None:
    """The robot_state_publisher executable, or None when it is not installed."""
    found = shutil.which("robot_state_publisher")
    if found:
        return found
    for pattern in ROBOT_STATE_PUBLISHER_PATHS:
        for path in sorted(glob.glob(pattern)):
            if os.access(path, os.X_OK):
                return path
    return None


def robot_state_publisher_command(executable: str, joint_states: str) -> list[str]:
    """robot_state_publisher with the book's remap: it listens to jointctl's ``joint_states``."""
    return [executable, f"joint_states:={joint_states}", "__name:=robot_state_publisher"]


def rviz_config_text(fixed_frame: str, layout: RvizLayout | None = None) -> str:
    """The shipped rviz configuration (fixed frame ``world``) with its fixed frame set to ``fixed_frame``
    and, given a ``layout``, its window, view and TF axes from it."""
    text = RVIZ_CONFIG.read_text().replace("    Fixed Frame: world\n", f"    Fixed Frame: {fixed_frame}\n")
    if layout is None:
        return text
    header = "".join(line + "\n" for line in text.splitlines() if line.startswith("#"))
    return header + yaml.safe_dump(apply_layout(yaml.safe_load(text), layout), sort_keys=False)


def robot_bounds(session) -> tuple[np.ndarray, np.ndarray]:
    """The box [m, world frame = the root link's] around the robot's drawn links as the session
    starts: the simulated world's pose, or on hardware without one the model at zero positions."""
    world = session.world
    if world is not None:
        model, data = world.model, world.data
        bodies = robot_bodies(model, [obj.name for obj in world.spawned])
    else:
        model = compile_robot(session.robot)
        data = mujoco.MjData(model)
        bodies = None
    mujoco.mj_kinematics(model, data)
    found = drawn_bounds(model, data, bodies)
    return found if found is not None else (np.zeros(3), np.zeros(3))


class Viewers:
    """``serve --rviz``: robot_state_publisher and rviz as child processes of the node."""

    def __init__(self) -> None:
        self.processes: list[tuple[str, subprocess.Popen]] = []
        self._tmp: str | None = None
        self._stopping = False

    def start(self, description: RobotDescription) -> str:
        """Start what can be started; returns the one line that says what was and what was not."""
        said = []
        rsp = find_robot_state_publisher()
        topic = description.joint_states_topic
        if rsp is None:
            said.append("robot_state_publisher is not installed (apt-get install ros-robot-state-publisher): "
                        "no TF")
        elif topic is None:
            said.append("no joint states are published (no joint_state_controller): robot_state_publisher "
                        "not started")
        else:
            self._spawn("robot_state_publisher", robot_state_publisher_command(rsp, topic))
            said.append(f"robot_state_publisher started (joint_states:={topic})")
        rviz = shutil.which("rviz")
        if rviz is None:
            said.append("rviz is not installed (apt-get install rviz): not started")
        elif not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            said.append("rviz not started: no display (DISPLAY is not set)")
        else:
            self._tmp = tempfile.mkdtemp(prefix="jointctl-rviz-")
            config = Path(self._tmp) / "jointctl.rviz"
            layout = rviz_layout(*description.bounds, *screen_size_px())
            config.write_text(rviz_config_text(description.root_link, layout))
            self._spawn("rviz", [rviz, "-d", str(config)])
            width, height = layout.window_px[2:]
            said.append(f"rviz started (fixed frame {description.root_link}, objects on {OBJECT_MARKERS_TOPIC}; "
                        f"window {width}x{height} for a screen from {layout.screen_source}, view fitted to the "
                        "robot)")
        return "jointctl: --rviz: " + "; ".join(said) + "; serving"

    def _spawn(self, name: str, command: list[str]) -> None:
        # Its own process group: a Ctrl-C in the terminal reaches jointctl, which stops it in order.
        process = subprocess.Popen(command, stdin=subprocess.DEVNULL, start_new_session=True)
        self.processes.append((name, process))
        threading.Thread(target=self._watch, args=(name, process), daemon=True, name=f"jointctl-{name}").start()

    def _watch(self, name: str, process: subprocess.Popen) -> None:
        status = process.wait()
        if not self._stopping:
            print(f"jointctl: --rviz: {name} exited (status {status}); the node serves on", file=sys.stderr)

    def stop(self) -> None:
        """Stop the started processes (SIGINT, as roscpp nodes want, then SIGKILL after
        :data:`STOP_TIMEOUT_S`)."""
        self._stopping = True
        for _, process in self.processes:
            if process.poll() is None:
                process.send_signal(signal.SIGINT)
        for _, process in self.processes:
            try:
                process.wait(STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        self.processes.clear()
        if self._tmp is not None:
            shutil.rmtree(self._tmp, ignore_errors=True)
            self._tmp = None


def attach_robot_description(node) -> RobotDescription:
    """Load ``/robot_description`` and start the objects' markers for ``node`` (a RosNode)."""
    return RobotDescription(node)


__all__ = ["LABELS_NAMESPACE", "MARKERS_NAMESPACE", "MARKERS_RATE_HZ", "OBJECT_MARKERS_TOPIC", "ROBOT_DESCRIPTION_PARAM", "RVIZ_CONFIG",
           "ObjectMarkers", "RobotDescription", "Viewers", "attach_robot_description",
           "find_robot_state_publisher", "robot_description_text", "robot_state_publisher_command"]
