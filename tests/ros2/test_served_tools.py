"""identify, bode and autotune with ``--hardware ros2`` on the C++ ``ros2_control_node`` of ROS 2 itself: the
mock hardware (``mock_components/GenericSystem`` with ``calculate_dynamics``) under ``pid_controller``s, whose
motion is known exactly (mock_rig/robot.urdf), reached through the reference topics, ``/joint_states`` and the
controllers' parameters, as any ROS 2 client reaches them.

The mock, each cycle of period h (ros2_control 4.22, ``GenericSystem::read``): an acceleration-commanded
joint integrates q += v·h, then v += a·h, then takes a = the command written the cycle before; a
velocity-commanded one q += v·h, then v = the command. With pid_controller's command written from the
position read that cycle (control_toolbox's PID, the derivative on the error's backward difference):

- joint1, acceleration: P(z) = h²/(z(z-1)²), C(z) = p + d(1 - 1/z)/h, T = PC/(1 + PC); its effort (the
  acceleration, as the joint_state_broadcaster reports it) moves a unit inertia with no damping: exactly;
- joint2, velocity: P(z) = h/(z(z-1)), C = p, T = hp/(z(z-1) + hp) (≈ p/(s + p));
- joint3, position through a forward command controller (the hardware's own servo): T = 1/z.

What the tools add to the loop is outside it: the reference's way to the controller and the state's way
back (a delay, which lowers only the phase), and this side's pace (a loop slower than real time shows the
robot its sines slower: the tools warn below 0.98 of real time; no warning here means the frequencies the
robot saw are within 2 % of those planned).
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from tests.processes import stop_process
from tests.ros2.environment import ros2
from tests.waiting import wait_until

#: Real-time measurements over the graph (a controller manager and a client at 200 Hz): they need the machine.
pytestmark = pytest.mark.exclusive

RIG = Path(__file__).with_name("mock_rig")
ROOT = Path(__file__).resolve().parents[2]
H = 0.005  # the rig's update period (controllers.yaml: update_rate 200)
ACCELERATION_GAINS = {"p": 100.0, "i": 0.0, "d": 10.0}  # controllers.yaml: pid_controller on joint1
VELOCITY_P = 10.0  # velocity_pid on joint2
#: The slowest pace the tools run at without a warning: the robot sees f·PACE..f.
PACE = 0.98
#: The sine fits' own error on a noiseless mock [dB] and [deg] (samples of a 200 Hz loop over whole periods).
FIT_DB, FIT_DEG = 0.1, 1.0
#: A mean delay between the reference written and the state read back the tools may add: each loop's wait for
#: the other's next cycle (h/2 each way on average), the transport both ways (a fraction of a millisecond on
#: loopback), and as over ROS 1 10 ms of room for a busy machine's lateness [s].
DELAY_BUDGET_S = H + 0.010


def acceleration_loop(f, p: float, d: float, h: float = H) -> np.ndarray:
    """joint1's closed loop position/reference at ``f`` [Hz] (see the module docstring)."""
    z = np.exp(2j * np.pi * np.asarray(f, dtype=float) * h)
    loop = h ** 2 / (z * (z - 1) ** 2) * (p + d * (1 - 1 / z) / h)
    return loop / (1 + loop)


def velocity_loop(f, p: float, h: float = H) -> np.ndarray:
    """joint2's closed loop position/reference at ``f`` [Hz]."""
    z = np.exp(2j * np.pi * np.asarray(f, dtype=float) * h)
    return h * p / (z * (z - 1) + h * p)


def acceleration_step(p: float, d: float, step: float, seconds: float, h: float = H, kick: float = 1.0) -> np.ndarray:
    """joint1's position each cycle after its reference steps by ``step`` from rest, the mock and the PID run
    as they do (``kick`` scales the first cycle's derivative term: a controller period that differs from the
    next one changes the velocity that kick leaves by their ratio)."""
    q = v = a = command = error_last = 0.0
    out = []
    for k in range(int(round(seconds / h))):
        q += v * h
        v += a * h
        a = command
        error = step - q
        command = p * error + d * (error - error_last) / h * (kick if k == 0 else 1.0)
        error_last = error
        out.append(q)
    return np.array(out)


def executable(env: dict, package: str, name: str) -> str:
    for prefix in env.get("AMENT_PREFIX_PATH", "").split(":"):
        path = Path(prefix) / "lib" / package / name
        if path.is_file():
            return str(path)
    raise FileNotFoundError(f"{package}/{name} in AMENT_PREFIX_PATH")


def jointctl_command(env: dict, *args: str) -> tuple[list[str], dict]:
    """(argv, env) of ``jointctl ARGS`` from this checkout, in the ROS 2 environment ``env``."""
    return ([sys.executable, "-m", "jointctl.cli", *args],
            dict(env, PYTHONPATH=f"{ROOT / 'src'}:{env.get('PYTHONPATH', '')}"))


def jointctl(env: dict, *args: str, timeout: float = 240.0) -> subprocess.CompletedProcess:
    argv, run_env = jointctl_command(env, *args)
    return subprocess.run(argv, env=run_env, capture_output=True, text=True, timeout=timeout)


def references(env: dict, controller: str) -> list[float]:
    """The pid_controller's reference of each dof now (NaN: none yet), from its ``~/controller_state``."""
    out = ros2(env, "topic", "echo", "--once", f"/{controller}/controller_state",
               "control_msgs/msg/MultiDOFStateStamped", timeout_s=30).stdout
    message = yaml.safe_load(out.split("---")[0])
    return [float(state["reference"]) for state in message["dof_states"]]


def gain(env: dict, controller: str, name: str) -> float:
    out = ros2(env, "param", "get", f"/{controller}", name, timeout_s=30).stdout
    return float(out.rsplit(":", 1)[1])


@pytest.fixture(scope="module")
def rig(ros2_env, tmp_path_factory):
    """robot_state_publisher with the rig's URDF, then ros2_control_node with its controllers, then the
    spawner (the start-up order ros2_control needs); the env of their graph."""
    folder = tmp_path_factory.mktemp("mock_rig")
    description = folder / "robot_state_publisher.yaml"
    description.write_text(yaml.safe_dump({"robot_state_publisher": {"ros__parameters": {
        "robot_description": (RIG / "robot.urdf").read_text()}}}))
    processes = []

    def start(name: str, *argv: str) -> None:
        log = open(folder / f"{name}.log", "w")
        processes.append(subprocess.Popen(list(argv), env=ros2_env, stdout=log, stderr=subprocess.STDOUT))
        log.close()

    try:
        start("robot_state_publisher", executable(ros2_env, "robot_state_publisher", "robot_state_publisher"),
              "--ros-args", "--params-file", str(description))
        start("ros2_control_node", executable(ros2_env, "controller_manager", "ros2_control_node"),
              "--ros-args", "--params-file", str(RIG / "controllers.yaml"))
        spawned = subprocess.run([executable(ros2_env, "controller_manager", "spawner"), "joint_state_broadcaster",
                                  "pid_controller", "velocity_pid", "joint3_position", "--controller-manager-timeout",
                                  "60"],
                                 env=ros2_env, capture_output=True, text=True, timeout=120)
        assert spawned.stdout.count("Configured and activated") + spawned.stderr.count(
            "Configured and activated") == 4, spawned.stdout + spawned.stderr
        yield ros2_env
    finally:
        for process in reversed(processes):
            stop_process(process)


def test_an_unknown_or_unfit_loop_is_refused_in_one_line_before_anything_is_sent(rig, tmp_path) -> None:
    # First in the module: the rig is fresh, so no reference was ever given to either controller (NaN).
    assert all(math.isnan(r) for r in references(rig, "pid_controller") + references(rig, "velocity_pid"))
    cases = [("autotune", "--controller", "joint9_pid", "--bandwidth-hz", "2"),
             ("bode", "--controller", "joint9_pid"),
             ("autotune", "--controller", "velocity_pid", "--bandwidth-hz", "2"),
             ("autotune", "--controller", "joint3_position", "--bandwidth-hz", "2"),
             ("identify", "--joint", "joint2")]
    for command, *argv in cases:
        result = jointctl(rig, command, "--hardware", "ros2", *argv, "--out", str(tmp_path / command))
        errors = [line for line in result.stderr.splitlines() if line.startswith("jointctl: error:")]
        assert result.returncode == 2 and len(errors) == 1, result.stderr
        assert not (tmp_path / command / "metrics.json").exists()
    unknown = jointctl(rig, "bode", "--hardware", "ros2", "--controller", "joint9_pid", "--out", str(tmp_path))
    assert "--controller" in unknown.stderr and "pid_controller (joint1)" in unknown.stderr
    assert "velocity_pid (joint2)" in unknown.stderr and "joint3_position (joint3)" in unknown.stderr
    unfit = jointctl(rig, "autotune", "--hardware", "ros2", "--controller", "velocity_pid", "--bandwidth-hz", "2",
                     "--out", str(tmp_path))
    assert "velocity" in unfit.stderr and "--controller" in unfit.stderr
    # Nothing was sent: both loops still have no reference.
    assert all(math.isnan(r) for r in references(rig, "pid_controller") + references(rig, "velocity_pid"))
    # A joint whose states carry no effort cannot be identified: said before it moves (its forward command
    # controller was only told to hold it where it is).
    no_effort = jointctl(rig, "identify", "--hardware", "ros2", "--joint", "joint3", "--out", str(tmp_path / "j3"))
    assert no_effort.returncode == 2 and "no effort" in no_effort.stderr and "--joint" in no_effort.stderr
    assert not (tmp_path / "j3" / "metrics.json").exists()


def test_without_ros2_sourced_the_tools_say_how_in_one_line(tmp_path) -> None:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "LD_LIBRARY_PATH", "AMENT_PREFIX_PATH")}
    env["PYTHONPATH"] = str(ROOT / "src")
    result = subprocess.run([sys.executable, "-m", "jointctl.cli", "bode", "--hardware", "ros2", "--controller",
                             "pid_controller", "--out", str(tmp_path)], env=env, capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 2 and result.stderr.count("\n") == 1, result.stderr
    assert "ROS 2 is not available" in result.stderr and "setup.bash" in result.stderr


def test_identify_through_the_acceleration_loop_finds_the_unit_inertia(rig, tmp_path) -> None:
    result = jointctl(rig, "identify", "--hardware", "ros2", "--joint", "joint1", "--duration-s", "6",
                      "--out", str(tmp_path))
    assert result.returncode == 0, result.stderr
    assert "warning" not in result.stderr, result.stderr
    metrics = json.loads(result.stdout)
    # The effort the joint states report is the acceleration the mock integrates over each cycle's own period:
    # v(k+1) - v(k) = effort(k)·(t(k+1) - t(k)), so a unit inertia with nothing else, up to the fit's grid
    # (the states put on a uniform one: the controller manager's late cycles move a sample by its lateness).
    assert metrics["inertia_kg_m2"] == pytest.approx(1.0, rel=0.01)
    assert metrics["model_inertia_kg_m2"] == pytest.approx(1.0, rel=1e-9)
    peak = metrics["excitation"]["saturation"]["peak_effort"]
    for figure in ("damping_n_m_s_rad", "friction_n_m", "gravity_sin_n_m", "gravity_cos_n_m"):
        # None in the mock: what the grid's resampling leaves is under a thousandth of the efforts the excitation
        # asks (its damping term at the top speed alike).
        scale = peak / metrics["excitation"]["saturation"]["peak_velocity"] if figure.startswith("damping") else peak
        assert abs(metrics[figure]) < 1e-3 * scale, (figure, metrics[figure], scale)
    assert metrics["acceleration"] == "forward" and metrics["effort_shift_cycles"] == 0
    excitation = metrics["excitation"]
    assert excitation["rest_after"] == pytest.approx(excitation["rest_before"], abs=1e-3)
    # The loop holds where it was left: the reference it was given when this side connected (the joint at rest).
    assert references(rig, "pid_controller")[0] == pytest.approx(excitation["rest_before"], abs=1e-3)


def _check_against(points: dict, theory, label: str) -> list[float]:
    """Each measured point against ``theory(f)`` (complex): the gain within what the pace allows and the fit
    adds, the phase below the theory's by a delay within the budget; the excess delays [s]."""
    delays = []
    for f, gain_db, phase_deg in zip(points["frequencies_hz"], points["gain_db"], points["phase_deg"]):
        band = 20 * np.log10(np.abs(theory(np.linspace(PACE * f, f, 50))))
        assert band.min() - FIT_DB <= gain_db <= band.max() + FIT_DB, (label, f, gain_db, band.min(), band.max())
        expected = float(np.degrees(np.angle(theory(f))))
        excess = expected - phase_deg  # the lag the delay adds [deg]
        pace_deg = abs(expected - float(np.degrees(np.angle(theory(PACE * f)))))
        assert -FIT_DEG - pace_deg <= excess <= 360 * f * DELAY_BUDGET_S + FIT_DEG + pace_deg, (label, f, excess)
        delays.append(excess / (360 * f))
    return delays


def test_bode_of_the_acceleration_loop_is_the_mocks_transfer_function(rig, tmp_path) -> None:
    result = jointctl(rig, "bode", "--hardware", "ros2", "--controller", "pid_controller", "--f-min-hz", "0.8",
                      "--f-max-hz", "5", "--points", "5", "--out", str(tmp_path))
    assert result.returncode == 0, result.stderr
    assert "warning" not in result.stderr, result.stderr
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    _check_against(metrics, lambda f: acceleration_loop(f, ACCELERATION_GAINS["p"], ACCELERATION_GAINS["d"]),
                   "joint1")
    # Beside jointctl's model of it: the gains read from the controller's parameters, the plant the acceleration
    # command implies.
    model = metrics["model"]
    assert (model["p"], model["i"], model["d"]) == (100.0, 0.0, 10.0)
    assert (model["mass"], model["damping"]) == (1.0, 0.0) and metrics["plant_source"].startswith("acceleration")
    assert metrics["controller"] == "/pid_controller" and metrics["period_s"] == H


def test_bode_of_the_velocity_loop_is_the_mocks_transfer_function(rig, tmp_path) -> None:
    result = jointctl(rig, "bode", "--hardware", "ros2", "--controller", "velocity_pid", "--f-min-hz", "0.8",
                      "--f-max-hz", "5", "--points", "4", "--out", str(tmp_path))
    assert result.returncode == 0, result.stderr
    assert "warning" not in result.stderr, result.stderr
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    _check_against(metrics, lambda f: velocity_loop(f, VELOCITY_P), "joint2")
    # A loop commanding velocity has no effort model here: measured alone.
    assert metrics["plant_source"] is None and "model" not in metrics


def test_autotune_through_the_acceleration_loop_designs_for_the_unit_plant_and_puts_the_gains_back(
        rig, tmp_path) -> None:
    result = jointctl(rig, "autotune", "--hardware", "ros2", "--controller", "pid_controller", "--zeta", "0.7",
                      "--bandwidth-hz", "2", "--out", str(tmp_path))
    assert result.returncode == 0, result.stderr
    tuned = json.loads(result.stdout)
    assert tuned["previous_gains"] == tuned["gains_restored"] == ACCELERATION_GAINS
    assert {name: gain(rig, "pid_controller", f"gains.joint1.{name}") for name in "pid"} == ACCELERATION_GAINS
    p, d = tuned["gains"]["p"], tuned["gains"]["d"]
    assert (tuned["mass"], tuned["damping"]) == (1.0, 0.0)
    # The gains on the mock's own loop meet the spec's overshoot (ζ 0.7: 4.6 %) from rest over a long record.
    y = acceleration_step(p, d, 0.1, 6.0)
    assert 100 * (y.max() - 0.1) / 0.1 == pytest.approx(100 * math.exp(-math.pi * 0.7 / math.sqrt(1 - 0.49)), abs=0.5)
    # The model's -3 dB bandwidth is that of the same PD on a unit inertia with the command held over each cycle
    # (h²(z+1)/(2(z-1)²)): jointctl designed on the plant the acceleration command implies. (The mock integrates
    # the command a cycle later, 1.5 cycles of delay more, which raises its own crossing: 15 % at 200 Hz.)
    f = np.linspace(0.1, 10, 20_000)
    z = np.exp(2j * np.pi * f * H)
    held = H ** 2 * (z + 1) / (2 * (z - 1) ** 2) * (p + d * (1 - 1 / z) / H)
    crossing = f[np.argmax(20 * np.log10(np.abs(held / (1 + held))) < -3.0103)]
    assert crossing == pytest.approx(tuned["model"]["bandwidth_hz"], rel=1e-3)
    # The check step on the robot, as the tools measure it (2 s after the step; the final value the mean of the
    # last 0.2 s): its derivative kick d·step/h lasts one controller cycle, and the velocity it leaves scales with
    # the ratio of that cycle's period to the next's; periods within ±20 % of each other bound the overshoot.
    from jointctl.metrics.step_loop import step_figures

    bounds = []
    for kick in np.linspace(0.8, 1.25, 19):
        path = acceleration_step(p, d, tuned["check_step"], 2.0, kick=kick)
        bounds.append(step_figures(np.arange(path.size) * H, path, np.full(path.size, tuned["check_step"]),
                                   ).overshoot_pct)
    assert min(bounds) <= tuned["robot"]["step_overshoot_pct"] <= max(bounds), (tuned["robot"], min(bounds),
                                                                                max(bounds))
    # The file: the controller's parameters with the tuned gains, as ros2 param load (and --params-file) read it.
    written = yaml.safe_load(Path(tuned["yaml"]).read_text())
    parameters = written["pid_controller"]["ros__parameters"]
    assert parameters["command_interface"] == "acceleration" and parameters["dof_names"] == ["joint1"]
    assert (parameters["gains"]["joint1"]["p"], parameters["gains"]["joint1"]["d"]) == pytest.approx((p, d), rel=1e-5)
    try:
        loaded = ros2(rig, "param", "load", "/pid_controller", tuned["yaml"], timeout_s=60)
        assert "Set parameter gains.joint1.p successful" in loaded.stdout, loaded.stdout + loaded.stderr
        assert gain(rig, "pid_controller", "gains.joint1.p") == pytest.approx(p, rel=1e-5)
    finally:
        for name, value in ACCELERATION_GAINS.items():
            ros2(rig, "param", "set", "/pid_controller", f"gains.joint1.{name}", repr(value), timeout_s=30)
    assert gain(rig, "pid_controller", "gains.joint1.p") == ACCELERATION_GAINS["p"]


def test_bode_through_a_forward_command_controller_is_the_mocks_one_cycle(rig, tmp_path) -> None:
    # A fixed 0.2 rad: the mock's velocity is the position's difference over the cycle, and a cycle that gets two
    # commands (two loops at one rate on two clocks) doubles it; the planned amplitudes would then read as the
    # velocity limit touched at 5 Hz.
    result = jointctl(rig, "bode", "--hardware", "ros2", "--controller", "joint3_position", "--f-min-hz", "0.8",
                      "--f-max-hz", "5", "--points", "3", "--amplitude", "0.2", "--out", str(tmp_path))
    assert result.returncode == 0, result.stderr
    assert "warning" not in result.stderr, result.stderr
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    _check_against(metrics, lambda f: np.exp(-2j * np.pi * np.asarray(f) * H), "joint3")
    assert metrics["plant_source"] is None and "model" not in metrics


def test_an_interrupted_autotune_puts_the_gains_back(rig, tmp_path) -> None:
    argv, env = jointctl_command(rig, "autotune", "--hardware", "ros2", "--controller", "pid_controller",
                                 "--zeta", "0.7", "--bandwidth-hz", "2", "--out", str(tmp_path))
    process = subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        # Interrupted in its check on the robot: the new gains are on the controller.
        wait_until(lambda: gain(rig, "pid_controller", "gains.joint1.p") != ACCELERATION_GAINS["p"],
                   "the autotune's gains on the controller", timeout_s=120, every_s=0.2)
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait(10)
    assert process.returncode == 130 and "interrupted" in err, err
    assert {name: gain(rig, "pid_controller", f"gains.joint1.{name}") for name in "pid"} == ACCELERATION_GAINS
    assert not (tmp_path / "metrics.json").exists()


def test_a_robust_design_of_the_acceleration_loop_is_refused_before_anything_is_sent(rig, tmp_path) -> None:
    """--robust varies a simulated robot, whose pid_controller commands an effort: the mock's acceleration joint has
    no such twin (jointctl's robots take efforts), and is refused in one line before the design runs."""
    result = jointctl(rig, "autotune", str(RIG / "robot.urdf"), "--controllers", str(RIG / "controllers.yaml"),
                      "--hardware", "ros2", "--controller", "pid_controller", "--bandwidth-hz", "2", "--robust",
                      "payload_kg=0:1", "--out", str(tmp_path))
    errors = [line for line in result.stderr.splitlines() if line.startswith("jointctl: error:")]
    assert result.returncode == 2 and len(errors) == 1, result.stderr
    assert "--robust" in errors[0] and "acceleration" in errors[0]
    assert {name: gain(rig, "pid_controller", f"gains.joint1.{name}") for name in "pid"} == ACCELERATION_GAINS
    assert not (tmp_path / "metrics.json").exists()


#: The 1-DOF robot: a 1.01 kg vertical piston (g 9.81 m/s²), the robot jointctl serves as a ros2_control robot.
PISTON_KG, G = 1.01, 9.81


@pytest.fixture(scope="module")
def served_piston(ros2_env, tmp_path_factory):
    """``jointctl serve one_dof --ros2 --controllers ros2`` (pid_controller on the piston's effort, 1 kHz) on a DDS
    domain of its own (the mock rig's controller manager has the same names), its pid_controller holding -0.5 m."""
    from tests.ros2.conftest import SETUP
    from tests.ros2.environment import release_domain, ros2_environment, stop_daemon, take_domain
    from tests.ros2.served import ServedRobot

    domain = take_domain(besides=(int(ros2_env["ROS_DOMAIN_ID"]),))
    folder = tmp_path_factory.mktemp("served_piston")
    env = ros2_environment(SETUP, domain, folder / "ros_log")
    env["PYTHONPATH"] = f"{ROOT / 'src'}:{env.get('PYTHONPATH', '')}"
    robot = ServedRobot(env, folder / "serve.log", "one_dof", "--controllers", "ros2")
    try:
        robot.wait_up(["joint_state_broadcaster", "pid_controller"])
        ros2(env, "topic", "pub", "-r", "20", "-t", "10", "/pid_controller/reference",
             "control_msgs/msg/MultiDOFCommand", "{dof_names: [joint1], values: [-0.5]}")
        robot.rest("joint1")
        yield env
    finally:
        robot.stop()
        stop_daemon(env)
        release_domain(domain)


def test_a_robust_design_runs_its_family_on_the_simulated_twin_and_checks_the_served_robot(served_piston,
                                                                                          tmp_path) -> None:
    """jointctl's served 1-DOF robot as the ros2_control robot, its own robot folder as the twin: the family
    (payload 0-1 kg) runs in simulation, the robust gains then step the robot. The robot is the family's 0 kg
    plant, so its step is that plant's run: the same overshoot and rest (m·g/p short of the reference: gravity
    binds there, and on the robot), its settling later by at most the reference's way to it; the gains go back."""
    env = served_piston
    result = jointctl(env, "autotune", "one_dof", "--hardware", "ros2", "--controller", "pid_controller",
                      "--overshoot-pct", "10", "--settling-s", "0.3", "--step", "0.1", "--robust", "payload_kg=0:1",
                      "--robust-samples", "0", "--out", str(tmp_path), timeout=600)
    assert result.returncode == 0, result.stderr
    tuned = json.loads(result.stdout)
    robust, robot = tuned["robust"], tuned["robot"]
    assert robust["law"] == "control_toolbox" and len(robust["robot"]) == 2 + 1
    assert all(not row.get("error") for row in robust["robot"])
    twin = next(row for row in robust["robot"] if row["values"] == {"payload_kg": 0.0})
    p = robust["gains"]["p"]
    assert robot["gains"] == {k: pytest.approx(round(robust["gains"][k], 6)) for k in ("p", "i", "d")}
    assert robot["step_overshoot_pct"] == pytest.approx(twin["overshoot_pct"], abs=0.05)
    assert robot["step_final_error"] == pytest.approx(PISTON_KG * G / p, rel=1e-4)
    assert twin["final_error"] == pytest.approx(PISTON_KG * G / p, rel=1e-4)
    assert -0.001 <= robot["step_settling_s"] - twin["settling_s"] <= DELAY_BUDGET_S  # a 1 ms cycle's reading
    assert robot["binds"] == twin["binds"] == ["gravity"]
    assert "on the robot, the step of 0.1 misses the spec" in result.stderr
    # The gains found are back; the file is the controller's parameters with the robust gains, as ROS 2 reads it.
    assert tuned["gains_restored"] == {"p": 400.0, "i": 0.0, "d": 20.0}
    assert {name: gain(env, "pid_controller", f"gains.joint1.{name}") for name in "pid"} == tuned["gains_restored"]
    written = yaml.safe_load((tmp_path / "pid_controller_tuned.yaml").read_text())
    joint1 = written["pid_controller"]["ros__parameters"]["gains"]["joint1"]
    assert (joint1["p"], joint1["i"], joint1["d"]) == (robot["gains"]["p"], robot["gains"]["i"], robot["gains"]["d"])
