"""Which runs take the compiled cycle: those whose every part has a compiled form; every other run keeps the
Python loop and says why (the first part without one), in the loop and in the run's metrics."""

from __future__ import annotations

import json

import pytest

from jointctl.commands.sources import CommandSource, SourceFeed
from jointctl.compiled.plan import compile_loop
from jointctl.scenario.run import run_scenario
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario
from tests.conftest import step_scenario
from tests.faulty_controllers import FAULTY_TYPE

POSITION = "joint1_position_controller"


def mode_of(session: Session) -> tuple[str, str | None]:
    session.run(0.002)
    return session.loop.mode, session.loop.mode_reason


def test_a_run_of_built_in_parts_is_compiled(write_scenario):
    assert mode_of(Session(load_scenario(write_scenario(step_scenario())))) == ("compiled", None)


def test_the_model_feed_forward_is_compiled(write_scenario):
    changes = {"controllers": {POSITION: {"feedforward": {"gravity": True, "inertia": True}}}}
    assert mode_of(Session(load_scenario(write_scenario(step_scenario(**changes))))) == ("compiled", None)


@pytest.mark.parametrize(("changes", "reason"), [
    ({"loop": "python"}, "the scenario asks for it (loop: python)"),
    ({"controllers": {POSITION: {"type": FAULTY_TYPE, "fail_above": 10.0}}},
     f"controller '{POSITION}' (FaultyPositionController) has no compiled form"),
    ({"latency_cycles": 1}, "the hardware (ImperfectHardware) has no compiled form"),
], ids=["asked", "user controller", "late commands"])
def test_a_part_without_a_compiled_form_keeps_the_python_loop_and_says_which(changes, reason, write_scenario):
    session = Session(load_scenario(write_scenario(step_scenario(**changes))))
    assert mode_of(session) == ("python", reason)


def test_a_command_source_of_the_users_keeps_the_python_loop(write_scenario):
    class Ramp(CommandSource):
        def sample(self, t: float) -> float:
            return -0.2 - 0.01 * t

    session = Session(load_scenario(write_scenario(step_scenario(commands={}))))
    session.loop.add_input(SourceFeed(Ramp(), session.manager.controller(POSITION)))
    assert mode_of(session) == ("python", f"the command source Ramp of '{POSITION}' has no compiled form")


def test_a_trajectory_executor_and_its_goals_are_compiled():
    session = Session(load_scenario("one_dof_trajectory"))
    assert mode_of(session) == ("compiled", None)


def test_a_velocity_controller_chained_to_an_admittance_controller_runs_compiled_after_it(write_scenario):
    """The manager updates the admittance controller first (upstream first): its compiled form writes the velocity
    controller's reference, whose watchdog is off while chained, as in Python."""
    session = Session(load_scenario(write_scenario(step_scenario(
        controller_file="nac", start_controllers=["joint_state_controller", "joint1_velocity_controller",
                                                  "joint1_admittance_controller"], commands={},
        controllers={"joint1_velocity_controller": {"command_timeout_s": 0.1}}))))
    assert mode_of(session) == ("compiled", None)
    velocity = session.manager.controller("joint1_velocity_controller")
    admittance = session.manager.controller("joint1_admittance_controller")
    assert [call.__self__ for call in session.manager.update_calls][1:] == [admittance, velocity]
    from jointctl.compiled.plan import controller_reason

    # Its upstream not (yet) among the compiled controllers updated before it: it has no compiled form.
    assert controller_reason(velocity) == ("controller 'joint1_velocity_controller' (JointVelocityController) is "
                                           "chained to 'joint1_admittance_controller'")
    assert controller_reason(velocity, [admittance]) is None


def test_the_cartesian_admittance_runs_compiled_with_either_inertia():
    session = Session(load_scenario("arm7dof_nac_catch"))
    assert mode_of(session) == ("compiled", None)
    session = Session(load_scenario("arm7dof_nac_catch", ["controllers.arm7dof_nac_controller.use_model_inertia=true"]))
    assert mode_of(session) == ("compiled", None)


def test_edges_keep_the_python_loop(write_scenario):
    session = Session(load_scenario(write_scenario(step_scenario())))
    session.manager.controller("joint_state_controller").subscribe(lambda sample: None)  # a ROS publisher's way
    assert mode_of(session) == ("python", "controller 'joint_state_controller' (JointStateController) has "
                                          "subscribers")
    session = Session(load_scenario(write_scenario(step_scenario())))
    session.loop.add_observer(print_nothing)
    assert mode_of(session) == ("python", "the loop observer print_nothing has no compiled form")
    session = Session(load_scenario(write_scenario(step_scenario())), realtime=True, speed=100.0)
    assert mode_of(session) == ("python", "the loop is paced to the wall clock")


def print_nothing(time_s: float) -> None:
    pass


def test_the_compiler_is_asked_at_each_run(write_scenario):
    session = Session(load_scenario(write_scenario(step_scenario())))
    assert isinstance(compile_loop(session.loop), object) and mode_of(session)[0] == "compiled"
    session.loop.add_observer(print_nothing)
    assert mode_of(session)[0] == "python"
    session.loop.remove_observer(print_nothing)
    assert mode_of(session)[0] == "compiled"


def test_a_run_says_its_loop_in_its_metrics(write_scenario, tmp_path):
    metrics = run_scenario(load_scenario(write_scenario(step_scenario(duration_s=0.2))), tmp_path / "c", mcap=True)
    assert metrics["loop"] == "compiled" and "loop_reason" not in metrics
    path = write_scenario(step_scenario(duration_s=0.2, loop="python"))
    run_scenario(load_scenario(path), tmp_path / "p", mcap=False)
    written = json.loads((tmp_path / "p" / "metrics.json").read_text())
    assert written["loop"] == "python" and written["loop_reason"] == "the scenario asks for it (loop: python)"


def test_the_loop_field_takes_auto_or_python(write_scenario):
    from jointctl.errors import ConfigError

    assert load_scenario(write_scenario(step_scenario())).loop == "auto"
    with pytest.raises(ConfigError, match="loop.*must be one of auto, python"):
        load_scenario(write_scenario(step_scenario(loop="compiled")))


def test_a_hook_added_while_a_compiled_run_goes_takes_it_on_in_python_from_the_next_stretch(write_scenario):
    from jointctl.compiled.run import STRETCH_CYCLES

    session = Session(load_scenario(write_scenario(step_scenario(duration_s=5.0))))
    seen = []
    original = session.loop.compiler

    def compile_then_add_an_observer(loop):
        run = original(loop)
        hand_over = run._hand_over

        def first_stretch_done(*args):  # an edge's thread adds its hook as the first stretch runs
            hand_over(*args)
            if not seen:
                loop.add_observer(seen.append)

        run._hand_over = first_stretch_done
        return run

    session.loop.compiler = compile_then_add_an_observer
    session.run()
    assert session.loop.mode == "python" and "changed" in session.loop.mode_reason
    assert len(seen) == 5000 - STRETCH_CYCLES and seen[0] == pytest.approx(STRETCH_CYCLES * 0.001)


def test_a_command_source_into_a_chained_velocity_controller_keeps_the_python_loop(write_scenario):
    """Its upstream owns its reference: the Python loop's edge door refuses the source's value (chained), which
    the compiled cycle would write."""
    from jointctl.commands.sources import ConstantSource, SourceFeed

    session = Session(load_scenario(write_scenario(step_scenario(
        controller_file="nac", start_controllers=["joint_state_controller", "joint1_velocity_controller",
                                                  "joint1_admittance_controller"], commands={}))))
    session.run(0.001)
    velocity = session.manager.controller("joint1_velocity_controller")
    session.loop.add_input(SourceFeed(ConstantSource(0.1), velocity))
    from jointctl.compiled.plan import python_reason

    assert python_reason(session.loop) == ("the command source feeds 'joint1_velocity_controller', which takes no "
                                           "command source")


def test_every_built_in_scenario_runs_compiled():
    from jointctl.paths import scenarios_dir

    names = sorted(p.stem for p in scenarios_dir().glob("*.yaml"))
    assert len(names) >= 10
    for name in names:
        assert mode_of(Session(load_scenario(name))) == ("compiled", None), name
