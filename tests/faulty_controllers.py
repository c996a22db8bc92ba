"""A controller type that fails on purpose, for the failure-policy tests.

Importing this module registers ``test_controllers/FaultyPositionController``: the chapter's
effort position controller, until its reference passes ``fail_above`` (m or rad); from then on
its update raises (``fault: raise``) or leaves a NaN effort (``fault: nan``). Processes under test
load it with ``python -c "import tests.faulty_controllers; ..."`` before jointctl's CLI.
"""

from __future__ import annotations

import math
import sys

from jointctl.control.registry import register_controller
from jointctl.control.joint_controllers import JointPositionController
from jointctl.control.params import Params

FAULTY_TYPE = "test_controllers/FaultyPositionController"


@register_controller(FAULTY_TYPE)
class FaultyPositionController(JointPositionController):
    def __init__(self, name: str, params: Params) -> None:
        self.fail_above = params.number("fail_above", math.inf)
        self.fault = params.string("fault", "raise")
        super().__init__(name, params)

    def update(self, time_s: float, period_s: float) -> None:
        super().update(time_s, period_s)
        if self.reference > self.fail_above:
            if self.fault == "raise":
                raise RuntimeError(f"deliberate fault at reference {self.reference:.4g}")
            self.effort_command[self.index] = math.nan


def main() -> int:
    """``python -m tests.faulty_controllers ARGS``: jointctl's CLI with this type registered."""
    from jointctl.cli import main as jointctl_main

    return jointctl_main(sys.argv[1:])


if __name__ == "__main__":
    sys.exit(main())
