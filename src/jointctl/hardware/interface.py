"""What every robot, simulated or real, offers to the control loop.

Like a ros_control ``RobotHW``: after :meth:`HardwareInterface.read` the state
lists hold one value per joint (``position`` in m or rad, ``velocity`` in m/s
or rad/s, ``effort`` in N or N·m: the effort applied during the last period),
and each force-torque sensor's wrench; controllers write into the command
lists returned by :meth:`command_buffer`, and :meth:`write` sends them.
:meth:`advance` lets one control period of hardware time pass: a physics step
for a simulator, nothing for a robot that runs on its own clock.

State and commands are plain Python lists of floats: the robots here have at
most a few joints, and per-element access to a list is several times cheaper
than to a numpy array in the 1 kHz loop (measured: 341 k against 302 k
cycles/s for the whole 1-DOF cycle). Joints are indexed in ``joint_names``
order; callers resolve names to indices once, with :meth:`joint_index`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence

from jointctl.errors import ConfigError

EFFORT = "effort"
VELOCITY = "velocity"
POSITION = "position"


class SimulationDoor(ABC):
    """What only a simulated robot offers: gravity, objects spawned into and removed from its world,
    their poses (the reset to the initial state is ``HardwareInterface.reset``). Real hardware has none (``HardwareInterface.simulation`` is None), and the
    edges that use it (the tuning page, scenario objects, the ROS world services) say so.

    Changes are made from the loop thread, at the start of a cycle (the edges queue them there).
    Frames: the world frame, z up; poses as position [m] and quaternion (w, x, y, z).
    """

    @property
    @abstractmethod
    def gravity_m_s2(self) -> tuple[float, float, float]:
        """World-frame gravity [m/s²]."""

    @abstractmethod
    def set_gravity(self, gravity_m_s2: tuple[float, float, float]) -> None:
        """Change gravity from the next step on."""

    @property
    @abstractmethod
    def floor(self) -> bool:
        """Whether the world has a ground plane."""

    @property
    @abstractmethod
    def spawned(self) -> tuple:
        """The objects spawned so far, oldest first (:class:`~jointctl.sim.objects.ObjectSpec`)."""

    @abstractmethod
    def has_body(self, name: str) -> bool:
        """Whether a body (a robot link or a spawned object) has that name."""

    @abstractmethod
    def spawn(self, spec) -> None:
        """Add a rigid object (an :class:`~jointctl.sim.objects.ObjectSpec`) to the world."""

    @abstractmethod
    def remove(self, name: str):
        """Remove the spawned object ``name``; returns its spec."""

    @abstractmethod
    def remove_spawned(self) -> None:
        """Remove every spawned object."""

    @abstractmethod
    def body_state(self, name: str) -> tuple:
        """(position [m], quaternion (w, x, y, z), angular velocity [rad/s], linear velocity [m/s])
        of body ``name``'s frame, in world axes; numpy arrays, fresh copies."""

    @property
    @abstractmethod
    def solver(self) -> dict[str, float]:
        """The contact solver's settings: ``iterations``, ``tolerance``."""

    @abstractmethod
    def on_rebuild(self, listener) -> None:
        """Call ``listener()`` whenever the world is rebuilt (objects added or removed)."""


class HardwareInterface(ABC):
    """Joint state handles, command handles and wrench sensor handles of one robot."""

    joint_names: tuple[str, ...]
    position: list[float]
    velocity: list[float]
    effort: list[float]
    #: The simulation door, on simulated hardware only.
    simulation: SimulationDoor | None = None
    #: Why the robot cannot be commanded now (a lost connection, stale state), or None. Simulated
    #: hardware never has one; a trajectory executor aborts its goal and refuses new ones while set.
    fault: str | None = None
    #: The hardware's own word on whether the robot moves (an industrial controller's STATUS
    #: ``in_motion``), or None when it gives none. A trajectory goal succeeds only when it is not True.
    in_motion: bool | None = None

    def __init__(self, joint_names: tuple[str, ...], sensor_names: tuple[str, ...] = ()) -> None:
        self.joint_names = tuple(joint_names)
        n = len(self.joint_names)
        self.position = [0.0] * n
        self.velocity = [0.0] * n
        self.effort = [0.0] * n
        self.sensor_names = tuple(sensor_names)
        self.wrenches: dict[str, list[float]] = {s: [0.0] * 6 for s in self.sensor_names}
        self._index = {name: k for k, name in enumerate(self.joint_names)}
        self._commands: dict[str, list[float]] = {}

    def joint_index(self, name: str, *, source: str | None = None, field: str = "joint") -> int:
        """Index of joint ``name`` in the state and command lists; ConfigError if unknown."""
        try:
            return self._index[name]
        except KeyError:
            raise ConfigError(
                f"no such joint on this robot (joints: {', '.join(self.joint_names)})",
                source=source, field=field, value=name,
            ) from None

    @abstractmethod
    def command_interfaces(self, joint: str) -> frozenset[str]:
        """The command interfaces (``"effort"``, ``"velocity"``, ``"position"``) of ``joint``."""

    def command_buffer(self, interface: str) -> list[float]:
        """The list controllers write ``interface`` commands into (one entry per joint)."""
        buf = self._commands.get(interface)
        if buf is None:
            buf = self._commands[interface] = [0.0] * len(self.joint_names)
        return buf

    @property
    def command_buffers(self) -> tuple[list[float], ...]:
        """Every command list made so far (the loop checks them for non-finite values)."""
        return tuple(self._commands.values())

    def command_safe(self, index: int) -> None:
        """Put joint ``index`` in its safe action, for when the controller commanding it fails:
        zero effort (the joint's own damping and friction brake it; a hold would need a controller,
        and the one that failed cannot be trusted), zero velocity, or the measured position."""
        for interface, buf in self._commands.items():
            buf[index] = self.position[index] if interface == POSITION else 0.0

    @abstractmethod
    def read(self) -> None:
        """Refresh ``position``, ``velocity``, ``effort`` and the wrenches."""

    @abstractmethod
    def write(self) -> None:
        """Send the command buffers to the actuators."""

    @abstractmethod
    def advance(self, period_s: float) -> None:
        """Let ``period_s`` seconds of hardware time pass."""

    #: True for hardware that executes whole trajectories itself (an industrial controller with its own
    #: interpolator): a trajectory executor hands it each goal through :meth:`execute_trajectory`.
    takes_trajectories: bool = False
    #: With ``takes_trajectories``: None to be handed the goal's own points, or the period [s] at which
    #: the executor samples its plan of the goal (for a controller that wants a dense stream).
    trajectory_sample_period_s: float | None = None
    #: With ``takes_trajectories``: True while a trajectory handed over is still being sent or executed,
    #: by the hardware's own word. A goal on such hardware ends when this is False (or on a fault).
    executing: bool = False

    def execute_trajectory(self, joint_indices: Sequence[int], times_s: Sequence[float],
                           positions: Sequence[Sequence[float]],
                           velocities: Sequence[Sequence[float]] | None = None,
                           accelerations: Sequence[Sequence[float]] | None = None) -> None:
        """Execute a trajectory by the hardware's own means: ``positions[k]`` [rad or m] of the joints
        ``joint_indices`` (with ``velocities[k]`` [per s] and ``accelerations[k]`` [per s²] when given)
        at ``times_s[k]`` [s] from now, increasing; a point at 0 is where the motion starts. Joints not
        listed keep their position command. Only hardware with ``takes_trajectories`` implements it."""
        raise NotImplementedError(f"{type(self).__name__} does not take whole trajectories")

    def stop_motion(self) -> None:
        """Bring the joints to rest by the hardware's own means, for a canceled or aborted motion.

        Hardware that servos by itself (an industrial controller with its own interpolator) stops
        there at its own limits and reports ``fault`` until at rest. The default does nothing:
        the controllers' decelerating references stop the joints."""

    def reset(self) -> None:
        """Return to the initial state, where the hardware can (simulators); else no-op."""
