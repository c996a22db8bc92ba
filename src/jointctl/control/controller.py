"""The controller contract (the types loadable from YAML are listed in :mod:`jointctl.control.registry`).

A controller, like a ros_control plugin, is configured once against the
hardware (it resolves its joint names to indices and keeps references to the
command lists it writes) and then updated every cycle with
``update(time_s, period_s)``. It declares the command interfaces it claims as
``(joint, interface)`` pairs; the manager never lets two running controllers
claim the same one. A controller may write another controller's reference
(chaining, as ros2_control's reference interfaces): it names it in ``downstream``, claims
``(that controller, "reference")`` and runs before it in every cycle. While it runs, the
downstream controller is in *chained mode* (its ``upstream`` names the writer): its reference
comes from that controller only, and its edge door (``set_reference``) refuses.

Words, used one way everywhere: a controller's *reference* is its input (the position or
velocity it tracks: from a command topic, a command source or an upstream controller; the trace's
``<joint>.reference`` column); its *command* is its output to the hardware (the effort written to
a command handle).
"""

from __future__ import annotations

from abc import ABC, abstractmethod

from jointctl.control.context import ControlContext
from jointctl.control.params import Params
from jointctl.hardware.interface import HardwareInterface
from jointctl.hardware.loan import HardwareLoan
from jointctl.model.robot_model import RobotModel


class Controller(ABC):
    """Base class of every controller run by the loop."""

    #: Joint names this controller commands; empty for broadcasters.
    joints: tuple[str, ...] = ()
    #: Names of the controllers whose reference this one writes (chaining); they run after it.
    downstream: tuple[str, ...] = ()
    #: The running controller that writes this one's reference interfaces (chained mode), if any;
    #: kept by the manager.
    upstream: str | None = None
    #: Whether it reads the model feed-forward (``context.feedforward``) in its update: the manager
    #: then runs the feed-forward once per cycle, before its first user. Set by configure().
    uses_model: bool = False
    #: Whether it reads the feed-forward's inertia term (M(q)·q̈_ref): computed only while one does.
    uses_model_inertia: bool = False

    def __init__(self, name: str, params: Params) -> None:
        self.name = name
        self.source = params.source
        self.field = params.field
        #: Shared with the manager's other controllers; set by the manager before configure().
        self.context: ControlContext | None = None

    @abstractmethod
    def claimed_interfaces(self) -> tuple[tuple[str, str], ...]:
        """``(joint, interface)`` pairs this controller writes."""

    @abstractmethod
    def configure(self, hardware: HardwareInterface | HardwareLoan, robot: RobotModel) -> None:
        """Resolve names against the hardware and the model; raise ConfigError if impossible.

        The manager passes a :class:`~jointctl.hardware.loan.HardwareLoan`: the state handles (kept
        and indexed in the loop: they are updated in place) and the command handles of the
        interfaces :meth:`claimed_interfaces` names; asking for others raises ConfigError."""

    def bind_downstream(self, controllers: dict[str, Controller]) -> None:
        """Receive the controllers named in ``downstream`` (called before start)."""

    def start(self, time_s: float) -> None:
        """Called when the controller starts running, before its first update."""

    def stop(self, time_s: float) -> None:
        """Called when the controller stops running."""

    def fail(self, time_s: float, reason: str) -> None:
        """Called instead of :meth:`stop` when this controller or one of its chain failed; ``reason``
        says why (for goals or commands still pending). Must not raise."""
        self.stop(time_s)

    @abstractmethod
    def update(self, time_s: float, period_s: float) -> None:
        """One control cycle at ``time_s`` for a period of ``period_s`` seconds."""
