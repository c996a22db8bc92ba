"""CartesianAdmittanceController: the 7-DOF NAC's kinematics, one cycle's arithmetic, the single
integration per cycle, saturation, the wrist servo, the tare, refusals and chaining.

Theory (chapter 11.6): each cycle ``f = K (p_att - p) - B Jv q̇ + F`` (F the sensed force in the
base frame), ``τ = Jvᵀ f``, ``q̈ = H⁻¹ (τ - c q̇)``, ``q̇_cmd += q̈ dt`` once, clamped to the
velocity limits. With wrist joints W servoing the flange orientation, the arm joints A follow
``(Tᵀ H T) q̈_A = Tᵀ (Jvᵀ f - c q̇)`` with ``T = [I; -Jr_W⁺ Jr_A]`` and the wrist gets
``q̇_W = Jr_W⁺ (k e - Jr_A q̇_A)``. The hand computations below use a Jacobian from finite
differences of the forward kinematics (the robot's own model, jointctl.model.dynamics), not its Jacobian.
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
import yaml

from jointctl.control import CartesianAdmittanceController, ControllerManager, JointVelocityController
from jointctl.control.cartesian_admittance_controller import _cholesky_solve, rotation_vector
from jointctl.control.registry import controller_types
from jointctl.errors import ConfigError, ControllerError
from jointctl.hardware.interface import EFFORT
from jointctl.model import load_robot_model
from jointctl.model.dynamics import RobotDynamics
from jointctl.paths import robots_dir

from .conftest import FakeHardware

ARM_DIR = robots_dir() / "arm7dof"
NAC_YAML = ARM_DIR / "config" / "arm7dof_nac_params.yaml"
NAMESPACE = "arm7dof"
NAC = "arm7dof_nac_controller"
FIELD = f"{NAMESPACE}.{NAC}"
JOINTS = tuple(f"joint{k}" for k in range(7))
VELS = tuple(f"joint{k}_velocity_controller" for k in range(7))
PRE_POSE = (0.0, 1.0, 0.0, -2.0, 0.0, 1.0, 0.0)
LIMITS = np.array([0.2, 0.2, 0.3, 0.3, 0.4, 0.5, 0.4])  # the chapter's velocity limits [rad/s]
KV = np.array([5000.0, 5000.0, 5000.0, 3000.0, 1000.0, 1000.0, 500.0])  # the chapter's velocity gains
DT = 0.001


class SensorHardware(FakeHardware):
    """The control tests' fake hardware with a settable force-torque sensor."""

    def __init__(self, joint_names=JOINTS, sensor_names=("ft_sensor",)) -> None:
        super().__init__(tuple(joint_names))
        self.sensor_names = tuple(sensor_names)
        self.wrenches = {s: [0.0] * 6 for s in self.sensor_names}

    def set_wrench(self, sensor: str, values) -> None:
        self.wrenches[sensor][:] = [float(v) for v in values]  # in place: controllers hold the list

    def set_joints(self, q, qd=None) -> None:
        qd = [0.0] * len(q) if qd is None else qd
        for name, value, rate in zip(self.joint_names, q, qd):
            self.set_state(name, float(value), float(rate))


@pytest.fixture(scope="module")
def arm():
    return load_robot_model(ARM_DIR / "urdf" / "arm7dof.xacro")


class FlangeKinematics:
    """The flange (link8) and the sensor frame of the arm's own model, as copies for hand computations."""

    def __init__(self, arm) -> None:
        self.dynamics = RobotDynamics(arm, joints=JOINTS)
        self.flange, self.sensor = self.dynamics.frame("link8"), self.dynamics.frame("ft_sensor_link")

    def set_pose(self, q, *, inertia: bool = False) -> None:
        self.dynamics.set_pose(q, inertia=inertia)

    @property
    def position(self) -> np.ndarray:
        return self.flange.position.copy()

    @property
    def rotation(self) -> np.ndarray:
        return self.flange.rotation.copy()

    @property
    def sensor_rotation(self) -> np.ndarray:
        return self.sensor.rotation.copy()

    def jacobians(self) -> tuple[np.ndarray, np.ndarray]:
        jv, jr = self.flange.jacobians()
        return jv.copy(), jr.copy()

    def mass_matrix(self) -> np.ndarray:
        return self.dynamics.mass_matrix()


@pytest.fixture(scope="module")
def kin(arm) -> FlangeKinematics:
    return FlangeKinematics(arm)


@pytest.fixture
def hw() -> SensorHardware:
    hardware = SensorHardware()
    hardware.set_joints(PRE_POSE)
    return hardware


def definitions(**changes) -> dict:
    """The arm's NAC file; keyword arguments replace NAC keys (``None`` removes one)."""
    tree = yaml.safe_load(NAC_YAML.read_text())
    controllers = copy.deepcopy(tree[NAMESPACE])
    for key, value in changes.items():
        if value is None:
            controllers[NAC].pop(key, None)
        else:
            controllers[NAC][key] = value
    return {NAMESPACE: controllers}


@pytest.fixture
def make_manager(hw, arm, write_yaml):
    def make(**changes) -> ControllerManager:
        manager = ControllerManager(hw, arm, (0.0, 0.0, -0.5))
        manager.load_file(write_yaml(definitions(**changes)))
        return manager

    return make


def started(make_manager, **changes) -> tuple[ControllerManager, CartesianAdmittanceController]:
    manager = make_manager(**changes)
    manager.start([*VELS, NAC])
    return manager, manager.controller(NAC)


def plain(**changes) -> dict:
    """No wrist servo, no tare: exactly the chapter's q̈ = H⁻¹(Jvᵀ f - c q̇)."""
    return {"wrist_joints": [], "tare": False, **changes}


def fd_kinematics(kin: FlangeKinematics, q, h: float = 1e-6):
    """Flange position, rotation, sensor rotation and a central-difference Jacobian (Jv, Jr)."""
    q = np.asarray(q, dtype=float)
    kin.set_pose(q)
    p0, r0, rs = kin.position, kin.rotation, kin.sensor_rotation
    jv, jr = np.zeros((3, len(q))), np.zeros((3, len(q)))
    for i in range(len(q)):
        dq = np.zeros(len(q))
        dq[i] = h
        kin.set_pose(q + dq)
        p_plus, r_plus = kin.position, kin.rotation
        kin.set_pose(q - dq)
        p_minus, r_minus = kin.position, kin.rotation
        jv[:, i] = (p_plus - p_minus) / (2 * h)
        jr[:, i] = rotation_vector(r_plus @ r_minus.T) / (2 * h)
    kin.set_pose(q)
    return p0, r0, rs, jv, jr


# -- registration and the file -------------------------------------------------------------
def test_the_type_is_registered_by_importing_jointctl_control() -> None:
    cls = controller_types()["admittance_controllers/CartesianAdmittanceController"]
    assert cls is CartesianAdmittanceController


def test_the_arm_file_loads_with_the_chapters_values(make_manager, arm) -> None:
    nac = make_manager().load(NAC)
    assert isinstance(nac, CartesianAdmittanceController)
    assert nac.joint_names == JOINTS
    assert nac.joints == ()
    assert nac.downstream == VELS
    assert nac.claimed_interfaces() == tuple((v, "reference") for v in VELS)
    assert nac.attractor.tolist() == [0.0, 0.0, 1.5]
    assert nac.stiffness.tolist() == [100.0, 100.0, 10.0]
    assert nac.damping.tolist() == [10.0, 10.0, 10.0]
    assert nac.inertia_estimate.tolist() == [20.0, 20.0, 10.0, 10.0, 3.0, 3.0, 3.0]
    assert nac.joint_damping.tolist() == [1.0] * 7
    assert nac.wrist_joints == (4, 5, 6) and nac.arm_joints == (0, 1, 2, 3)
    assert nac.wrist_gain == 20.0
    assert nac.tare is True and nac.use_model_inertia is False
    assert nac.frame == "link8"
    np.testing.assert_array_equal(nac.max_velocity, LIMITS)  # default: the joints' limits
    assert nac.field == FIELD


def test_frame_defaults_to_the_sensor_link_and_wrist_to_the_last_three(make_manager) -> None:
    nac = make_manager(frame=None, wrist_joints=None, wrist_gain=None).load(NAC)
    assert nac.frame == "ft_sensor_link"
    assert nac.wrist_joints == (4, 5, 6) and nac.wrist_gain == 20.0


def test_scalar_max_velocity_and_joint_damping_apply_to_every_joint(make_manager) -> None:
    nac = make_manager(max_velocity=0.1, joint_damping=2.5).load(NAC)
    assert nac.max_velocity.tolist() == [0.1] * 7
    assert nac.joint_damping.tolist() == [2.5] * 7


# -- kinematics ----------------------------------------------------------------------------
def test_the_pre_pose_puts_the_flange_where_the_chapter_says(kin) -> None:
    kin.set_pose(PRE_POSE)
    np.testing.assert_allclose(kin.position, [0.0, 0.05, 1.63], atol=0.002)
    np.testing.assert_allclose(kin.rotation, np.eye(3), atol=0.002)  # pointing up
    kin.set_pose(np.zeros(7))
    np.testing.assert_allclose(kin.position, [0.0, 0.05, 2.55], atol=0.002)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_model_jacobian_matches_finite_differences_of_forward_kinematics(kin, seed) -> None:
    q = np.array(PRE_POSE) + np.random.default_rng(seed).uniform(-0.5, 0.5, 7)
    _, _, _, jv_fd, jr_fd = fd_kinematics(kin, q)
    kin.set_pose(q)
    jv, jr = kin.jacobians()
    np.testing.assert_allclose(jv, jv_fd, atol=1e-7)
    np.testing.assert_allclose(jr, jr_fd, atol=1e-7)


def test_the_controller_uses_the_robot_dynamics_of_its_joints_and_frames(make_manager, arm) -> None:
    nac = make_manager().load(NAC)
    assert isinstance(nac.dynamics, RobotDynamics) and nac.dynamics.joint_names == JOINTS
    assert (nac.flange.link, nac.sensor_frame.link) == ("link8", "ft_sensor_link")


def test_rotation_vector_is_axis_times_angle() -> None:
    angle, axis = 0.3, np.array([1.0, 2.0, -2.0]) / 3.0
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rotation = np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k  # Rodrigues
    np.testing.assert_allclose(rotation_vector(rotation), angle * axis, atol=1e-12)
    assert np.allclose(rotation_vector(np.eye(3)), 0.0)


# -- one cycle's arithmetic ------------------------------------------------------------------
class StubFrame:
    """A hand-picked frame: origin at ``p``, axes ``rotation``, Jacobians given."""

    def __init__(self, p=(0.0, 0.0, 0.0), rotation=None, jv=None, jr=None) -> None:
        self.position = np.array(p, dtype=float)
        self.rotation = np.eye(3) if rotation is None else np.array(rotation, dtype=float)
        self._jv = np.zeros((3, 7)) if jv is None else np.array(jv, dtype=float)
        self._jr = np.zeros((3, 7)) if jr is None else np.array(jr, dtype=float)

    def jacobians(self):
        return self._jv, self._jr


class StubDynamics:
    def set_pose(self, q, *, inertia=False) -> None:
        pass


def test_one_update_by_hand_with_stub_kinematics(make_manager, hw) -> None:
    manager, nac = started(make_manager, **plain(
        attractor=[0.0, 0.0, 1.5], stiffness=[100.0, 100.0, 10.0], damping=[10.0, 10.0, 10.0],
        joint_damping=1.0, inertia_estimate=[20, 20, 10, 10, 3, 3, 3], max_velocity=10.0))
    jv = np.zeros((3, 7))
    jv[0, 0], jv[1, 1], jv[2, 2], jv[2, 3] = 1.0, 2.0, 0.5, -1.0
    rs = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # sensor turned 90° about z
    nac.dynamics, nac.flange, nac.sensor_frame = StubDynamics(), StubFrame([0.01, -0.02, 1.45], jv=jv), \
        StubFrame(rotation=rs)
    hw.set_joints(PRE_POSE, [0.01, 0.0, 0.02, 0.0, 0.0, 0.0, 0.0])
    hw.set_wrench("ft_sensor", [0.5, 0.0, -3.0, 9.0, 9.0, 9.0])  # torques are ignored
    nac.update(0.0, DT)
    # v = Jv q̇ = (0.01, 0, 0.01); F = rs·(0.5, 0, -3) = (0, 0.5, -3)
    # f = K (p_att - p) - B v + F = (-1 - 0.1 + 0, 2 - 0 + 0.5, 0.5 - 0.1 - 3) = (-1.1, 2.5, -2.6)
    np.testing.assert_allclose(nac.velocity, [0.01, 0.0, 0.01], atol=1e-15)
    np.testing.assert_allclose(nac.force, [0.0, 0.5, -3.0], atol=1e-15)
    np.testing.assert_allclose(nac.virtual_force, [-1.1, 2.5, -2.6], atol=1e-12)
    # τ = Jvᵀ f = (-1.1, 5.0, -1.3, 2.6, 0, 0, 0); q̈ = (τ - 1·q̇) / H
    tau = np.array([-1.1, 5.0, -1.3, 2.6, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(nac.torque, tau, atol=1e-12)
    qdd = (tau - np.array([0.01, 0.0, 0.02, 0, 0, 0, 0])) / np.array([20, 20, 10, 10, 3, 3, 3])
    np.testing.assert_allclose(nac.acceleration, qdd, atol=1e-12)
    np.testing.assert_allclose(nac.velocity_command, qdd * DT, atol=1e-15)
    assert [manager.controller(v).reference_input for v in VELS] == nac.velocity_command


def test_one_update_on_the_real_arm_matches_a_hand_computation(make_manager, hw, kin) -> None:
    q = np.array([0.1, 1.1, -0.2, -1.9, 0.15, 0.9, -0.1])
    qd = np.array([0.01, -0.02, 0.03, 0.0, 0.02, -0.01, 0.005])
    wrench = [0.3, -0.4, -5.0, 0.0, 0.0, 0.0]
    h = np.array([20.0, 20.0, 10.0, 10.0, 3.0, 3.0, 3.0])
    manager, nac = started(make_manager, **plain(max_velocity=10.0))
    hw.set_joints(q, qd)
    hw.set_wrench("ft_sensor", wrench)
    manager.update(0.0, DT)
    p, _, rs, jv, _ = fd_kinematics(kin, q)
    force = rs @ np.array(wrench[:3])
    f = np.array([100.0, 100.0, 10.0]) * (np.array([0.0, 0.0, 1.5]) - p) - 10.0 * (jv @ qd) + force
    qdd = (jv.T @ f - 1.0 * qd) / h
    np.testing.assert_allclose(nac.position, p, atol=1e-12)
    np.testing.assert_allclose(nac.force, force, atol=1e-12)
    np.testing.assert_allclose(nac.virtual_force, f, rtol=1e-6)
    np.testing.assert_allclose(nac.velocity_command, qdd * DT, rtol=1e-6, atol=1e-12)


def test_model_inertia_replaces_the_constant_estimate(make_manager, hw, kin) -> None:
    q, qd = np.array(PRE_POSE), np.array([0.0, 0.01, 0.0, -0.01, 0.0, 0.0, 0.0])
    manager, nac = started(make_manager, **plain(use_model_inertia=True, inertia_estimate=None,
                                                 max_velocity=10.0))
    hw.set_joints(q, qd)
    hw.set_wrench("ft_sensor", [0.0, 0.0, -5.0, 0, 0, 0])
    nac.update(0.0, DT)
    kin.set_pose(q, inertia=True)
    m = kin.mass_matrix()
    np.testing.assert_allclose(nac.acceleration, np.linalg.solve(m, nac.torque - qd), rtol=1e-10)


def test_q_ddot_dt_is_added_once_per_cycle(make_manager, hw) -> None:
    # The chapter's code adds q̈·dt twice per cycle (halving the effective inertia): not here.
    manager, nac = started(make_manager, **plain(max_velocity=10.0, joint_damping=0.0, damping=[0, 0, 0]))
    hw.set_joints(PRE_POSE)
    hw.set_wrench("ft_sensor", [0.0, 0.0, -20.0, 0, 0, 0])
    nac.update(0.0, DT)
    qdd = np.array(nac.acceleration)
    first = np.array(nac.velocity_command)
    np.testing.assert_allclose(first, qdd * DT, rtol=1e-12, atol=1e-18)
    nac.update(DT, DT)  # the same state: the same q̈ again, added once more
    np.testing.assert_allclose(nac.velocity_command, 2 * qdd * DT, rtol=1e-12, atol=1e-18)
    nac.update(2 * DT, 0.002)  # integrated over the period given
    np.testing.assert_allclose(nac.velocity_command, 4 * qdd * DT, rtol=1e-12, atol=1e-18)


def test_an_unloaded_flange_at_the_attractor_at_rest_commands_nothing(make_manager, hw, kin) -> None:
    kin.set_pose(PRE_POSE)
    manager, nac = started(make_manager, **plain(attractor=kin.position.tolist()))
    for k in range(3):
        manager.update(k * DT, DT)
    assert np.abs(nac.velocity_command).max() < 1e-12


# -- saturation ----------------------------------------------------------------------------
def test_velocity_commands_saturate_at_the_joint_limits_and_the_integrator_holds_the_limit(
        make_manager, hw) -> None:
    manager, nac = started(make_manager, **plain(stiffness=[0, 0, 0], damping=[0, 0, 0], joint_damping=0.0))
    hw.set_wrench("ft_sensor", [300.0, -300.0, 300.0, 0, 0, 0])
    for k in range(200):
        nac.update(k * DT, DT)
    command = np.array(nac.velocity_command)
    assert np.all(np.abs(command) <= LIMITS + 1e-15)
    saturated = np.isclose(np.abs(command), LIMITS)
    assert saturated.sum() >= 3
    np.testing.assert_allclose(nac.velocity_reference, command)  # the state is the clamped value
    # Reversing the force comes back from the clamp, not from the unclamped integral.
    before = command.copy()
    hw.set_wrench("ft_sensor", [-300.0, 300.0, -300.0, 0, 0, 0])
    nac.update(1.0, DT)
    np.testing.assert_allclose(nac.velocity_command, np.clip(before + np.array(nac.acceleration) * DT, -LIMITS, LIMITS),
                               rtol=1e-12)


def test_max_velocity_overrides_the_limits(make_manager, hw) -> None:
    manager, nac = started(make_manager, **plain(stiffness=[0, 0, 0], max_velocity=[0.01] * 7))
    hw.set_wrench("ft_sensor", [300.0, 300.0, 300.0, 0, 0, 0])
    for k in range(100):
        nac.update(k * DT, DT)
    assert np.abs(nac.velocity_command).max() == pytest.approx(0.01)


# -- the wrist servo -------------------------------------------------------------------------
def test_the_wrist_cancels_the_arm_joints_rotation_of_the_flange(make_manager, hw, kin) -> None:
    manager, nac = started(make_manager, tare=False, max_velocity=10.0)
    hw.set_wrench("ft_sensor", [2.0, -1.0, -5.0, 0, 0, 0])
    for k in range(20):
        nac.update(k * DT, DT)
    kin.set_pose(PRE_POSE)
    jv, jr = kin.jacobians()
    command = np.array(nac.velocity_command)
    arm_only = command.copy()
    arm_only[4:] = 0.0
    assert np.linalg.norm(jr @ arm_only) > 1e-4  # the arm joints alone would turn the flange...
    # ...the wrist cancels that (to the damped least squares' 0.1 %)
    assert np.linalg.norm(jr @ command) < 1e-3 * np.linalg.norm(jr @ arm_only)
    assert np.linalg.norm(jv @ command) > 1e-4


def test_the_wrist_servos_an_orientation_error_at_the_wrist_gain(make_manager, hw, kin) -> None:
    manager, nac = started(make_manager, tare=False, wrist_gain=20.0)
    angle = 0.01
    nac.target_rotation = nac.target_rotation @ np.array(
        [[1, 0, 0], [0, math.cos(angle), -math.sin(angle)], [0, math.sin(angle), math.cos(angle)]])
    nac.update(0.0, DT)
    kin.set_pose(PRE_POSE)
    _, jr = kin.jacobians()
    np.testing.assert_allclose(nac.orientation_error, [angle, 0.0, 0.0], atol=1e-9)
    # the flange turns back at wrist_gain·e (to the damped least squares' 0.1 %)
    np.testing.assert_allclose(jr @ np.array(nac.velocity_command), [20.0 * angle, 0.0, 0.0],
                               atol=1e-3 * 20 * angle)


def test_with_the_wrist_the_arm_joints_follow_the_constrained_dynamics(make_manager, hw, kin) -> None:
    q = np.array([0.1, 1.1, -0.2, -1.9, 0.15, 0.9, -0.1])
    qd = np.array([0.01, -0.02, 0.03, 0.0, 0.02, -0.01, 0.005])
    manager, nac = started(make_manager, tare=False, max_velocity=10.0)
    hw.set_joints(q, qd)
    hw.set_wrench("ft_sensor", [0.3, -0.4, -5.0, 0, 0, 0])
    nac.update(0.0, DT)
    kin.set_pose(q)
    jv, jr = kin.jacobians()
    a, w = [0, 1, 2, 3], [4, 5, 6]
    pinv = np.linalg.pinv(jr[:, w])
    t = np.vstack([np.eye(4), -pinv @ jr[:, a]])
    h = np.diag([20.0, 20.0, 10.0, 10.0, 3.0, 3.0, 3.0])
    qdd = np.linalg.solve(t.T @ h @ t, t.T @ (jv.T @ nac.virtual_force - qd))
    np.testing.assert_allclose(nac.acceleration, qdd, rtol=1e-3)
    np.testing.assert_allclose(nac.velocity_command[:4], qdd * DT, rtol=1e-3)
    wrist = pinv @ (20.0 * np.array(nac.orientation_error) - jr[:, a] @ (qdd * DT))
    np.testing.assert_allclose(nac.velocity_command[4:], wrist, rtol=1e-3, atol=1e-9)


@pytest.mark.parametrize("model_inertia", [False, True])
@pytest.mark.parametrize("wrist", [[4, 5, 6], [5, 6], [3, 4, 5, 6]])
def test_the_wrist_dynamics_are_the_documented_formula_evaluated_literally(make_manager, hw, kin, model_inertia,
                                                                          wrist) -> None:
    """T = [I; -P], P = Jr_Wᵀ·(Jr_W·Jr_Wᵀ + λ²·I)⁻¹·Jr_A; (Tᵀ·H·T)·q̈_A = Tᵀ·(Jvᵀ·f - c·q̇);
    q̇_W = Jr_Wᵀ·(Jr_W·Jr_Wᵀ + λ²·I)⁻¹·(k·e - Jr_A·q̇_A): to rounding, whatever the wrist joints."""
    q = np.array([0.1, 1.1, -0.2, -1.9, 0.15, 0.9, -0.1])
    qd = np.array([0.01, -0.02, 0.03, 0.0, 0.02, -0.01, 0.005])
    changes = {"use_model_inertia": True, "inertia_estimate": None} if model_inertia else {}
    manager, nac = started(make_manager, tare=False, max_velocity=10.0, wrist_joints=wrist, **changes)
    hw.set_joints(q, qd)
    hw.set_wrench("ft_sensor", [0.3, -0.4, -5.0, 0, 0, 0])
    angle = 1e-4  # an orientation error to servo
    nac.target_rotation = nac.target_rotation @ np.array(
        [[1, 0, 0], [0, math.cos(angle), -math.sin(angle)], [0, math.sin(angle), math.cos(angle)]])
    nac.update(0.0, DT)
    kin.set_pose(q, inertia=True)
    jv, jr = kin.flange.jacobians()
    a = [k for k in range(7) if k not in wrist]
    dls = jr[:, wrist].T @ np.linalg.inv(jr[:, wrist] @ jr[:, wrist].T + 0.01**2 * np.eye(3))
    t = np.vstack([np.eye(len(a)), -dls @ jr[:, a]])[np.argsort(a + wrist)]  # rows in joint order
    h = kin.mass_matrix() if model_inertia else np.diag([20.0, 20.0, 10.0, 10.0, 3.0, 3.0, 3.0])
    qdd = np.linalg.solve(t.T @ h @ t, t.T @ (jv.T @ nac.virtual_force - 1.0 * qd))
    np.testing.assert_allclose(nac.acceleration, qdd, rtol=1e-9)
    command = np.array(nac.velocity_command)
    np.testing.assert_allclose(command[a], qdd * DT, rtol=1e-9)
    e = rotation_vector(nac.target_rotation @ kin.rotation.T)
    np.testing.assert_allclose(nac.orientation_error, e, atol=1e-15)
    expected = dls @ (20.0 * e - jr[:, a] @ (qdd * DT))
    assert np.abs(expected).max() < 10.0  # within max_velocity: not clamped
    np.testing.assert_allclose(command[wrist], expected, rtol=1e-9)


# -- tare ------------------------------------------------------------------------------------
def test_tare_averages_while_holding_still_then_subtracts(make_manager, hw, kin) -> None:
    manager, nac = started(make_manager, tare=True, tare_time_s=0.005, wrist_joints=[])
    readings = [[0.0, 0.0, -0.04], [0.0, 0.0, -0.05], [0.0, 0.0, -0.06], [0.01, 0.0, -0.05],
                [-0.01, 0.0, -0.05]]
    for k, r in enumerate(readings):  # five cycles of 1 ms: the tare window
        hw.set_wrench("ft_sensor", [*r, 0, 0, 0])
        manager.update(k * DT, DT)
        assert nac.velocity_command == [0.0] * 7
        assert [manager.controller(v).reference_input for v in VELS] == [0.0] * 7
    kin.set_pose(PRE_POSE)
    expected_tare = kin.sensor_rotation @ np.mean(readings, axis=0)
    np.testing.assert_allclose(nac.tare_force, expected_tare, atol=1e-15)
    hw.set_wrench("ft_sensor", [0.0, 0.0, -5.05, 0, 0, 0])
    manager.update(5 * DT, DT)
    np.testing.assert_allclose(nac.force, kin.sensor_rotation @ [0, 0, -5.05] - expected_tare, atol=1e-12)
    assert np.abs(nac.velocity_command).max() > 0


def test_tare_time_zero_takes_the_reading_at_start_and_tare_false_counts_the_plate(make_manager, hw) -> None:
    hw.set_wrench("ft_sensor", [0.0, 0.0, -0.05, 0, 0, 0])
    manager, nac = started(make_manager, tare=True, tare_time_s=0.0)
    assert nac.tare_force[2] == pytest.approx(-0.05, abs=0.002)
    nac.update(0.0, DT)
    assert np.linalg.norm(nac.force) < 1e-12 and np.abs(nac.velocity_command).max() > 0
    manager2, nac2 = started(make_manager, tare=False)
    assert nac2.tare_force.tolist() == [0.0, 0.0, 0.0]
    nac2.update(0.0, DT)
    assert nac2.force[2] == pytest.approx(-0.05, abs=0.002)


def test_starting_again_resets_the_integrator_and_the_orientation(make_manager, hw) -> None:
    manager, nac = started(make_manager, **plain(stiffness=[0, 0, 0]))
    hw.set_wrench("ft_sensor", [0, 0, -10.0, 0, 0, 0])
    for k in range(5):
        nac.update(k * DT, DT)
    assert np.abs(nac.velocity_reference).max() > 0
    manager.stop([NAC, *VELS])
    manager.start([*VELS, NAC])
    assert list(nac.velocity_reference) == [0.0] * 7
    assert nac.velocity_command == [0.0] * 7


# -- set_gains -------------------------------------------------------------------------------
def test_set_gains_changes_all_or_nothing(make_manager) -> None:
    manager, nac = started(make_manager)
    nac.set_gains(stiffness=[50, 50, 5], damping=[20, 20, 30], attractor=[0.1, 0.0, 1.4])
    assert nac.stiffness.tolist() == [50, 50, 5] and nac.damping.tolist() == [20, 20, 30]
    assert nac.attractor.tolist() == [0.1, 0.0, 1.4]
    for bad in ({"stiffness": [1, 2]}, {"damping": [1, -2, 3]}, {"inertia_estimate": [1, 1, 1, 1, 1, 1, 0]},
                {"attractor": [0, 0, math.nan]}, {"stiffness": [1, 2, 3], "damping": "x"}):
        with pytest.raises(ConfigError) as info:
            nac.set_gains(**bad)
        assert info.value.field in bad
    assert nac.stiffness.tolist() == [50, 50, 5] and nac.damping.tolist() == [20, 20, 30]


# -- refusals --------------------------------------------------------------------------------
@pytest.mark.parametrize(("changes", "field"), [
    ({"attractor": [0.0, 1.5]}, "attractor"),
    ({"attractor": None}, "attractor"),
    ({"attractor": [0.0, "up", 1.5]}, "attractor[1]"),
    ({"stiffness": [100.0, 100.0]}, "stiffness"),
    ({"stiffness": [100.0, -1.0, 10.0]}, "stiffness[1]"),
    ({"damping": [10.0, 10.0, 10.0, 10.0]}, "damping"),
    ({"damping": [10.0, 10.0, -10.0]}, "damping[2]"),
    ({"damping": [10.0, math.inf, 10.0]}, "damping[1]"),
    ({"inertia_estimate": [20.0, 20.0, 10.0, 10.0, 3.0]}, "inertia_estimate"),
    ({"inertia_estimate": [20.0, 20.0, 10.0, 0.0, 3.0, 3.0, 3.0]}, "inertia_estimate[3]"),
    ({"inertia_estimate": [20.0, 20.0, 10.0, 10.0, 3.0, -3.0, 3.0]}, "inertia_estimate[5]"),
    ({"inertia_estimate": None}, "inertia_estimate"),
    ({"joint_damping": [1.0, 1.0]}, "joint_damping"),
    ({"joint_damping": -1.0}, "joint_damping[0]"),
    ({"max_velocity": [0.2] * 6}, "max_velocity"),
    ({"max_velocity": 0.0}, "max_velocity[0]"),
    ({"velocity_controllers": list(VELS[:6])}, "velocity_controllers"),
    ({"joints": ["joint0", "joint1", "joint1"]}, "joints[2]"),
    ({"wrist_joints": [4, 5, 7]}, "wrist_joints[2]"),
    ({"wrist_joints": [4, 4]}, "wrist_joints[1]"),
    ({"wrist_joints": list(range(7))}, "wrist_joints"),
    ({"wrist_gain": -1.0}, "wrist_gain"),
    ({"use_model_inertia": "yes"}, "use_model_inertia"),
    ({"tare": 1}, "tare"),
    ({"tare_time_s": -0.1}, "tare_time_s"),
    ({"frame": ""}, "frame"),
    ({"stifness": [1, 1, 1]}, "stifness"),
])
def test_bad_parameters_are_refused_naming_the_field(make_manager, changes, field) -> None:
    with pytest.raises(ConfigError) as info:
        make_manager(**changes).load(NAC)
    assert info.value.field == f"{FIELD}.{field}"


@pytest.mark.parametrize(("changes", "field"), [
    ({"sensor": "wrist_sensor"}, "sensor"),
    ({"joints": ["joint0", "joint1", "joint2", "joint3", "joint4", "joint5", "elbow"]}, "joints[6]"),
    ({"frame": "link9"}, "frame"),
])
def test_unknown_sensor_joint_or_frame_is_refused_naming_the_field(make_manager, changes, field) -> None:
    with pytest.raises(ConfigError) as info:
        make_manager(**changes).load(NAC)
    assert info.value.field == f"{FIELD}.{field}"
    assert info.value.has_value


# -- chaining --------------------------------------------------------------------------------
def test_it_runs_before_the_velocity_controllers_in_the_same_cycle(make_manager, hw) -> None:
    manager = make_manager(**plain(max_velocity=10.0))
    manager.start([*VELS, NAC])  # started after them, still updated first
    assert manager.active[0].name == NAC
    assert {c.name for c in manager.active} == {NAC, *VELS}
    nac = manager.controller(NAC)
    qd = np.array([0.0, 0.01, 0.0, -0.02, 0.0, 0.0, 0.0])
    hw.set_joints(PRE_POSE, qd)
    hw.set_wrench("ft_sensor", [0.0, 0.0, -5.0, 0, 0, 0])
    manager.update(0.0, DT)
    command = np.array(nac.velocity_command)
    assert np.abs(command).max() > 0
    np.testing.assert_allclose(manager.references, command, rtol=1e-12)  # this cycle's command
    np.testing.assert_allclose(hw.command_buffer(EFFORT), KV * (command - qd), rtol=1e-12)
    for k, name in enumerate(VELS):
        assert manager.command_owner(name) is nac
        assert isinstance(manager.controller(name), JointVelocityController)


def test_it_needs_its_velocity_controllers_running(make_manager) -> None:
    manager = make_manager()
    with pytest.raises(ControllerError) as info:
        manager.start([*VELS[:6], NAC])
    assert info.value.value == NAC
    assert VELS[6] in str(info.value)


def test_velocity_controllers_must_match_the_joints_in_order(make_manager) -> None:
    swapped = [VELS[1], VELS[0], *VELS[2:]]
    manager = make_manager(velocity_controllers=swapped)
    with pytest.raises(ConfigError) as info:
        manager.start([*VELS, NAC])
    assert info.value.field == f"{FIELD}.velocity_controllers[0]"
    assert not manager.active


def test_nothing_else_may_command_its_velocity_controllers(make_manager, write_yaml, hw, arm) -> None:
    tree = definitions()
    tree[NAMESPACE]["second_nac"] = copy.deepcopy(tree[NAMESPACE][NAC])
    manager = ControllerManager(hw, arm)
    manager.load_file(write_yaml(tree))
    manager.start([*VELS, NAC])
    with pytest.raises(ControllerError) as info:
        manager.start(["second_nac"])
    assert "already claimed" in str(info.value)


@pytest.mark.parametrize("n", [1, 2, 3, 5, 7])
def test_the_cholesky_solve_is_numpys_solve_within_the_conditioning_bound(n) -> None:
    """Cholesky is backward stable: the computed x solves (A + ΔA)·x = b with |ΔA| <= γ_{3n+1}·|Lᵀ|·|L|
    (Higham, Accuracy and Stability of Numerical Algorithms, theorem 10.4), so its error relative to ‖x‖ is at
    most about n·(3n + 1)·ε·κ(A); the matrices range from well to badly conditioned."""
    rng = np.random.default_rng(n)
    eps = np.finfo(float).eps
    for decades in (0, 4, 8):
        q, _ = np.linalg.qr(rng.standard_normal((n, n)))
        a = q @ np.diag(np.logspace(0, -decades, n)) @ q.T
        a = (a + a.T) / 2
        b = rng.standard_normal(n)
        exact = np.linalg.solve(a, b)
        x = np.array(_cholesky_solve(a.tolist(), b.tolist()))
        bound = n * (3 * n + 1) * eps * np.linalg.cond(a)
        assert np.linalg.norm(x - exact) <= bound * np.linalg.norm(exact)


@pytest.mark.parametrize("matrix", [
    [[1.0, 2.0], [2.0, 1.0]],                     # indefinite (eigenvalues 3 and -1)
    [[1.0, 1.0], [1.0, 1.0]],                     # singular
    [[-1.0, 0.0], [0.0, 1.0]],                    # a negative first pivot
    [[1.0, 0.0], [0.0, math.nan]],                # not a number
], ids=["indefinite", "singular", "negative", "nan"])
def test_the_cholesky_solve_refuses_a_matrix_that_is_not_positive_definite(matrix) -> None:
    with pytest.raises(np.linalg.LinAlgError, match="not positive definite"):
        _cholesky_solve(matrix, [1.0, 1.0])
