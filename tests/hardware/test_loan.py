"""Handles are loaned: every state handle, and command handles only for claimed interfaces."""

from __future__ import annotations

import pytest

from jointctl.control.controller import Controller
from jointctl.control.manager import ControllerManager
from jointctl.errors import ConfigError
from jointctl.hardware.interface import EFFORT, VELOCITY
from jointctl.hardware.loan import HardwareLoan
from jointctl.model import load_robot_model
from tests.control.conftest import ONE_DOF_XACRO, FakeHardware


class _Greedy(Controller):
    """Claims the velocity interface of its joint, then asks for the effort commands too."""

    def __init__(self, name, params) -> None:
        super().__init__(name, params)
        self.interface = params.string("interface")

    def claimed_interfaces(self):
        return (("joint1", VELOCITY),)

    def configure(self, hardware, robot) -> None:
        self.commands = hardware.command_buffer(self.interface)

    def update(self, time_s, period_s) -> None:
        pass


def test_a_loan_shares_the_hardwares_own_state_lists_and_claimed_commands():
    hw = FakeHardware(("joint1", "joint2"))
    loan = HardwareLoan(hw, [("joint1", EFFORT)], borrower="c")
    assert loan.position is hw.position and loan.velocity is hw.velocity and loan.effort is hw.effort
    hw.set_state("joint2", 0.25)  # the hardware updates its lists in place: the loan sees it
    assert loan.position[1] == 0.25
    assert loan.command_buffer(EFFORT) is hw.command_buffer(EFFORT)


def test_a_loan_refuses_command_handles_that_were_not_claimed():
    loan = HardwareLoan(FakeHardware(), [("joint1", VELOCITY)], borrower="greedy", source="ctl.yaml")
    with pytest.raises(ConfigError) as caught:
        loan.command_buffer(EFFORT)
    assert caught.value.field == "greedy" and caught.value.value == EFFORT and "claims no effort" in str(caught.value)


def test_the_manager_refuses_at_configure_a_controller_using_handles_it_did_not_claim(tmp_path):
    robot = load_robot_model(ONE_DOF_XACRO)
    path = tmp_path / "greedy.yaml"
    path.write_text("greedy: {type: test/Greedy, interface: effort}\nhonest: {type: test/Greedy, interface: velocity}\n")
    manager = ControllerManager(FakeHardware(), robot, types={"test/Greedy": _Greedy})
    manager.load_file(path)
    assert manager.load("honest").commands == [0.0]  # its claimed interface: loaned
    with pytest.raises(ConfigError, match="claims no effort") as caught:
        manager.load("greedy")
    assert caught.value.source == str(path) and caught.value.field == "greedy"
