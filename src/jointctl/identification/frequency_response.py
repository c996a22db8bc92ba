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
Simulated time (or the robot's, on hardware). **Amplitudes**: each frequency gets the largest
amplitude whose predicted motion (the model below, steady state at that frequency) keeps the joint's
position, speed and effort inside fractions of its limits and the user's (``--max-effort``,
``--max-velocity``, ``--workspace``): the rule of :mod:`jointctl.identification.safety`, so the
amplitude shrinks where the loop resonates or its effort grows with frequency; the whole timetable is
then simulated on the model and a sine whose start would leave a budget is made smaller
(:func:`plan_sweep`). The amplitude used is reported per point. **Saturation**: the share of each
point's cycles at the actuator's effort or velocity limit is reported; a point above the threshold is
``saturated``, drawn apart and left out of the figures of merit. A crossing of a limit stops the
sweep and brings the joint back (:class:`~jointctl.identification.safety.Guard`).

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
from jointctl.control.pid_controller import PidController
from jointctl.control.position_loop import position_loop
from jointctl.errors import ConfigError
from jointctl.identification.plant_fit import IdentificationError
from jointctl.identification.safety import (DEFAULT, GUARD_FRACTION, Envelope, Guard, Safety, SaturationMonitor, allow,
                                            envelope_for, predicted_peaks, run_guarded, sine_peaks)
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

    def step(self, seconds: float) -> tuple[np.ndarray, np.ndarray]:
        """(t [s], y): the sampled closed loop's response to a unit reference step at t = 0 (y[0] = 0: no
        feed-through), run as its difference equation (the loop's transfer function, a few states: exact,
        and far faster than stepping the state space); y NaN for gains beyond numbers."""
        from scipy.signal import lfilter, ss2tf

        t = np.arange(int(round(seconds / self.period_s))) * self.period_s
        *_, a_cl, b_cl, c_cl = self._matrices()
        if not np.all(np.isfinite(a_cl)):
            return t, np.full_like(t, math.nan)
        num, den = ss2tf(a_cl, b_cl, c_cl, np.zeros((1, 1)))
        return t, lfilter(num[0], den, np.ones_like(t))

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

    def unit_response(self, frequencies_hz) -> dict[str, np.ndarray]:
        """The steady-state response of the sampled loop to a unit sine reference (1 m or rad for a
        position loop, 1 m/s or rad/s for a velocity loop) at each of ``frequencies_hz``, complex:
        ``position`` [m or rad], ``velocity`` [m/s or rad/s] and ``effort`` [N or N·m], the effort the
        controller adds to what holds the joint at rest (gravity), i.e. what moves the plant. The
        effort is read off the sampled plant, ``U = B⁺·(zI - A)·X``: exact for every law."""
        a, bu, *_, a_cl, b_cl, _ = self._matrices()
        eye, plant_eye = np.eye(a_cl.shape[0]), np.eye(2)
        pinv = np.linalg.pinv(bu)
        out = {"position": [], "velocity": [], "effort": []}
        for f in np.asarray(frequencies_hz, dtype=float):
            z = np.exp(1j * 2 * math.pi * f * self.period_s)
            x = np.linalg.solve(z * eye - a_cl, b_cl)[:2, 0]
            out["position"].append(x[0])
            out["velocity"].append(x[1])
            out["effort"].append((pinv @ ((z * plant_eye - a) @ x))[0])
        return {k: np.array(v) for k, v in out.items()}

    def simulate(self, reference) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(position, velocity, effort) of the sampled loop at each cycle of ``reference`` (one value a
        loop period, the deviation from where the joint rests: m or rad for a position loop, m/s or
        rad/s for a velocity loop), from rest; the same units as :meth:`unit_response`. The state
        ``x`` steps as ``x⁺ = A x + B r``; the effort is ``B⁺·(x⁺ - A_plant x)`` on the plant's states
        (filtered as transfer functions: linear, and fast on long references)."""
        from scipy.signal import lfilter, ss2tf

        a, bu, *_, a_cl, b_cl, _ = self._matrices()
        pinv = np.linalg.pinv(bu)
        n = a_cl.shape[0]
        plant_a = np.hstack([a, np.zeros((2, n - 2))])
        outputs = np.vstack([np.eye(n)[:2], pinv @ (a_cl[:2] - plant_a)])
        direct = np.vstack([np.zeros((2, 1)), pinv @ b_cl[:2]])
        r = np.asarray(reference, dtype=float)
        numerators, denominator = ss2tf(a_cl, b_cl, outputs, direct)
        return tuple(lfilter(numerator, denominator, r) for numerator in numerators)

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
    """One measured frequency: ``gain_db`` [dB] and ``phase_deg`` [deg] at ``frequency_hz`` [Hz], with
    the sine's ``amplitude`` [m, rad, or per s] and the ``saturation`` share (a fraction of the point's
    cycles at the actuator's effort or velocity limit, see :mod:`jointctl.identification.safety`);
    ``saturated`` when that share is above the threshold."""

    frequency_hz: float
    gain_db: float
    phase_deg: float
    amplitude: float = math.nan
    saturation: float = 0.0
    saturated: bool = False


def measure(scenario: Scenario, controller_name: str, frequencies_hz, *, amplitude: float | None = None,
            settle_s: float = 1.5, measure_periods: int = 4, measure_s: float = 1.0, plant: dict | None = None,
            safety: Safety | None = None, amplitude_cap: float | None = None) -> tuple[list[Point], dict]:
    """Stepped-sine measurement of ``controller_name``'s closed loop on the scenario's simulated robot,
    in simulated time (see the module docstring); (points, context) where context holds the loop,
    joint, amplitudes, gains, the plan and the loop time it took. ``plant``, ``safety`` and
    ``amplitude_cap`` as for :func:`sweep`."""
    return measure_in_session(Session(scenario), controller_name, frequencies_hz, amplitude=amplitude,
                              settle_s=settle_s, measure_periods=measure_periods, measure_s=measure_s, plant=plant,
                              safety=safety, amplitude_cap=amplitude_cap)


def measure_in_session(session, controller_name: str, frequencies_hz, *, amplitude: float | None = None,
                       settle_s: float = 1.5, measure_periods: int = 4, measure_s: float = 1.0,
                       plant: dict | None = None, safety: Safety | None = None,
                       amplitude_cap: float | None = None) -> tuple[list[Point], dict]:
    """:func:`measure` in a session that exists (a live robot's too); the gains are those the
    controller had when the sweep began."""
    controller, loop = loop_controller(session.manager, controller_name)
    gains = controller.pid.gains
    law = getattr(controller, "derivative", "error")
    as_dict = {"p": gains.p, "i": gains.i, "d": gains.d}
    # A P(D) position loop holds gravity by a static error (a droop) unless an integral or feed-forward does.
    droops = loop == "position" and not gains.i and "gravity" not in getattr(controller, "feedforward_terms", ())
    points, context = sweep(session, controller.joint, frequencies_hz, controller.set_reference, loop=loop,
                            amplitude=amplitude, settle_s=settle_s, measure_periods=measure_periods,
                            measure_s=measure_s, gains=as_dict, derivative=law, plant=plant, safety=safety,
                            amplitude_cap=amplitude_cap, effort_limit=controller.effort_limit,
                            droop_gain=gains.p if droops else None,
                            offset=controller.reference_input[0] if loop == "position" else None)
    context["gains"] = as_dict
    context["derivative"] = law
    return points, context


def loop_controller(manager, name: str, joint: str | None = None):
    """(controller, "position" | "velocity") for ``name``, an effort position or velocity controller
    of ``manager``, or a pid_controller's effort position loop of ``joint`` (its only dof when None) as
    :func:`~jointctl.control.position_loop.position_loop` shows it; a ConfigError naming ``--controller``
    otherwise."""
    try:
        controller = manager.controller(name)
    except Exception:
        raise ConfigError(f"no such controller (started: {', '.join(c.name for c in manager.active)})",
                          field="--controller", value=name) from None
    if isinstance(controller, JointPositionController):
        return controller, "position"
    if isinstance(controller, JointVelocityController):
        return controller, "velocity"
    if isinstance(controller, PidController):
        if joint is None and len(controller.dof_names) > 1:
            raise ConfigError(f"servos {', '.join(controller.dof_names)}: give --joint", field="--controller",
                              value=name)
        found = position_loop(controller, joint)
        if found is not None:
            return found, "position"
        raise ConfigError("the tools model a pid_controller that commands a joint's effort on its own position "
                          "(command_interface effort, reference_and_state_interfaces starting with position, "
                          "the joint's own state)", field="--controller", value=name)
    raise ConfigError("must be an effort position or velocity controller, or a pid_controller commanding an effort",
                      field="--controller", value=name)


def measure_servoed(session: Session, joint: str, frequencies_hz, *, amplitude: float | None = None,
                    settle_s: float = 1.5, measure_periods: int = 4, measure_s: float = 1.0,
                    gains: dict | None = None, derivative: str = "error", plant: dict | None = None,
                    safety: Safety | None = None, amplitude_cap: float | None = None) -> tuple[list[Point], dict]:
    """The same measurement on hardware that servos its joints itself (an industrial controller behind
    :class:`~jointctl.hardware.industrial.IndustrialHardware`, a robot served on the ROS graph): the
    sine goes straight to the joint's position (or velocity) command interface, the response is the
    position (or velocity) the hardware reports. ``session`` must start no controller that commands
    the joint; it runs as it is paced (the wall clock, for real hardware). With the loop's ``gains``
    (``{"p", "i", "d"}``, a served ros_control loop's) and ``derivative`` law the amplitudes are
    planned on its model; without, on the reference alone (no effort is predicted)."""
    owner = session.manager.commanding(joint)
    if owner is not None:
        raise ConfigError(f"controller {owner.name!r} commands it; start none that does", field="--joint", value=joint)
    loop, set_reference = servo_reference(session.hardware, joint)
    droop = gains["p"] if gains is not None and loop == "position" and not gains.get("i") else None
    return sweep(session, joint, frequencies_hz, set_reference, loop=loop, amplitude=amplitude,
                 settle_s=settle_s, measure_periods=measure_periods, measure_s=measure_s, gains=gains,
                 derivative=derivative, plant=plant, safety=safety, amplitude_cap=amplitude_cap, droop_gain=droop,
                 offset=held_reference(session.hardware, joint) if loop == "position" else None)


def held_reference(hardware, joint: str) -> float | None:
    """The position reference a served loop held when this side connected (its ``state`` topic's set
    point, :attr:`~jointctl.ros.served_hardware.ServedRobotHardware.set_points`), or None when unknown."""
    value = (getattr(hardware, "set_points", None) or {}).get(joint)
    return float(value) if isinstance(value, (int, float)) and math.isfinite(value) else None


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


def loop_model(robot, joint: str, pose: dict, gains: dict, period_s: float, loop: str, derivative: str,
               plant: dict | None = None) -> tuple[LoopModel, str]:
    """(the LoopModel of ``joint``'s loop with ``gains``, where its plant came from): the plant from
    ``plant`` (an identification's metrics) or else ``robot``'s model at ``pose`` (joint name -> position)."""
    if plant is not None:
        mass, damping = plant_of(plant)
        source = plant_source(plant)
    else:
        mass, damping = model_plant(robot, joint, pose)
        source = "robot model"
    model = LoopModel(float(mass), float(damping), gains["p"], gains["i"], gains["d"], period_s, loop,
                      derivative if derivative in ("error", "measurement") else "error")
    return model, source


def plant_source(plant: dict) -> str:
    """Where a plant given as a dict came from: its ``plant_source`` when it says (a plant the hardware
    implies, e.g. a unit inertia behind an acceleration command), else "identified" (an identification's
    metrics)."""
    return str(plant.get("plant_source", "identified"))


def plant_friction(plant: dict | None) -> float | None:
    """The Coulomb friction of an identification's metrics [N or N·m], or None when it has none."""
    if plant is None:
        return None
    value = plant.get("friction_n", plant.get("friction_n_m"))
    return abs(float(value)) if isinstance(value, (int, float)) and math.isfinite(value) else None


def schedule_of(frequencies, start_s: float, settle_s: float, measure_periods: int,
                measure_s: float) -> list[tuple[float, float, float, float]]:
    """The stepped sines' timetable from ``start_s`` [s]: (frequency [Hz], start, measuring from, end)
    each; each sine settles ``settle_s`` and at least two periods, then is measured over at least
    ``measure_periods`` periods and ``measure_s``; both spans are whole periods, so each sine ends where
    it began (at the rest reference) and the next begins there: the reference never jumps."""
    schedule = []
    t0 = start_s
    for f in frequencies:
        settle = math.ceil(max(settle_s, 2.0 / f) * f - 1e-9) / f
        span = math.ceil(max(measure_periods, measure_s * f) - 1e-9) / f
        schedule.append((f, t0, t0 + settle, t0 + settle + span))
        t0 += settle + span
    return schedule


def plan_sweep(frequencies_hz, envelope: Envelope, model: LoopModel | None, *, loop: str, period_s: float,
               amplitude: float | None = None, amplitude_cap: float | None = None, settle_s: float = 1.5,
               measure_periods: int = 4, measure_s: float = 1.0, lead_s: float = 0.5) -> dict:
    """The amplitude of each stepped sine (the rule of :mod:`jointctl.identification.safety`) and what
    ``model`` predicts of the sweep: per frequency the largest safe amplitude (steady state), the
    limit that binds ("cap" where ``amplitude_cap`` is the smaller) and the amplitude used (``amplitude``
    at every frequency, refused where it is beyond the safe one; else the safe one, at most
    ``amplitude_cap``); then the whole timetable is
    simulated on the model from rest (the change from one sine to the next included) and a sine
    whose transient would leave a budget is made smaller until none does. Returns the ``schedule``
    (:func:`schedule_of`), per-point ``rows`` (frequency_hz, safe_amplitude, binds, amplitude, predicted
    peaks beside their limits, reduced_for_transient) and the ``envelope``."""
    frequencies = [float(f) for f in frequencies_hz]
    schedule = schedule_of(frequencies, lead_s, settle_s, measure_periods, measure_s)
    allowances = [allow(sine_peaks(model, f, loop), envelope) for f in frequencies]
    if amplitude is not None:
        for f, allowance in zip(frequencies, allowances):
            allowance.refuse_beyond(amplitude, what=f" at {f:.3g} Hz")
        amplitudes = [float(amplitude)] * len(frequencies)
    else:
        amplitudes = [a.amplitude if amplitude_cap is None else min(a.amplitude, amplitude_cap) for a in allowances]
    peaks = None
    if model is not None:
        budgets = envelope.budgets()
        for _ in range(8):
            peaks = _schedule_peaks(model, schedule, amplitudes, period_s, loop)
            worst = [max(_used(p, envelope)[k] / budgets[k] if budgets[k] > 0 and math.isfinite(budgets[k]) else 0.0
                         for k in ("position", "velocity", "effort")) for p in peaks]
            if max(worst) <= 1 + 1e-9:
                break
            if amplitude is not None:
                k = int(np.argmax(worst))
                raise IdentificationError(
                    f"must be positive and at most {amplitudes[k] / worst[k]:.4g} {envelope.unit} at "
                    f"{frequencies[k]:.3g} Hz: the change from the sine before it would leave the budget there",
                    field="amplitude", value=amplitude)
            amplitudes = [a / w * 0.999 if w > 1 else a for a, w in zip(amplitudes, worst)]
    rows = []
    for k, (f, allowance, a) in enumerate(zip(frequencies, allowances, amplitudes)):
        predicted = allowance.predicted(a)
        if peaks is not None:  # the timetable's own peaks, transients included
            predicted = predicted_peaks(envelope, envelope.droop + peaks[k]["position"], peaks[k]["velocity"],
                                        peaks[k]["effort"])
        capped = amplitude is None and amplitude_cap is not None and amplitude_cap < allowance.amplitude
        rows.append({"frequency_hz": f, "safe_amplitude": allowance.amplitude,
                     "binds": "cap" if capped else allowance.binds, "amplitude": a, "predicted": predicted,
                     "reduced_for_transient": a < (min(allowance.amplitude, amplitude_cap) if capped
                                                   else allowance.amplitude) * (1 - 1e-9)})
    return {"schedule": schedule, "rows": rows, "envelope": envelope, "loop": loop,
            "duration_s": schedule[-1][3] + 0.1 if schedule else 0.0}


def _used(peaks: dict, envelope: Envelope) -> dict:
    """What a sine's peaks use of each budget: the swing, the speed, and the effort with the gravity
    stiffness over the swing."""
    return {"position": peaks["position"], "velocity": peaks["velocity"],
            "effort": peaks["effort"] + envelope.stiffness * peaks["position"]}


def _schedule_peaks(model: LoopModel, schedule, amplitudes, period_s: float, loop: str) -> list[dict]:
    """Per sine of ``schedule`` at ``amplitudes``, the model's largest position swing, speed and effort
    over its span (the reference's own swing counted, as in the rule), simulated from rest."""
    start = schedule[0][1]
    n = int(round((schedule[-1][3] - start) / period_s)) + 200
    t = start + np.arange(n) * period_s
    r = np.zeros(n)
    spans = []
    for (f, t0, _, t1), a in zip(schedule, amplitudes):
        window = (t >= t0 - 1e-9) & (t < t1 - 1e-9)
        r[window] = a * np.sin(2 * math.pi * f * (t[window] - t0))
        spans.append(window)
    q, v, u = model.simulate(r)
    own = r if loop == "position" else None
    peaks = []
    for (f, *_), a, window in zip(schedule, amplitudes, spans):
        swing = np.abs(q[window]).max() if window.any() else 0.0
        swing = max(swing, a if own is not None else a / (2 * math.pi * f))
        peaks.append({"position": float(swing), "velocity": float(np.abs(v[window]).max()),
                      "effort": float(np.abs(u[window]).max())})
    return peaks


def sweep(session: Session, joint: str, frequencies_hz, set_reference, *, loop: str, amplitude: float | None,
          settle_s: float, measure_periods: int, measure_s: float, gains: dict | None = None,
          derivative: str = "error", plant: dict | None = None, safety: Safety | None = None,
          amplitude_cap: float | None = None, effort_limit: float | None = None,
          droop_gain: float | None = None, offset: float | None = None) -> tuple[list[Point], dict]:
    """Run the stepped sines on ``session`` (any hardware), handing each cycle's reference to
    ``set_reference``; (points, context). The amplitudes are planned by :func:`plan_sweep` on the loop
    model (``gains`` ``{"p", "i", "d"}`` and ``derivative``, the plant from ``plant`` or the robot model;
    no model without gains), inside ``safety``'s limits; ``amplitude`` fixes one for every frequency
    (refused where unsafe), ``amplitude_cap`` caps the planned ones. A position loop's sines are centred
    on ``offset`` [m or rad], the reference the loop holds (default: where the joint is; a loop under
    gravity rests below its reference, and a jump of the reference to there would kick a derivative on
    the error by ``d·droop/period``). While it runs, the saturation of
    every cycle is counted and a :class:`~jointctl.identification.safety.Guard` watches the limits:
    a crossing stops the sweep, brings the joint back and raises SafetyStop."""
    safety = safety or DEFAULT
    frequencies = [float(f) for f in frequencies_hz]
    hardware, robot = session.hardware, session.robot
    period = session.loop.period_s
    nyquist = 0.5 / period
    if not frequencies or min(frequencies) <= 0 or max(frequencies) >= nyquist:
        raise IdentificationError(f"frequencies must be positive and below the loop's Nyquist {nyquist:g} Hz",
                                  field="frequencies_hz", value=frequencies)
    index = hardware.joint_index(joint)
    hardware.read()
    rest = hardware.position[index] if offset is None or loop != "position" else float(offset)
    pose = dict(zip(hardware.joint_names, hardware.position))
    model = source = None
    if gains is not None:
        model, source = loop_model(robot, joint, pose, gains, period, loop, derivative, plant)
    envelope = envelope_for(robot, joint, rest, safety, pose=pose, gravity_m_s2=session_gravity(session),
                            friction=plant_friction(plant), droop_gain=droop_gain, effort_limit=effort_limit)
    started = session.loop.time_s
    plan = plan_sweep(frequencies, envelope, model, loop=loop, period_s=period, amplitude=amplitude,
                      amplitude_cap=amplitude_cap, settle_s=settle_s, measure_periods=measure_periods,
                      measure_s=measure_s, lead_s=0.5)
    amplitudes = [row["amplitude"] for row in plan["rows"]]
    schedule = [(f, started + a, started + b, started + c) for f, a, b, c in plan["schedule"]]
    samples: list[tuple[float, float, float]] = []  # one tuple per cycle: whole even when read from another thread
    state = {"k": 0}
    offset = rest if loop == "position" else 0.0

    def reference_at(time_s: float) -> float:
        k = state["k"]
        while k < len(schedule) and time_s >= schedule[k][3] - 1e-9:
            k += 1
        state["k"] = k
        if k >= len(schedule) or time_s < schedule[k][1] - 1e-9:
            return offset
        f, start = schedule[k][0], schedule[k][1]
        return offset + amplitudes[k] * math.sin(2 * math.pi * f * (time_s - start))

    measured = hardware.position if loop == "position" else hardware.velocity
    # A velocity loop does not hold a position: gravity or friction would walk the joint to a limit. A
    # slow position term in its reference (a tenth of the lowest frequency) keeps it near ``rest``; the
    # fit uses the reference as given, so the loop's response is measured all the same.
    hold_per_s = 2 * math.pi * min(frequencies) / 10 if loop == "velocity" else 0.0
    given = [offset]
    spec = robot.joint(joint)
    lower, upper, _ = spec.range_and_speed()
    guard = Guard(hardware, index, envelope, loop=loop, start=offset,
                  band=GUARD_FRACTION * (upper - lower) if math.isfinite(upper - lower) else math.inf)
    monitor = SaturationMonitor(hardware, index, envelope.effort_limit, envelope.velocity_limit,
                                safety.saturation_margin)

    def drive(time_s: float) -> None:
        given[0] = guard.reference(time_s, reference_at(time_s) + hold_per_s * (rest - hardware.position[index]))
        set_reference(given[0])

    def record(time_s: float) -> None:
        samples.append((time_s, given[0], measured[index]))

    session.loop.add_input(drive)
    watchers = (record, monitor, guard.observe)  # bound once: removal compares identity
    for hook in watchers:
        session.loop.add_observer(hook)
    try:
        run_guarded(session, plan["duration_s"], guard)
    finally:
        session.loop.remove_input(drive)
        for hook in watchers:
            session.loop.remove_observer(hook)
    if guard.trip is not None:
        raise guard.error("the sweep")
    # Reference and response at the same loop time: the response measured at the start of a cycle,
    # the reference that cycle's (held over the period that follows).
    t, r, y = np.array(list(samples)).T
    points, shares = [], []
    for (f, start, measure_from, end), a in zip(schedule, amplitudes):
        window = (t >= start - 1e-9) & (t < end - 1e-9)
        fit = sinusoid_response(t[window] - start, r[window], y[window], frequency_hz=f,
                                start_s=measure_from - start)
        share = monitor.share(start - 1e-9, end - 1e-9)
        shares.append(share)
        points.append(Point(f, 20 * math.log10(fit.amplitude_ratio), -fit.phase_lag_deg, a, share["share"],
                            share["share"] > safety.saturation_share))
    context = {"loop": loop, "joint": joint, "amplitude": max(amplitudes), "amplitudes": amplitudes, "rest": rest,
               "simulated_s": plan["duration_s"], "period_s": period,
               "plan": plan_summary(plan), "saturation": {**monitor.describe(), "threshold": safety.saturation_share,
                                                          "peak_effort": [s["peak_effort"] for s in shares],
                                                          "peak_velocity": [s["peak_velocity"] for s in shares]}}
    if source is not None:
        context["planned_on"] = source
    return points, context


def plan_summary(plan: dict) -> dict:
    """The parts of a :func:`plan_sweep` plan that go into metrics.json: per point the safe amplitude,
    the binding limit and the predicted peaks; the envelope's limits and budgets."""
    env: Envelope = plan["envelope"]
    return {"joint": env.joint, "rest": env.rest, "window": list(env.window), "room": env.room, "unit": env.unit,
            "velocity_limit": env.velocity_max, "effort_limit": env.effort_max, "bias": env.bias, "droop": env.droop,
            "budgets": env.budgets(), "duration_s": plan["duration_s"],
            "points": [{"frequency_hz": row["frequency_hz"], "amplitude": row["amplitude"],
                        "safe_amplitude": row["safe_amplitude"], "binds": row["binds"],
                        "reduced_for_transient": row["reduced_for_transient"],
                        "peak_position": row["predicted"]["position"]["peak"],
                        "peak_velocity": row["predicted"]["velocity"]["peak"],
                        "peak_effort": row["predicted"]["effort"]["peak"]} for row in plan["rows"]]}


def session_gravity(session) -> tuple[float, float, float]:
    """The gravity [m/s²] a session's robot is under: its scenario's (a live page's too), else Earth's."""
    scenario = getattr(session, "scenario", None) or getattr(getattr(session, "tuner", None), "scenario", None)
    return tuple(getattr(scenario, "gravity_m_s2", (0.0, 0.0, -9.81)))


def bode(scenario: Scenario, controller_name: str, frequencies_hz, *, plant: dict | None = None,
         amplitude: float | None = None, out_dir: str | Path | None = None, safety: Safety | None = None) -> dict:
    """Measure ``controller_name``'s closed loop at ``frequencies_hz`` and set it beside its model:
    the plant from ``plant`` (an identification's metrics: ``mass_kg``/``inertia_kg_m2`` and
    ``damping_*``) or else from the robot model (the joint's mass-matrix entry at the rest pose,
    armature included, and its URDF damping). The amplitudes are planned on that model inside
    ``safety``'s limits (:func:`plan_sweep`). Writes ``bode.png`` and ``metrics.json`` to ``out_dir``
    when given; returns the metrics."""
    points, context = measure(scenario, controller_name, frequencies_hz, amplitude=amplitude, plant=plant,
                              safety=safety)
    robot = load_robot_model(scenario.robot.description)
    pose = {**scenario.initial_positions, context["joint"]: context["rest"]}
    return compare(points, context, controller_name, plant, robot, pose, out_dir=out_dir)


def compare(points: list[Point], context: dict, controller_name: str, plant: dict | None, robot, pose: dict,
            *, out_dir: str | Path | None = None) -> dict:
    """Set measured ``points`` (with their sweep ``context`` and the ``gains`` in it) beside the loop
    model: the plant from ``plant`` (an identification's metrics) or else from ``robot`` (the
    joint's mass-matrix entry at ``pose``, joint name -> position, and its URDF damping); write
    ``bode.png`` and ``metrics.json`` to ``out_dir`` when given; the metrics."""
    model, source = loop_model(robot, context["joint"], pose, context["gains"], context["period_s"], context["loop"],
                               context.get("derivative", "error"), plant)
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

    A point measured while the actuator saturated (``saturated``, see :class:`Point`) is kept in the
    lists but left out of these figures (the loop it measured was not the linear loop): they are
    read off the other points, and ``saturated_hz`` lists the points left out.
    """
    f = np.array([p.frequency_hz for p in points])
    gain = np.array([p.gain_db for p in points])
    phase = np.unwrap(np.radians([p.phase_deg for p in points]))
    phase = np.degrees(phase)
    clean = np.array([not p.saturated for p in points], dtype=bool)
    fc, gc, pc = f[clean], gain[clean], phase[clean]
    peak = resonance_peak(gc)
    result = {"frequencies_hz": f.tolist(), "gain_db": gain.tolist(), "phase_deg": phase.tolist(),
              "amplitudes": [p.amplitude for p in points],
              "saturation_share": [p.saturation for p in points], "saturated": [p.saturated for p in points],
              "saturated_hz": f[~clean].tolist(),
              "resonance_peak_db": None if peak is None else float(gc[peak]),
              "resonance_hz": None if peak is None else float(fc[peak]),
              "bandwidth_hz": _crossing(fc, gc, -3.0), "phase_minus_90_hz": _crossing(fc, pc, -90.0)}
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


#: What the Bode figure of a position or a velocity loop plots: the closed loop's output over its reference.
_BODE_SUBJECT = {"position": "position / reference", "velocity": "velocity / reference"}


def write_bode(out_dir: str | Path, result: dict, title: str) -> Path:
    """``bode.png`` and ``bode.svg`` and ``metrics.json`` (strict JSON, non-finite figures as null: not
    measured or unbounded) into ``out_dir``. The figure: measured gain [dB] and phase [deg] on a log
    frequency axis spanning the sweep, saturated points crossed out, the model's curves, the -3 dB
    level and the bandwidth, the resonance peak, and the model's gain and phase margins written in the
    gain panel (they belong to the loop transfer function, not to the curve drawn). SVG element ids:
    ``bode-measured-gain``, ``bode-model-gain``, ``bode-bandwidth``, ``bode-resonance``, ``bode-margins``."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    from jointctl.recording.figures import new_figure, save_figure

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fig, (ax_gain, ax_phase) = new_figure([1.0, 1.0], size_in=(8.0, 6.0))
    f = np.asarray(result["frequencies_hz"], dtype=float)
    hit = np.asarray(result.get("saturated", [False] * len(f)), dtype=bool)
    for ax, key, what in ((ax_gain, "gain_db", "gain"), (ax_phase, "phase_deg", "phase")):
        values = np.asarray(result[key], dtype=float)
        ax.semilogx(f[~hit], values[~hit], "o", color="tab:blue", label="measured", gid=f"bode-measured-{what}")
        if hit.any():
            ax.semilogx(f[hit], values[hit], "x", color="tab:red", markersize=9, markeredgewidth=2,
                        label="saturated (left out)", gid=f"bode-saturated-{what}")
    model = result.get("model")
    if model is not None and len(f):
        dense = np.logspace(math.log10(min(f)), math.log10(max(f)), 400)
        lm = LoopModel(model["mass"], model["damping"], model["p"], model["i"], model["d"],
                       result["period_s"], result["loop"], result.get("derivative", "error"))
        g, ph = lm.response(dense)
        ax_gain.semilogx(dense, g, "-", color="tab:orange", label="model (plant, gains, 1 kHz hold)",
                         gid="bode-model-gain")
        ax_phase.semilogx(dense, ph, "-", color="tab:orange", label="model", gid="bode-model-phase")
        ax_gain.text(0.02, 0.04, _margins_text(model), transform=ax_gain.transAxes, fontsize=8, va="bottom",
                     bbox={"facecolor": "white", "alpha": 0.8, "edgecolor": "0.7"}, gid="bode-margins")
    ax_gain.axhline(-3.0, color="0.4", linestyle=":", linewidth=1.0, label="-3 dB")
    bandwidth = result.get("bandwidth_hz")
    if bandwidth is not None and math.isfinite(bandwidth):
        for k, ax in enumerate((ax_gain, ax_phase)):
            ax.axvline(bandwidth, color="tab:green", linestyle="--", linewidth=1.0,
                       label=f"bandwidth {bandwidth:.3g} Hz" if k == 0 else None,
                       gid="bode-bandwidth" if k == 0 else "bode-bandwidth-phase")
    if result.get("resonance_hz") is not None:
        ax_gain.annotate(f"peak {result['resonance_peak_db']:.1f} dB at {result['resonance_hz']:.3g} Hz",
                         (result["resonance_hz"], result["resonance_peak_db"]), xytext=(10, -16),
                         textcoords="offset points", fontsize=8, gid="bode-resonance",
                         arrowprops={"arrowstyle": "-", "color": "0.4"})
    if len(f):
        ax_phase.set_xlim(min(f) / 1.1, max(f) * 1.1)  # the sweep's range, not matplotlib's decades
    ax_phase.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    ax_phase.xaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    ax_phase.xaxis.set_minor_formatter(NullFormatter())
    subject = _BODE_SUBJECT.get(result.get("loop"), "output / input")
    ax_gain.set_ylabel(f"gain |{subject}| [dB]")
    ax_phase.set_ylabel("phase [°]")
    ax_phase.set_xlabel("frequency [Hz]")
    ax_gain.set_title(title)
    path = save_figure(fig, (ax_gain, ax_phase), out / "bode.png")
    write_metrics(out, result)  # strict JSON: a figure not measured or unbounded is null
    return path


def _margins_text(model: dict) -> str:
    """The model's stability margins in one line each (∞ where the phase never reaches -180°)."""
    gm, pm = model.get("gain_margin_db", math.inf), model.get("phase_margin_deg", math.nan)
    gm_text = "∞" if gm is None or not math.isfinite(gm) else f"{gm:.1f} dB at {model['phase_crossover_hz']:.3g} Hz"
    pm_text = ("none (the loop gain stays below 1)" if pm is None or not math.isfinite(pm)
               else f"{pm:.1f}° at {model['gain_crossover_hz']:.3g} Hz")
    return f"model's loop: gain margin {gm_text}\nphase margin {pm_text}"


__all__ = ["LoopModel", "Point", "analyse", "bode", "compare", "held_reference", "loop_controller", "loop_model",
           "measure", "measure_in_session", "measure_servoed", "model_plant", "plan_summary", "plan_sweep",
           "plant_friction", "plant_of", "resonance_peak", "schedule_of", "servo_reference", "session_gravity",
           "sweep", "write_bode"]
