"""``jointctl bode``: a joint's closed-loop frequency response, measured by stepped sines, against its model.

**Measured.** The joint's controller (a position loop, ``effort_controllers/JointPositionController``,
or a velocity loop, ``JointVelocityController``) follows a sine around where it rests, one
frequency after the other (``frequencies_hz``, log-spaced by default), each held until the
transient has died (``settle_s`` and at least two periods) and then measured over whole periods
(at least ``measure_periods`` and ``measure_s``): gain and phase of the response at the reference's
frequency by a least-squares sine fit (:func:`jointctl.metrics.response.sinusoid_response`).
The reference is position only (a plain command, no velocity), as the chapter's command topic gives
it: the PID's derivative acts on the error's difference (``derivative: error``, ros_controllers' law)
or on the measured speed (``derivative: measurement``), as the controller is configured. A velocity
loop's reference carries a slow position term as well, a tenth of the lowest frequency, so that
gravity does not walk the joint to a limit; the fit takes the reference as given, so the loop's own
response is what is measured.
Simulated time; the amplitude keeps the joint inside its range (a third of the room to the nearer
limit for a position loop; for a velocity loop the swing ``A/ω`` at the lowest frequency as well).

**Model.** The joint as a mass (or inertia) ``m`` with viscous damping ``b`` (the identified plant,
or the URDF's mass and damping), driven by the controller as configured (``p``, ``i``, ``d`` of its
YAML) at the loop period ``h`` with the effort held over each period: python-control discretises
the plant (zero-order hold, states position and speed) and closes the sampled loop
``u = p·e + i·h·Σe + d·(e - e_last)/h`` (position, derivative on error: ``C(z) = p + d(1 - z⁻¹)/h``
acts on ``r - y``, a zero in the closed loop), ``u = p·e + i·h·Σe - d·q̇`` (position, derivative on
measurement: ``d`` acts on the measured speed only, no zero) or ``u = p·e_v + i·h·Σe_v`` (velocity),
the law the controller runs (its ``derivative``; ``error`` for a served ros_control robot's
``effort_controllers/JointPositionController`` unless its parameters say otherwise). Its curve is drawn
beside the measurement, and its loop transfer function gives the gain and phase margins.

**Figures of merit** (``metrics.json``): per frequency, gain [dB] and phase [deg] measured and
modelled; the magnitude peak (resonance) and its frequency; the -3 dB bandwidth; the frequency
where the measured phase crosses -90° (a position loop: the natural frequency, shifted by the
hold's ``ω·h/2``); the model's gain and phase margins. ``metrics.json`` is strict JSON: a figure that is
not a finite number is ``null``, meaning not measured or unbounded (no -3 dB or -90° crossing inside the
swept range, an infinite margin; :mod:`jointctl.recording.metrics_file`).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jointctl.control.joint_controllers import JointPositionController, JointVelocityController
from jointctl.errors import ConfigError
from jointctl.identification.plant_fit import IdentificationError
from jointctl.model.loader import load_robot_model
from jointctl.recording.metrics_file import write_metrics
from jointctl.scenario.session import Session
from jointctl.scenario.spec import Scenario
from jointctl.metrics.response import sinusoid_response


@dataclass(frozen=True)
class LoopModel:
    """The sampled loop of the module docstring: plant ``mass`` [kg or kg·m²] and ``damping``
    [N·s/m or N·m·s/rad], gains ``p``, ``i``, ``d``, loop ``period_s``, ``loop`` "position" or "velocity",
    and the position loop's ``derivative`` law: "error" (ros_controllers': ``d`` on the error's
    backward difference, with a plain position reference) or "measurement" (``d`` on the measured speed)."""

    mass: float
    damping: float
    p: float
    i: float
    d: float
    period_s: float
    loop: str = "position"
    derivative: str = "error"

    def __post_init__(self) -> None:
        if self.derivative not in ("error", "measurement"):
            raise ValueError(f"derivative must be 'error' or 'measurement', not {self.derivative!r}")

    @property
    def _on_error(self) -> bool:
        return self.loop == "position" and self.derivative == "error" and self.d != 0.0

    def _matrices(self):
        """The sampled plant (A, B), the closed loop (A, B, C) on states (q, q̇[, e_last][, integral])
        and the loop's gain on the plant state, K(z) = (p + i·h·z/(z-1))·C + D (the loop broken at
        the plant input; derivative on error adds ``d·(1 - 1/z)/h`` to the error's gain instead of D)."""
        from scipy.linalg import expm

        h, m, b = self.period_s, self.mass, self.damping
        # Zero-order hold: exp([[A, B], [0, 0]]·h) = [[Ad, Bd], [0, I]] (the effort held over a period).
        held = expm(np.array([[0.0, 1.0, 0.0], [0.0, -b / m, 1.0 / m], [0.0, 0.0, 0.0]]) * h)
        a, bu = held[:2, :2], held[:2, 2:]
        c = np.array([[1.0, 0.0]]) if self.loop == "position" else np.array([[0.0, 1.0]])
        dv = np.array([[0.0, self.d]]) if self.loop == "position" else np.zeros((1, 2))
        kp = self.p + self.i * h  # the PID adds i·h·e to its integral before using it
        a_cl = a - bu @ (kp * c + dv)
        b_cl = bu * kp
        c_cl = c
        if self._on_error:
            # u = kp·e + (d/h)·(e - e_last), e = r - q; the state e_last takes this cycle's e.
            dh = self.d / h
            dv = np.zeros((1, 2))
            a_cl = np.block([[a - (kp + dh) * bu @ c, -dh * bu], [-c, np.zeros((1, 1))]])
            b_cl = np.vstack([bu * (kp + dh), [[1.0]]])
            c_cl = np.hstack([c, [[0.0]]])
            if self.i:
                bu_e = np.vstack([bu, [[0.0]]])
                c_e = np.hstack([c, [[0.0]]])
                a_cl = np.block([[a_cl, bu_e], [-self.i * h * c_e, np.ones((1, 1))]])
                b_cl = np.vstack([b_cl, [[self.i * h]]])
                c_cl = np.hstack([c_cl, [[0.0]]])
            return a, bu, c, dv, a_cl, b_cl, c_cl
        if self.i:
            a_cl = np.block([[a_cl, bu], [-self.i * h * c, np.ones((1, 1))]])
            b_cl = np.vstack([b_cl, [[self.i * h]]])
            c_cl = np.hstack([c, [[0.0]]])
        return a, bu, c, dv, a_cl, b_cl, c_cl

    def closed_loop(self):
        """The sampled closed loop, reference -> response, as a python-control state-space system."""
        import control

        *_, a_cl, b_cl, c_cl = self._matrices()
        return control.ss(a_cl, b_cl, c_cl, [[0.0]], self.period_s)

    def response(self, frequencies_hz) -> tuple[np.ndarray, np.ndarray]:
        """Closed-loop gain [dB] and phase [deg] at ``frequencies_hz``."""
        *_, a_cl, b_cl, c_cl = self._matrices()
        eye = np.eye(a_cl.shape[0])
        values = []
        for f in np.asarray(frequencies_hz, dtype=float):
            z = np.exp(1j * 2 * math.pi * f * self.period_s)
            values.append((c_cl @ np.linalg.solve(z * eye - a_cl, b_cl))[0, 0])
        h = np.array(values)
        return 20 * np.log10(np.abs(h)), np.degrees(np.unwrap(np.angle(h)))

    def loop_response(self, frequencies_hz) -> np.ndarray:
        """The loop transfer K(z)·(zI - A)⁻¹B at ``frequencies_hz`` (complex)."""
        a, bu, c, dv, *_ = self._matrices()
        out = []
        for f in np.asarray(frequencies_hz, dtype=float):
            z = np.exp(1j * 2 * math.pi * f * self.period_s)
            derivative = self.d * (1 - 1 / z) / self.period_s if self._on_error else 0.0
            gain = (self.p + (self.i * self.period_s * z / (z - 1) if self.i else 0.0) + derivative) * c + dv
            out.append((gain @ np.linalg.solve(z * np.eye(2) - a, bu))[0, 0])
        return np.array(out)

    def margins(self) -> dict:
        """Gain margin [dB] and phase margin [deg] of the loop, with their frequencies [Hz]."""
        import control

        f = np.logspace(-2, math.log10(0.49 / self.period_s), 4000)
        loop = control.frd(self.loop_response(f), 2 * np.pi * f)
        with warnings.catch_warnings():  # notes about the frequency-response method
            warnings.simplefilter("ignore", UserWarning)
            gm, pm, wcg, wcp = control.margin(loop)
        as_db = 20 * math.log10(gm) if gm and math.isfinite(gm) else math.inf
        return {"gain_margin_db": as_db, "gain_crossover_hz": _hz(wcp), "phase_margin_deg": float(pm),
                "phase_crossover_hz": _hz(wcg)}


def _hz(w) -> float:
    return float(w) / (2 * math.pi) if w is not None and math.isfinite(w) else math.nan


@dataclass(frozen=True)
class Point:
    frequency_hz: float
    gain_db: float
    phase_deg: float


def measure(scenario: Scenario, controller_name: str, frequencies_hz, *, amplitude: float | None = None,
            settle_s: float = 1.5, measure_periods: int = 4, measure_s: float = 1.0) -> tuple[list[Point], dict]:
    """Stepped-sine measurement of ``controller_name``'s closed loop on the scenario's simulated robot,
    in simulated time (see the module docstring); (points, context) where context holds the loop,
    joint, amplitude, gains and the loop time it took."""
    return measure_in_session(Session(scenario), controller_name, frequencies_hz, amplitude=amplitude,
                              settle_s=settle_s, measure_periods=measure_periods, measure_s=measure_s)


def measure_in_session(session, controller_name: str, frequencies_hz, *, amplitude: float | None = None,
                       settle_s: float = 1.5, measure_periods: int = 4,
                       measure_s: float = 1.0) -> tuple[list[Point], dict]:
    """:func:`measure` in a session that exists (a live robot's too); the gains are those the
    controller had when the sweep began."""
    controller, loop = loop_controller(session.manager, controller_name)
    gains = controller.pid.gains
    points, context = sweep(session, controller.joint, frequencies_hz, controller.set_reference, loop=loop,
                            amplitude=amplitude, settle_s=settle_s, measure_periods=measure_periods,
                            measure_s=measure_s)
    context["gains"] = {"p": gains.p, "i": gains.i, "d": gains.d}
    context["derivative"] = getattr(controller, "derivative", "error")
    return points, context


def loop_controller(manager, name: str):
    """(controller, "position" | "velocity") for ``name``, an effort position or velocity controller
    of ``manager``; a ConfigError naming ``--controller`` otherwise."""
    try:
        controller = manager.controller(name)
    except Exception:
        raise ConfigError(f"no such controller (started: {', '.join(c.name for c in manager.active)})",
                          field="--controller", value=name) from None
    if isinstance(controller, JointPositionController):
        return controller, "position"
    if isinstance(controller, JointVelocityController):
        return controller, "velocity"
    raise ConfigError("must be an effort position or velocity controller", field="--controller", value=name)


def measure_servoed(session: Session, joint: str, frequencies_hz, *, amplitude: float | None = None,
                    settle_s: float = 1.5, measure_periods: int = 4, measure_s: float = 1.0) -> tuple[list[Point], dict]:
    """The same measurement on hardware that servos its joints itself (an industrial controller behind
    :class:`~jointctl.hardware.industrial.IndustrialHardware`, a robot served on the ROS graph): the
    sine goes straight to the joint's position (or velocity) command interface, the response is the
    position (or velocity) the hardware reports. ``session`` must start no controller that commands
    the joint; it runs as it is paced (the wall clock, for real hardware)."""
    owner = session.manager.commanding(joint)
    if owner is not None:
        raise ConfigError(f"controller {owner.name!r} commands it; start none that does", field="--joint", value=joint)
    loop, set_reference = servo_reference(session.hardware, joint)
    return sweep(session, joint, frequencies_hz, set_reference, loop=loop, amplitude=amplitude,
                 settle_s=settle_s, measure_periods=measure_periods, measure_s=measure_s)


def servo_reference(hardware, joint: str) -> tuple[str, object]:
    """("position" | "velocity", set_reference) for a joint the hardware servos itself: the reference
    is written to its position (else velocity) command interface; a ConfigError naming ``--joint``
    when it has neither."""
    from jointctl.hardware.interface import POSITION, VELOCITY

    index = hardware.joint_index(joint, field="--joint")
    interfaces = hardware.command_interfaces(joint)
    loop = "position" if POSITION in interfaces else "velocity" if VELOCITY in interfaces else None
    if loop is None:
        raise ConfigError("the hardware has no position or velocity loop for it", field="--joint", value=joint)
    command = hardware.command_buffer(POSITION if loop == "position" else VELOCITY)

    def set_reference(value: float) -> None:
        command[index] = value

    return loop, set_reference


def sweep(session: Session, joint: str, frequencies_hz, set_reference, *, loop: str, amplitude: float | None,
          settle_s: float, measure_periods: int, measure_s: float) -> tuple[list[Point], dict]:
    """Run the stepped sines on ``session`` (any hardware), handing each cycle's reference to
    ``set_reference``; (points, context)."""
    frequencies = [float(f) for f in frequencies_hz]
    hardware, robot = session.hardware, session.robot
    period = session.loop.period_s
    nyquist = 0.5 / period
    if not frequencies or min(frequencies) <= 0 or max(frequencies) >= nyquist:
        raise IdentificationError(f"frequencies must be positive and below the loop's Nyquist {nyquist:g} Hz",
                                  field="frequencies_hz", value=frequencies)
    index = hardware.joint_index(joint)
    hardware.read()
    rest = hardware.position[index]
    lower, upper, _ = robot.joint(joint).range_and_speed()
    room = min(rest - lower, upper - rest)
    room = 1.0 if math.isinf(room) else room
    safe = room / 3 if loop == "position" else room / 3 * 2 * math.pi * min(frequencies)
    if amplitude is None:
        amplitude = safe
    elif not 0 < amplitude <= safe:
        raise IdentificationError(f"must be positive and at most {safe:.4g} (a third of the room to the nearer limit)",
                                  field="amplitude", value=amplitude)
    # One schedule: each frequency's sine from its start time, settling then measuring whole periods.
    schedule = []
    t0 = session.loop.time_s + 0.5
    for f in frequencies:
        settle = max(settle_s, 2.0 / f)
        span = math.ceil(max(measure_periods, measure_s * f)) / f
        schedule.append((f, t0, t0 + settle, t0 + settle + span))
        t0 += settle + span
    samples: list[tuple[float, float, float]] = []  # one tuple per cycle: whole even when read from another thread
    state = {"k": 0}
    offset = rest if loop == "position" else 0.0

    def reference_at(time_s: float) -> float:
        k = state["k"]
        while k < len(schedule) and time_s >= schedule[k][3]:
            k += 1
        state["k"] = k
        if k >= len(schedule) or time_s < schedule[k][1]:
            return offset
        f, start = schedule[k][0], schedule[k][1]
        return offset + amplitude * math.sin(2 * math.pi * f * (time_s - start))

    measured = hardware.position if loop == "position" else hardware.velocity
    # A velocity loop does not hold a position: gravity or friction would walk the joint to a limit. A
    # slow position term in its reference (a tenth of the lowest frequency) keeps it near ``rest``; the
    # fit uses the reference as given, so the loop's response is measured all the same.
    hold_per_s = 2 * math.pi * min(frequencies) / 10 if loop == "velocity" else 0.0
    given = [offset]

    def drive(time_s: float) -> None:
        given[0] = reference_at(time_s) + hold_per_s * (rest - hardware.position[index])
        set_reference(given[0])

    def record(time_s: float) -> None:
        samples.append((time_s, given[0], measured[index]))

    started = session.loop.time_s
    session.loop.add_input(drive)
    session.loop.add_observer(record)
    try:
        with session:
            session.run(t0 + 0.1 - started)
    finally:
        session.loop.remove_input(drive)
        session.loop.remove_observer(record)
    # Reference and response at the same loop time: the response measured at the start of a cycle,
    # the reference that cycle's (held over the period that follows).
    t, r, y = np.array(list(samples)).T
    points = []
    for f, start, measure_from, end in schedule:
        window = (t >= start) & (t < end)
        fit = sinusoid_response(t[window] - start, r[window], y[window], frequency_hz=f,
                                start_s=measure_from - start)
        points.append(Point(f, 20 * math.log10(fit.amplitude_ratio), -fit.phase_lag_deg))
    context = {"loop": loop, "joint": joint, "amplitude": amplitude, "rest": rest, "simulated_s": t0 - started,
               "period_s": period}
    return points, context


def bode(scenario: Scenario, controller_name: str, frequencies_hz, *, plant: dict | None = None,
         amplitude: float | None = None, out_dir: str | Path | None = None) -> dict:
    """Measure ``controller_name``'s closed loop at ``frequencies_hz`` and set it beside its model:
    the plant from ``plant`` (an identification's metrics: ``mass_kg``/``inertia_kg_m2`` and
    ``damping_*``) or else from the robot model (the joint's mass-matrix entry at the rest pose,
    armature included, and its URDF damping). Writes ``bode.png`` and ``metrics.json`` to
    ``out_dir`` when given; returns the metrics."""
    points, context = measure(scenario, controller_name, frequencies_hz, amplitude=amplitude)
    robot = load_robot_model(scenario.robot.description)
    pose = {**scenario.initial_positions, context["joint"]: context["rest"]}
    return compare(points, context, controller_name, plant, robot, pose, out_dir=out_dir)


def compare(points: list[Point], context: dict, controller_name: str, plant: dict | None, robot, pose: dict,
            *, out_dir: str | Path | None = None) -> dict:
    """Set measured ``points`` (with their sweep ``context`` and the ``gains`` in it) beside the loop
    model: the plant from ``plant`` (an identification's metrics) or else from ``robot`` (the
    joint's mass-matrix entry at ``pose``, joint name -> position, and its URDF damping); write
    ``bode.png`` and ``metrics.json`` to ``out_dir`` when given; the metrics."""
    if plant is not None:
        mass, damping = plant_of(plant)
        source = "identified"
    else:
        mass, damping = model_plant(robot, context["joint"], pose)
        source = "robot model"
    gains = context["gains"]
    model = LoopModel(float(mass), float(damping), gains["p"], gains["i"], gains["d"], context["period_s"],
                      context["loop"], context.get("derivative", "error"))
    result = analyse(points, model)
    result.update(controller=controller_name, plant_source=source, **context)
    if out_dir is not None:
        write_bode(out_dir, result, f"{controller_name}: closed-loop {context['loop']} response")
    return result


def plant_of(plant: dict) -> tuple[float, float]:
    """(inertia, damping) of an identification's metrics (``mass_kg`` or ``inertia_kg_m2``, and
    ``damping_n_s_m`` or ``damping_n_m_s_rad``); IdentificationError naming what is missing."""
    mass = plant.get("mass_kg", plant.get("inertia_kg_m2"))
    damping = plant.get("damping_n_s_m", plant.get("damping_n_m_s_rad"))
    if not (isinstance(mass, (int, float)) and mass > 0 and isinstance(damping, (int, float))):
        raise IdentificationError("the plant needs mass_kg or inertia_kg_m2 (positive) and damping_n_s_m or "
                                  "damping_n_m_s_rad, as jointctl identify writes them", field="plant",
                                  value=plant)
    return float(mass), float(damping)


def model_plant(robot, joint: str, pose: dict) -> tuple[float, float]:
    """The joint's inertia (its mass-matrix diagonal entry at ``pose``, joint name -> position, other
    joints at 0; armature included) and URDF damping."""
    from jointctl.model.dynamics import RobotDynamics

    dynamics = RobotDynamics(robot)
    names = [j.name for j in robot.movable_joints]
    dynamics.set_pose([float(pose.get(name, 0.0)) for name in names])
    k = names.index(joint)
    return float(dynamics.mass_matrix()[k, k]), float(robot.joint(joint).damping)


def analyse(points: list[Point], model: LoopModel | None) -> dict:
    """Figures of merit of measured ``points`` (and the model's, when given).

    ``resonance_hz`` and ``resonance_peak_db`` are the frequency and gain of the largest measured gain
    when it is a peak inside the swept range (above the gains at both ends of the range), and None (null
    in ``metrics.json``) otherwise: when the largest gain is at the lowest or the highest frequency
    swept, the sweep has found no peak, only the edge of its range: a well-damped loop's gain falls from
    the lowest frequency on (its largest gain is at the first test frequency, 0.5 Hz by default, which
    is no resonance), and a gain still rising at the highest frequency peaks beyond the range (sweep
    higher to find it).
    """
    f = np.array([p.frequency_hz for p in points])
    gain = np.array([p.gain_db for p in points])
    phase = np.unwrap(np.radians([p.phase_deg for p in points]))
    phase = np.degrees(phase)
    peak = resonance_peak(gain)
    result = {"frequencies_hz": f.tolist(), "gain_db": gain.tolist(), "phase_deg": phase.tolist(),
              "resonance_peak_db": None if peak is None else float(gain[peak]),
              "resonance_hz": None if peak is None else float(f[peak]),
              "bandwidth_hz": _crossing(f, gain, -3.0), "phase_minus_90_hz": _crossing(f, phase, -90.0)}
    if model is not None:
        model_gain, model_phase = model.response(f)
        result["model"] = {"gain_db": model_gain.tolist(), "phase_deg": model_phase.tolist(), **model.margins(),
                           "mass": model.mass, "damping": model.damping, "p": model.p, "i": model.i, "d": model.d}
    return result


def resonance_peak(gain_db) -> int | None:
    """The index of the largest gain when it lies inside the swept range, strictly above the gains at
    both ends; None when the largest gain is at (or level with) either end: no resonance peak was
    measured (see :func:`analyse`)."""
    gain = np.asarray(gain_db, dtype=float)
    if gain.size < 3:
        return None
    peak = int(np.argmax(gain))
    if not (0 < peak < gain.size - 1 and gain[peak] > gain[0] and gain[peak] > gain[-1]):
        return None
    return peak


def _crossing(f: np.ndarray, values: np.ndarray, level: float) -> float:
    """The first frequency where ``values`` falls through ``level`` (log-frequency interpolation); NaN if none."""
    below = np.nonzero(values < level)[0]
    if below.size == 0 or below[0] == 0:
        return math.nan
    k = int(below[0])
    a, b = values[k - 1], values[k]
    s = (a - level) / (a - b)
    return float(math.exp(math.log(f[k - 1]) + s * (math.log(f[k]) - math.log(f[k - 1]))))


def write_bode(out_dir: str | Path, result: dict, title: str) -> Path:
    """``bode.png`` (measured points, model curve) and ``metrics.json`` (strict JSON, non-finite figures as
    null: not measured or unbounded) into ``out_dir``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fig, (ax_gain, ax_phase) = plt.subplots(2, 1, sharex=True, figsize=(8, 6))
    f = result["frequencies_hz"]
    ax_gain.semilogx(f, result["gain_db"], "o", label="measured")
    ax_phase.semilogx(f, result["phase_deg"], "o", label="measured")
    if "model" in result:
        dense = np.logspace(math.log10(min(f)), math.log10(max(f)), 400)
        model = result["model"]
        lm = LoopModel(model["mass"], model["damping"], model["p"], model["i"], model["d"],
                       result["period_s"], result["loop"], result.get("derivative", "error"))
        g, p = lm.response(dense)
        ax_gain.semilogx(dense, g, "-", label="model (plant, gains, 1 kHz hold)")
        ax_phase.semilogx(dense, p, "-", label="model")
    ax_gain.set_ylabel("gain [dB]")
    ax_phase.set_ylabel("phase [deg]")
    ax_phase.set_xlabel("frequency [Hz]")
    ax_gain.set_title(title)
    for ax in (ax_gain, ax_phase):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    path = out / "bode.png"
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    write_metrics(out, result)  # strict JSON: a figure not measured or unbounded is null
    return path


__all__ = ["LoopModel", "Point", "analyse", "bode", "compare", "loop_controller", "measure", "measure_in_session",
           "measure_servoed", "model_plant", "plant_of", "resonance_peak", "servo_reference", "sweep",
           "write_bode"]
