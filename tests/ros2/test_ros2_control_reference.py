"""ros2_control's own ros2_control_node (Jazzy, mock_components) as the reference for jointctl's ROS 2 files and
controllers: the files ``jointctl init`` writes load and activate there, and pid_controller's published outputs
are, cycle for cycle, what jointctl's control_toolbox PID computes from the same errors and periods.

Everything ROS 2 runs in child processes (tests.ros2.environment); the reference's outputs are read from
``~/controller_state`` by a small rclpy probe, and only consecutive cycles are compared (a message the probe
missed leaves the PID's history unknown)."""

from __future__ import annotations

import contextlib
import io
import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from jointctl.cli import main
from jointctl.control.toolbox_pid import ToolboxGains, ToolboxPid
from jointctl.model.loader import description_text, load_robot_model
from tests import planar_arm
from tests.model.test_ros2_control import CONTROL_DEMO
from tests.processes import stop_process
from tests.ros2.environment import ros2

#: Latches a URDF on /robot_description (transient local), as robot_state_publisher does.
DESCRIBE = """
import sys, rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("robot_description_publisher")
latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
pub = node.create_publisher(String, "/robot_description", latched)
pub.publish(String(data=open(sys.argv[1]).read()))
rclpy.spin(node)
"""

#: Records ~/controller_state; once 20 states came, sends the reference 1.0 (best effort, as the controller
#: subscribes) a few times; writes [stamp, reference, feedback, error, time_step, output] rows to argv[1].
PROBE = """
import json, sys, time, rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from control_msgs.msg import MultiDOFCommand, MultiDOFStateStamped
rclpy.init()
node = rclpy.create_node("probe")
rows = []
def on_state(msg):
    s = msg.dof_states[0]
    rows.append([msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9, s.reference, s.feedback, s.error,
                 s.time_step, s.output])
node.create_subscription(MultiDOFStateStamped, "/pid_controller/controller_state", on_state,
                         QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
pub = node.create_publisher(MultiDOFCommand, "/pid_controller/reference",
                            QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
end, sent = time.time() + 30, False
while time.time() < end and len(rows) < 300:
    rclpy.spin_once(node, timeout_sec=0.01)
    if not sent and len(rows) > 20:
        for _ in range(3):
            pub.publish(MultiDOFCommand(dof_names=["joint1"], values=[1.0], values_dot=[]))
        sent = True
json.dump(rows, open(sys.argv[1], "w"))
"""

GAINS = {"p": 2.0, "i": 0.5, "d": 0.01, "i_clamp_max": 0.3, "i_clamp_min": -0.3}
PID_FILE = f"""
controller_manager:
  ros__parameters:
    update_rate: 100
    joint_state_broadcaster: {{type: joint_state_broadcaster/JointStateBroadcaster}}
    pid_controller: {{type: pid_controller/PidController}}
pid_controller:
  ros__parameters:
    dof_names: [joint1]
    command_interface: velocity
    reference_and_state_interfaces: [position]
    gains:
      joint1: {json.dumps(GAINS).replace('"', '')}
"""


@contextlib.contextmanager
def controller_manager(env: dict, urdf: Path, parameters: Path, log: Path):
    """ros2_control_node with ``parameters`` and ``urdf`` on /robot_description, until the block ends."""
    describe = subprocess.Popen(["python3", "-c", DESCRIBE, str(urdf)], env=env, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
    # The executable itself, not through `ros2 run` (which would leave it running when stopped).
    executable = next(path for prefix in env["AMENT_PREFIX_PATH"].split(":")
                      if (path := Path(prefix) / "lib" / "controller_manager" / "ros2_control_node").is_file())
    with open(log, "w") as out:
        node = subprocess.Popen([str(executable), "--ros-args", "--params-file", str(parameters)], env=env,
                                stdout=out, stderr=subprocess.STDOUT)
    try:
        yield
    finally:
        stop_process(node)
        stop_process(describe)


def spawn(env: dict, *controllers: str) -> subprocess.CompletedProcess:
    return subprocess.run(["ros2", "run", "controller_manager", "spawner", *controllers,
                           "--controller-manager-timeout", "60"], env=env, capture_output=True, text=True,
                          timeout=120)


def test_the_files_init_writes_load_and_activate_under_ros2_control_node(ros2_env, tmp_path):
    planar_arm.write_urdf(tmp_path)
    with contextlib.chdir(tmp_path), contextlib.redirect_stdout(io.StringIO()), \
            contextlib.redirect_stderr(io.StringIO()):
        assert main(["init", "planar_arm.urdf", "--out", "arm"]) == 0
    robot = load_robot_model(tmp_path / "arm" / "urdf" / "planar_arm.ros2_control.urdf.xacro")
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(description_text(robot))
    with controller_manager(ros2_env, urdf, tmp_path / "arm" / "config" / "ros2_controllers.yaml",
                            tmp_path / "node.log"):
        spawned = spawn(ros2_env, "joint_state_broadcaster", "pid_controller")
        listed = ros2(ros2_env, "control", "list_controllers", timeout_s=60).stdout
    assert spawned.returncode == 0, spawned.stdout + spawned.stderr + (tmp_path / "node.log").read_text()
    for line in ("pid_controller/PidController", "joint_state_broadcaster/JointStateBroadcaster"):
        assert any(line in row and "active" in row for row in listed.splitlines()), listed


def test_pid_controllers_outputs_are_control_toolboxs_pid_cycle_for_cycle(ros2_env, tmp_path):
    parameters = tmp_path / "controllers.yaml"
    parameters.write_text(PID_FILE)
    rows_file = tmp_path / "states.json"
    with controller_manager(ros2_env, CONTROL_DEMO, parameters, tmp_path / "node.log"):
        spawned = spawn(ros2_env, "joint_state_broadcaster", "pid_controller")
        assert spawned.returncode == 0, spawned.stdout + spawned.stderr
        probe = subprocess.run(["python3", "-c", PROBE, str(rows_file)], env=ros2_env, capture_output=True,
                               text=True, timeout=90)
    assert probe.returncode == 0, probe.stderr
    rows = json.loads(rows_file.read_text())
    first = next(k for k, row in enumerate(rows) if not math.isnan(row[1]))
    assert first > 0 and all(math.isnan(row[5]) and math.isnan(row[3]) for row in rows[:first])  # NaN before it
    pid = ToolboxPid(ToolboxGains(GAINS["p"], GAINS["i"], GAINS["d"], GAINS["i_clamp_max"], GAINS["i_clamp_min"]))
    compared = 0
    for k in range(first, len(rows)):
        stamp, reference, feedback, error, time_step, output = rows[k]
        if k > first and abs(stamp - rows[k - 1][0] - time_step) > 0.5 * time_step:
            break  # a state the probe missed
        assert output == pytest.approx(pid.compute(error, round(time_step * 1e9)), rel=1e-12, abs=1e-12), k
        compared += 1
    # The first: p·e + i·dt·e + d·e/dt, the kick from the last error 0.
    assert rows[first][5] > GAINS["p"] + GAINS["d"] / 0.02
    assert compared >= 20, (compared, len(rows))
    print(f"{compared} consecutive cycles compared", file=sys.stderr)
