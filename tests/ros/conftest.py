"""A real ROS 1 graph for the tests: a master on a port the OS handed out, jointctl serving, ROS's
own tools, and one long-lived probe node that the tests ask what is on the graph.

The tests skip when ROS 1 is missing, unless JOINTCTL_REQUIRE_ROS is set (CI sets it), in which
case they fail: nothing skips silently there.

Speed: a master and its probe node (tests/ros/probe_node.py) live for a module; each test gets the
module's master back clean (parameters deleted, the nodes it started gone from the graph). The
probe answers in milliseconds where ``rostopic echo -n 1`` costs a second of Python start-up, so
``wait_for_topic``, ``joint_position(s)`` and ``settle_to`` ask it whenever the environment's master
is one of these graphs (and fall back to ``rostopic`` for any other master).
"""

from __future__ import annotations

import json
import os
import queue
import re
import socket
import subprocess
import sys
import threading
import time
import xmlrpc.client
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path

import pytest

from tests.processes import stop_process
from tests.waiting import wait_until  # noqa: F401  (the ROS tests import it from here)

ROOT = Path(__file__).resolve().parents[2]
ROS_BUILD = ROOT / "build" / "ros"
PROBE = Path(__file__).with_name("probe_node.py")


def _ros_available() -> bool:
    try:
        import rospy  # noqa: F401
        import control_msgs.msg  # noqa: F401
    except ImportError:
        return False
    return True


if not _ros_available():
    if os.environ.get("JOINTCTL_REQUIRE_ROS"):
        raise RuntimeError("JOINTCTL_REQUIRE_ROS is set but rospy or jointctl's messages do not import: run make ros")
    pytest.skip("ROS 1 is not installed (make ros)", allow_module_level=True)


_handed_out: set[int] = set()


def free_port() -> int:
    """A port the OS handed out as free just now, never one this session handed out before (two
    calls in a row cannot return the same port). It is closed again: whoever binds it next may find
    it taken by someone else meanwhile, so a server started on it must detect a failed bind and
    retry on another (as :class:`Graph` does for the master)."""
    while True:
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        if port not in _handed_out:
            _handed_out.add(port)
            return port





def ros_environment(folder: Path, port: int) -> dict:
    env = dict(os.environ)
    env.update({
        "ROS_MASTER_URI": f"http://127.0.0.1:{port}", "ROS_HOSTNAME": "127.0.0.1",
        "ROS_HOME": str(folder / "ros_home"),
        "ROS_PACKAGE_PATH": f"{ROS_BUILD / 'src'}:{env.get('ROS_PACKAGE_PATH', '')}".rstrip(":"),
        "PYTHONPATH": f"{ROS_BUILD / 'py'}:{env.get('PYTHONPATH', '')}".rstrip(":"),
    })
    env.pop("ROS_IP", None)
    return env


class _Timeout(xmlrpc.client.Transport):
    def __init__(self, timeout_s: float) -> None:
        super().__init__()
        self.timeout_s = timeout_s

    def make_connection(self, host):
        connection = super().make_connection(host)
        connection.timeout = self.timeout_s
        return connection


def _answers(api_uri: str, timeout_s: float = 2.0) -> bool:
    """Whether a node's XML-RPC server at ``api_uri`` answers (as ``rosnode ping`` asks)."""
    try:
        xmlrpc.client.ServerProxy(api_uri, transport=_Timeout(timeout_s)).getPid("/jointctl_tests")
        return True
    except (OSError, xmlrpc.client.Error):
        return False


class Master:
    """``rosmaster --core`` on a port from :func:`free_port`. The port may be taken between the OS
    handing it out and the master binding it; rosmaster then prints "Unable to start XML-RPC
    server" and lives on without serving (it does not exit), and whatever holds the port may even
    answer a connection. So the master counts as up only when the master at the URI answers
    ``getPid`` with this process's id; after a failed bind it is stopped and started again on
    another port."""

    ATTEMPTS = 5

    def __init__(self, env: dict, port: int | None = None) -> None:
        self.env = env
        for _ in range(self.ATTEMPTS if port is None else 1):
            self.port = port or free_port()
            self.env["ROS_MASTER_URI"] = self.uri = f"http://127.0.0.1:{self.port}"
            if self._start():
                return
        raise AssertionError(f"no ROS master came up ({self.ATTEMPTS} ports tried): {self.output[-2000:]}")

    def _start(self) -> bool:
        self.process = subprocess.Popen(["rosmaster", "--core", "-p", str(self.port)], env=self.env,
                                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.lines: list[str] = []
        threading.Thread(target=lambda: self.lines.extend(self.process.stdout), daemon=True).start()
        proxy = xmlrpc.client.ServerProxy(self.uri, transport=_Timeout(2.0))  # whatever holds the port may not answer
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            if any("Unable to start XML-RPC server" in line for line in self.lines) or self.process.poll() is not None:
                break  # the bind failed (the port was taken meanwhile): another port
            try:
                code, _, pid = proxy.getPid("/jointctl_tests")
                if code == 1 and pid == self.process.pid:
                    return True
                break  # another master holds the port
            except (OSError, xmlrpc.client.Error):
                time.sleep(0.02)
        self.stop()
        return False

    @property
    def output(self) -> str:
        return "".join(self.lines)

    def stop(self, kill: bool = False) -> None:
        if kill and self.process.poll() is None:
            self.process.kill()
            self.process.wait(5)
        stop_process(self.process)


#: Probe nodes by the URI of the master they are on (how the env-taking helpers find them).
_PROBES: dict[str, Probe] = {}


class Probe:
    """The probe node (tests/ros/probe_node.py) on one master, asked over a pipe."""

    def __init__(self, env: dict) -> None:
        self.uri = env["ROS_MASTER_URI"]
        self.process = subprocess.Popen([sys.executable, str(PROBE)], env=env, stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, bufsize=1)
        self._answers: queue.Queue = queue.Queue()
        self._lock = threading.Lock()
        threading.Thread(target=self._read, daemon=True).start()
        ready = self._answer(60.0, "the probe node to start")
        self.name = ready["ready"]
        _PROBES[self.uri] = self

    def _read(self) -> None:
        for line in self.process.stdout:
            self._answers.put(line)
        self._answers.put(None)

    def _answer(self, timeout_s: float, what: str) -> dict:
        try:
            line = self._answers.get(timeout=timeout_s)
        except queue.Empty:
            raise AssertionError(f"the probe node did not answer within {timeout_s:g} s ({what})") from None
        if line is None:
            raise AssertionError(f"the probe node ended ({what}): {self.process.stderr.read()[-2000:]}")
        return json.loads(line)

    def ask(self, timeout_s: float = 30.0, **request) -> dict:
        """Ask the node (see probe_node.py); its answer, or AssertionError with the node's reason."""
        with self._lock:
            self.process.stdin.write(json.dumps({**request, "timeout": timeout_s}) + "\n")
            self.process.stdin.flush()
            answer = self._answer(timeout_s + 30.0, repr(request)[:200])
        if not answer.get("ok"):
            raise AssertionError(f"probe: {answer.get('error')}")
        return answer

    def messages(self, topic: str, count: int = 1, timeout_s: float = 30.0) -> list[dict]:
        """The next ``count`` messages of ``topic``: ``{"text": as rostopic echo prints it, "msg": plain}``."""
        return self.ask(timeout_s, op="messages", topic=topic, count=count)["messages"]

    def cursor(self, topic: str, timeout_s: float = 30.0) -> int:
        """Subscribe to ``topic`` (once it has a publisher) and keep what arrives from now on: the
        mark to read it from (:meth:`since`)."""
        return self.ask(timeout_s, op="cursor", topic=topic)["cursor"]

    def since(self, topic: str, cursor: int, count: int = 0, timeout_s: float = 30.0) -> list[dict]:
        """The messages of ``topic`` received after ``cursor`` (plain JSON): all so far (``count`` 0),
        or the first ``count``, waiting for them."""
        answer = self.ask(timeout_s, op="messages", topic=topic, count=count, after=cursor, text=False)
        return [m["msg"] for m in answer["messages"]]

    def message(self, topic: str, timeout_s: float = 30.0) -> dict:
        """The next message of ``topic``, as plain JSON (fields by name; times have "s" and "ns")."""
        return self.messages(topic, 1, timeout_s)[0]["msg"]

    def publish(self, topic: str, kind: str, msg: dict, timeout_s: float = 30.0) -> int:
        """Publish once a subscriber is connected; how many are."""
        return self.ask(timeout_s, op="publish", topic=topic, type=kind, msg=msg)["connections"]

    def param(self, name: str):
        answer = self.ask(op="param", name=name)
        return None if answer.get("missing") else answer["value"]

    def close(self) -> None:
        _PROBES.pop(self.uri, None)
        if self.process.poll() is None:
            self.process.stdin.close()
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                stop_process(self.process)


class Graph:
    """A master and its probe node, for a module; processes started against it are stopped at
    :meth:`close` (the master last)."""

    def __init__(self, folder: Path, *, display: bool = True) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        self.folder = folder
        self.env = ros_environment(folder, 0)
        if not display:
            for name in ("DISPLAY", "WAYLAND_DISPLAY"):
                self.env.pop(name, None)
        self.master = Master(self.env)
        self.port = self.master.port
        self.processes: list[subprocess.Popen] = []
        self.probe = Probe(self.env)

    def rosgraph(self):
        import rosgraph
        return rosgraph.Master("/jointctl_tests", master_uri=self.env["ROS_MASTER_URI"])

    def nodes(self) -> set[str]:
        state = self.rosgraph().getSystemState()
        return {node for group in state for _, names in group for node in names}

    def start(self, *args: str, log: str | None = None) -> subprocess.Popen:
        out = open(self.folder / log, "w") if log else subprocess.DEVNULL
        process = subprocess.Popen(list(args), env=self.env, stdout=out, stderr=subprocess.STDOUT, text=True)
        self.processes.append(process)
        return process

    def reset(self) -> None:
        """The master as a new one: every parameter but the master's own deleted, and no node on the
        graph but the probe (a node killed without leaving is unregistered, as ``rosnode cleanup``
        does)."""
        self.probe.ask(op="forget")
        master = self.rosgraph()
        for name in master.getParamNames():
            if name != "/run_id":
                try:
                    master.deleteParam(name)
                except Exception:  # noqa: BLE001 (deleted with its parent namespace already)
                    pass

        def others_gone():
            others = self.nodes() - {self.probe.name}
            for node in [n for n in others if not _answers(master.lookupNode(n))]:
                self._unregister(node)
                others.discard(node)
            return not others or None

        wait_until(others_gone, "the test's nodes to leave the graph", timeout_s=30, every_s=0.1)

    def _unregister(self, node: str) -> None:
        import rosgraph

        api = self.rosgraph().lookupNode(node)
        as_node = rosgraph.Master(node, master_uri=self.env["ROS_MASTER_URI"])
        publishers, subscribers, services = self.rosgraph().getSystemState()
        for topic, names in publishers:
            if node in names:
                as_node.unregisterPublisher(topic, api)
        for topic, names in subscribers:
            if node in names:
                as_node.unregisterSubscriber(topic, api)
        for service, names in services:
            if node in names:
                as_node.unregisterService(service, self.rosgraph().lookupService(service))

    def close(self) -> None:
        self.probe.close()
        for process in reversed(self.processes):
            stop_process(process)
        self.master.stop()


@pytest.fixture(scope="module")
def ros_graph(tmp_path_factory):
    """A master and probe node for the module (see :class:`Graph`)."""
    graph = Graph(tmp_path_factory.mktemp("ros_graph"))
    yield graph
    graph.close()


@pytest.fixture
def ros_env(ros_graph):
    """Environment of the module's master, clean for this test (see :meth:`Graph.reset`)."""
    yield ros_graph.env
    ros_graph.reset()


@pytest.fixture
def probe(ros_graph, ros_env) -> Probe:
    """The probe node on the test's master."""
    return ros_graph.probe


def run(env, *args, timeout=20.0, check=True) -> subprocess.CompletedProcess:
    result = subprocess.run(list(args), env=env, capture_output=True, text=True, timeout=timeout)
    if check and result.returncode != 0:
        raise AssertionError(f"{args} failed ({result.returncode}): {result.stderr[-2000:]}")
    return result


def probe_for(env) -> Probe | None:
    """The probe node on ``env``'s master, if one of these graphs runs it."""
    return _PROBES.get(env.get("ROS_MASTER_URI", ""))


def wait_for_topic(env, topic: str, timeout_s: float = 30.0) -> str:
    """One message of ``topic`` as rostopic prints it, waiting for the publisher to appear."""
    probe = probe_for(env)
    if probe is not None:
        return probe.messages(topic, 1, timeout_s)[0]["text"] + "\n---\n"
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        result = run(env, "rostopic", "echo", "-n", "1", topic, timeout=10, check=False)
        if result.returncode == 0 and result.stdout.strip():
            return result.stdout
        time.sleep(0.3)
    raise AssertionError(f"no message on {topic} within {timeout_s} s")


def joint_position(env, topic: str = "/one_DOF_robot/joint_states") -> float:
    """The first joint's position in the next message of ``topic``."""
    probe = probe_for(env)
    if probe is not None:
        return float(probe.message(topic)["position"][0])
    text = wait_for_topic(env, topic)
    return float(re.search(r"position: \[([-0-9.e]+)", text).group(1))


def _column(msg: dict, column: str) -> float:
    """``column`` as ``rostopic echo -p`` names it (``field.position0``, ``field.header.stamp``: times
    in nanoseconds) of a plain message."""
    value = msg
    for part in column.removeprefix("field.").split("."):
        if part in value:
            value = value[part]
        else:
            name, index = re.fullmatch(r"(\D+)(\d+)", part).groups()
            value = value[name][int(index)]
    return float(value["ns"] if isinstance(value, dict) and "ns" in value else value)


def joint_positions(env, topic: str, count: int, column: str = "field.position0") -> list[float]:
    """``column`` of the next ``count`` messages of a JointState ``topic``."""
    probe = probe_for(env)
    if probe is not None:
        return [_column(m["msg"], column) for m in probe.messages(topic, count, timeout_s=60)]
    text = run(env, "rostopic", "echo", "-p", "-n", str(count), topic, timeout=30).stdout
    lines = [line for line in text.splitlines() if line.strip()]
    header = lines[0].lstrip("%").split(",")
    index = header.index(column)
    return [float(line.split(",")[index]) for line in lines[1:]]


def settle_to(env, target: float, timeout_s: float = 10.0, tol: float = 0.002) -> float:
    """Poll the joint position until it is within ``tol`` of ``target``; the last position seen."""
    deadline = time.monotonic() + timeout_s
    while True:
        q = joint_position(env)
        if abs(q - target) < tol or time.monotonic() > deadline:
            return q
        time.sleep(0.05)


@pytest.fixture
def serve(ros_env):
    """Start ``jointctl serve ARGS`` against the test's master; stopped (SIGTERM) afterwards."""
    processes = []

    def start(*args: str, wait_topic: str | None = None):
        process = subprocess.Popen([sys.executable, "-m", "jointctl.cli", "serve", *args], env=ros_env,
                                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        processes.append(process)
        if wait_topic:
            wait_for_topic(ros_env, wait_topic, timeout_s=60)
        return process

    yield start
    for process in processes:
        stop_process(process)


def printed_until(process: subprocess.Popen, predicate: Callable[[str], object], what: str,
                  timeout_s: float = 30.0) -> str:
    """What ``process`` (stdout a pipe) has printed, read as it comes until ``predicate(text)`` holds;
    AssertionError naming ``what`` after ``timeout_s``. The text is kept (``stop_and_read`` adds it)."""
    import select

    text = getattr(process, "printed", "")
    fd = process.stdout.fileno()
    deadline = time.monotonic() + timeout_s
    while not predicate(text):
        left = deadline - time.monotonic()
        if left <= 0:
            process.printed = text
            raise AssertionError(f"waited {timeout_s:g} s for {what}; printed: {text[-2000:]!r}")
        if select.select([fd], [], [], min(left, 0.5))[0]:
            chunk = os.read(fd, 65536)
            if not chunk:
                process.printed = text
                raise AssertionError(f"the process ended before {what}; printed: {text[-2000:]!r}")
            text += chunk.decode(errors="replace")
    process.printed = text
    return text


def stop_and_read(process: subprocess.Popen, timeout_s: float = 20.0) -> str:
    """SIGTERM ``process`` (stdout a pipe) and everything it printed (with what was read before)."""
    process.terminate()
    return getattr(process, "printed", "") + process.communicate(timeout=timeout_s)[0]


@contextmanager
def served_graph(folder: Path, *args: str, wait_topic: str, display: bool = True):
    """A graph of its own (master, probe) with ``jointctl serve ARGS`` on it, once ``wait_topic``
    flows: for a module whose tests only read the served robot. Yields (graph, the serve process,
    its output going to ``folder/serve.log``)."""
    graph = Graph(folder, display=display)
    try:
        process = graph.start(sys.executable, "-m", "jointctl.cli", "serve", *args, log="serve.log")
        wait_for_topic(graph.env, wait_topic, timeout_s=60)
        yield graph, process
    finally:
        graph.close()
