"""The layers of docs/architecture.md, read from the imports: a package imports only the packages below it,
no two modules import each other (nor any longer circle), and nothing in control/, trajectory/ or runtime/
knows the simulator (mujoco, jointctl.sim).

Every import counts: lazy ones inside functions, relative ones (``from .x import y``, ``from .. import z``)
and package-attribute ones (``from jointctl import sim``)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "jointctl"
#: Shared helpers below every layer (the package root's ``__init__`` holds the version and puts the
#: environment's packages first: python_path).
FOUNDATION = ("jointctl", "errors", "validate", "paths", "python_path", "jit")
#: Every package of jointctl, bottom to top: each may import only those before it (and the foundation).
#: wire: pure codecs; model ... runtime: the loop; then the edges, each family its own package (sweep runs
#: scenarios and may use identification's designs; compiled: the loop's cycle of the built-in parts, compiled).
LAYERS = ("wire", "model", "sim", "hardware", "control", "trajectory", "runtime",
          "commands", "metrics", "recording", "visuals", "compiled",
          "scenario", "identification", "sweep", "industrial_controller", "clients", "tuning", "ros", "ros2", "cli")
#: The core: what runs inside the loop; the edges sit on it.
CORE = ("model", "sim", "hardware", "control", "trajectory", "runtime")
SIMULATOR_FREE = ("control", "trajectory", "runtime")


def module_name(path: Path) -> str:
    """``jointctl.a.b`` for PACKAGE/a/b.py; a file outside the package is a top-level module."""
    try:
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    except ValueError:
        parts = [path.stem]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path) -> set[str]:
    """Every module ``path`` imports, at any depth of the file, as absolute names. ``from a import b``
    yields ``a`` and ``a.b`` (b may be a module); relative imports are resolved against ``path``."""
    package = module_name(path).split(".")
    if path.name != "__init__.py":
        package = package[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = package[: len(package) - node.level + 1] if node.level else []
            module = ".".join(base + ([node.module] if node.module else []))
            found.add(module)
            found.update(f"{module}.{alias.name}" for alias in node.names if alias.name != "*")
    return found


def package_of(module: str) -> str | None:
    """The jointctl package (or foundation module) ``module`` belongs to; None outside jointctl."""
    parts = module.split(".")
    if parts[0] != "jointctl":
        return None
    if len(parts) > 1 and ((PACKAGE / parts[1]).is_dir() or (PACKAGE / f"{parts[1]}.py").exists()):
        return parts[1]
    return "jointctl"  # the package root's own names (__version__)


def sources() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def modules_in(layer: str) -> list[Path]:
    return sorted((PACKAGE / layer).rglob("*.py"))


def test_every_package_has_its_place():
    packages = {p.name for p in PACKAGE.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    modules = {p.stem for p in PACKAGE.glob("*.py") if p.name != "__init__.py"}
    assert packages - set(LAYERS) == set(), "add the new package to LAYERS"
    assert modules - set(FOUNDATION) == set(), "a module at the package root is foundation or belongs in a package"


@pytest.mark.parametrize("layer", LAYERS)
def test_a_package_imports_only_the_packages_below_it(layer):
    allowed = set(LAYERS[: LAYERS.index(layer) + 1]) | set(FOUNDATION)
    wrong = {f"{path.relative_to(PACKAGE)} imports {module}"
             for path in modules_in(layer) for module in imports(path)
             if package_of(module) is not None and package_of(module) not in allowed}
    assert not wrong, sorted(wrong)


def test_the_foundation_imports_nothing_of_jointctl_above_it():
    wrong = {f"{path.name} imports {module}" for path in PACKAGE.glob("*.py") for module in imports(path)
             if package_of(module) not in (None, *FOUNDATION)}
    assert not wrong, sorted(wrong)


def test_wire_formats_import_only_the_foundation():
    wrong = {f"{path.relative_to(PACKAGE)} imports {module}" for path in modules_in("wire")
             for module in imports(path) if package_of(module) not in (None, "wire", *FOUNDATION)}
    assert not wrong, sorted(wrong)


def import_graph() -> dict[str, set[str]]:
    """Module -> the jointctl modules it imports (names that are attributes, not modules, dropped)."""
    names = {module_name(path): path for path in sources()}
    return {name: {m for m in imports(path) if m in names and m != name} for name, path in names.items()}


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for other in sorted(graph[node]):
            if other not in index:
                visit(other)
                low[node] = min(low[node], low[other])
            elif other in on_stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            component = []
            while True:
                top = stack.pop()
                on_stack.discard(top)
                component.append(top)
                if top == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def test_no_modules_import_each_other():
    # A package's __init__ that hands its modules' names on imports them; a module importing its own
    # package's face is then a circle only in name: count modules, not faces.
    graph = import_graph()
    faces = {name for name in graph if (PACKAGE.parent / name.replace(".", "/") / "__init__.py").exists()}
    graph = {name: {m for m in found if m not in faces} for name, found in graph.items() if name not in faces}
    assert circles(graph) == []


@pytest.mark.parametrize("layer", SIMULATOR_FREE)
def test_control_trajectory_and_runtime_do_not_know_the_simulator(layer):
    wrong = {f"{path.relative_to(PACKAGE)} imports {module}"
             for path in modules_in(layer) for module in imports(path)
             if module.split(".")[0] == "mujoco" or package_of(module) == "sim"}
    assert not wrong, sorted(wrong)


def test_only_the_ros_edge_imports_rospy_and_actionlib():
    ros_modules = {"rospy", "actionlib", "rosgraph", "dynamic_reconfigure", "rosbag"}
    wrong = {f"{path.relative_to(PACKAGE)} imports {module}"
             for path in sources() if "ros" not in path.relative_to(PACKAGE).parts[:1]
             for module in imports(path) if module.split(".")[0] in ros_modules}
    assert not wrong, sorted(wrong)


def test_only_the_ros2_edge_imports_rclpy_and_ros2_only_messages():
    # ROS 2's std_msgs, sensor_msgs... have ROS 1's names: these packages exist only in ROS 2.
    ros2_modules = {"rclpy", "rcl_interfaces", "controller_manager_msgs", "builtin_interfaces", "rosidl_runtime_py"}
    wrong = {f"{path.relative_to(PACKAGE)} imports {module}"
             for path in sources() if "ros2" not in path.relative_to(PACKAGE).parts[:1]
             for module in imports(path) if module.split(".")[0] in ros2_modules}
    assert not wrong, sorted(wrong)


# -- the reader itself: it must see what it is to catch ------------------------------------------------

def test_the_reader_sees_lazy_absolute_and_package_attribute_imports(tmp_path):
    probe = tmp_path / "probe.py"
    probe.write_text("import mujoco\nfrom jointctl.sim.world import MujocoWorld\nfrom jointctl import sim\n"
                     "def f():\n    import rospy\n")
    found = imports(probe)
    assert {"mujoco", "jointctl.sim.world", "rospy"} <= found
    assert package_of("jointctl.sim") == "sim" and "jointctl.sim" in found


def test_the_reader_resolves_relative_imports(monkeypatch, tmp_path):
    root = tmp_path / "jointctl"
    (root / "control").mkdir(parents=True)
    module = root / "control" / "probe.py"
    module.write_text("from ..sim import world\nfrom . import pid\nfrom .manager import Manager\n")
    face = root / "control" / "__init__.py"
    face.write_text("from .pid import Pid\nfrom .. import sim\n")
    monkeypatch.setattr(__import__(__name__, fromlist=["PACKAGE"]), "PACKAGE", root)
    assert {"jointctl.sim", "jointctl.sim.world", "jointctl.control.pid", "jointctl.control.manager"} <= imports(module)
    assert {"jointctl.control.pid", "jointctl.sim"} <= imports(face)


def test_the_circle_finder_finds_a_circle_of_three_and_none_in_a_chain():
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert circles({"a": {"b"}, "b": {"c"}, "c": set()}) == []
