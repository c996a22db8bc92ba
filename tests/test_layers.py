"""The layers of docs/architecture.md, read from the imports: lower layers never import higher
ones, and nothing in control/, trajectory/ or runtime/ knows the simulator (mujoco, jointctl.sim)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "jointctl"
#: Bottom to top; every other package (scenario, tools, tuning, clients, ros, cli) is an edge.
LAYERS = ("model", "sim", "hardware", "control", "trajectory", "runtime")
#: Shared helpers below every layer.
FOUNDATION = ("errors", "validate", "paths")
#: Wire formats: pure codecs (no I/O, nothing of jointctl but the foundation) that hardware may speak.
WIRE_FORMATS = ("jointctl.industrial.simple_message",)
SIMULATOR_FREE = ("control", "trajectory", "runtime")


def imports(path: Path) -> set[str]:
    """Every module ``path`` imports, at any depth of the file (lazy imports included)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module)
    return found


def package_of(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if parts[0] == "jointctl" and len(parts) > 1 else None


def modules_in(layer: str) -> list[Path]:
    return sorted((PACKAGE / layer).rglob("*.py"))


@pytest.mark.parametrize("layer", LAYERS)
def test_a_layer_imports_only_the_layers_below_it(layer):
    allowed = set(LAYERS[: LAYERS.index(layer) + 1]) | set(FOUNDATION)
    wrong = {f"{path.relative_to(PACKAGE)} imports {module}"
             for path in modules_in(layer) for module in imports(path)
             if package_of(module) is not None and package_of(module) not in allowed
             and module not in WIRE_FORMATS}
    assert not wrong, sorted(wrong)


@pytest.mark.parametrize("module", WIRE_FORMATS)
def test_wire_formats_import_only_the_foundation(module):
    path = PACKAGE.parent / (module.replace(".", "/") + ".py")
    wrong = {m for m in imports(path) if package_of(m) is not None and package_of(m) not in FOUNDATION}
    assert not wrong, sorted(wrong)


@pytest.mark.parametrize("layer", SIMULATOR_FREE)
def test_control_trajectory_and_runtime_do_not_know_the_simulator(layer):
    wrong = {f"{path.relative_to(PACKAGE)} imports {module}"
             for path in modules_in(layer) for module in imports(path)
             if module.split(".")[0] == "mujoco" or package_of(module) == "sim"}
    assert not wrong, sorted(wrong)


def test_only_the_ros_edge_imports_rospy_and_actionlib():
    ros_modules = {"rospy", "actionlib", "rosgraph", "dynamic_reconfigure"}
    wrong = {f"{path.relative_to(PACKAGE)} imports {module}"
             for path in sorted(PACKAGE.rglob("*.py")) if "ros" not in path.relative_to(PACKAGE).parts[:1]
             for module in imports(path) if module.split(".")[0] in ros_modules}
    assert not wrong, sorted(wrong)


def test_the_reader_sees_imports_it_must_catch(tmp_path):
    probe = tmp_path / "probe.py"
    probe.write_text("import mujoco\nfrom jointctl.sim.world import MujocoWorld\ndef f():\n    import rospy\n")
    assert imports(probe) == {"mujoco", "jointctl.sim.world", "rospy"}
