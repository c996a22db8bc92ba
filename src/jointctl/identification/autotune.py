"""``jointctl autotune``: gains for a damping ratio and a bandwidth, checked on the model and on the robot.

**Design.** The plant is the joint's mass (or inertia) ``m`` and viscous damping ``b`` (identified,
or the robot model's). A position loop gets a PD (``p``, ``d``; the derivative on the measured
speed, as jointctl's position controller does with a position-only reference), making
``p / (m s² + (b + d) s + p)``: ``ωn = sqrt(p/m)``, ``ζ = (b + d) / (2·sqrt(p·m))``, whose -3 dB
bandwidth is ``ωn·sqrt(1 - 2ζ² + sqrt(4ζ⁴ - 4ζ² + 2))`` and step overshoot ``exp(-πζ/sqrt(1-ζ²))``
(4.6 % at ζ = 0.7). A velocity loop gets a P (``p``), making ``p / (m s + p + b)`` with bandwidth
``(p + b)/m``. The continuous design is then corrected for the 1 kHz sample-and-hold: the sampled
loop's model (python-control, :class:`~jointctl.identification.frequency_response.LoopModel`) is
solved for the gains whose overshoot and -3 dB bandwidth meet the spec.

**Effort.** A step of ``step`` [m or rad; m/s or rad/s for a velocity loop] asks ``p·step`` at once,
on top of the gravity load: when ``p·step + |gravity|`` exceeds the joint's effort limit the spec
is refused, naming the bandwidth that step allows.

**Check.** Before they are offered, the gains are simulated on the sampled model and on the robot
itself (the scenario with the new gains: a step of ``step`` from rest, and a stepped-sine sweep
around the bandwidth), and both figures are reported. The gains are written as the robot's
controller YAML (the chapter's format), the tuned controller's ``pid`` replaced, everything else as
loaded.
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import numpy as np
import yaml
from scipy.optimize import fsolve

from jointctl.errors import ConfigError
from jointctl.identification.frequency_response import LoopModel, _crossing, _model_plant, loop_controller, measure
from jointctl.identification.plant_fit import IdentificationError
from jointctl.scenario.session import Session
from jointctl.scenario.spec import Scenario


def bandwidth_ratio(zeta: float) -> float:
    """-3 dB bandwidth over ωn of ``ωn² / (s² + 2ζωn s + ωn²)``."""
    return math.sqrt(1 - 2 * zeta**2 + math.sqrt(4 * zeta**4 - 4 * zeta**2 + 2))


def overshoot_of(zeta: float) -> float:
    """Step overshoot (a fraction) of an underdamped second-order loop."""
    return math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2)) if zeta < 1 else 0.0


def zeta_of(overshoot: float) -> float:
    """The damping ratio of a second-order loop with step ``overshoot`` (a fraction; NaN if none)."""
    if not overshoot > 0:
        return math.nan
    log = math.log(overshoot)
    return -log / math.sqrt(math.pi**2 + log**2)


def design(mass: float, damping: float, *, loop: str, bandwidth_hz: float, zeta: float = 0.7,
           period_s: float = 0.001) -> dict:
    """Gains ``{"p", "i", "d"}`` for the spec on the sampled loop (see the module docstring)."""
    wb = 2 * math.pi * bandwidth_hz
    if loop == "velocity":
        p0 = mass * wb - damping
        if p0 <= 0:
            raise IdentificationError(f"the plant alone is faster than {bandwidth_hz:g} Hz: no gain needed",
                                      field="bandwidth_hz", value=bandwidth_hz)

        def miss_v(x):
            model = LoopModel(mass, damping, x[0], 0.0, 0.0, period_s, "velocity")
            gain, _ = model.response([bandwidth_hz])
            dc, _ = model.response([1e-3])
            return [gain[0] - dc[0] + 3.0103]

        (p,) = fsolve(miss_v, [p0], xtol=1e-10)
        return {"p": float(p), "i": 0.0, "d": 0.0}
    if not 0 < zeta < 1:
        raise IdentificationError("must be in (0, 1) (an underdamped loop)", field="zeta", value=zeta)
    wn = wb / bandwidth_ratio(zeta)
    p0, d0 = mass * wn**2, 2 * zeta * wn * mass - damping
    if d0 < 0:
        raise IdentificationError(f"the plant's own damping exceeds ζ {zeta:g} at {bandwidth_hz:g} Hz; ask for a "
                                  "higher bandwidth or damping ratio", field="zeta", value=zeta)
    target_overshoot = overshoot_of(zeta)

    def miss(x):
        model = LoopModel(mass, damping, x[0], 0.0, x[1], period_s, "position")
        gain, _ = model.response([bandwidth_hz])
        return [gain[0] + 3.0103, (_model_overshoot(model) - target_overshoot) * 100]

    p, d = fsolve(miss, [p0, d0], xtol=1e-10)
    return {"p": float(p), "i": 0.0, "d": float(d)}


def _model_overshoot(model: LoopModel) -> float:
    import control

    closed = model.closed_loop()
    n = int(round(3.0 / model.period_s))
    t = np.arange(n) * model.period_s
    _, y = control.step_response(closed, T=t)
    y = np.asarray(y).ravel()
    final = y[-1]
    return float((y.max() - final) / final)


def autotune(scenario_for, controller_name: str, *, bandwidth_hz: float, zeta: float = 0.7, step: float,
             plant: dict | None = None, out_dir: str | Path | None = None, check_on_robot: bool = True) -> dict:
    """Tune ``controller_name`` of the scenario ``scenario_for(overrides)`` gives (see the module
    docstring); the metrics (gains, predicted and simulated figures). ``plant`` as for
    :func:`jointctl.identification.frequency_response.bode`."""
    for name, value in (("bandwidth_hz", bandwidth_hz), ("step", step)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise IdentificationError("must be a positive number", field=name, value=value)
    scenario: Scenario = scenario_for(())
    session = Session(scenario)
    hardware = session.hardware
    controller, loop = loop_controller(session.manager, controller_name)
    joint = controller.joint
    hardware.read()
    rest = hardware.position[hardware.joint_index(joint)]
    period = session.loop.period_s
    if plant is not None:
        mass = plant.get("mass_kg", plant.get("inertia_kg_m2"))
        damping = plant.get("damping_n_s_m", plant.get("damping_n_m_s_rad"))
        gravity = abs(plant.get("gravity_load_n", 0.0))
        source = "identified"
    else:
        mass, damping = _model_plant(scenario, joint, rest)
        gravity = _gravity_load(session, joint)
        source = "robot model"
    effort_limit = controller.effort_limit
    gains = design(mass, damping, loop=loop, bandwidth_hz=bandwidth_hz, zeta=zeta, period_s=period)
    need = gains["p"] * step + gravity
    if need > effort_limit:
        achievable = _achievable_hz(mass, damping, loop, zeta, (effort_limit - gravity) / step)
        raise IdentificationError(
            f"a step of {step:g} would ask {need:.4g} of the joint's effort limit {effort_limit:g} (p {gains['p']:.4g}"
            f" and a gravity load of {gravity:.4g}); the most this step allows is {achievable:.3g} Hz",
            field="bandwidth_hz", value=bandwidth_hz)
    model = LoopModel(mass, damping, gains["p"], gains["i"], gains["d"], period, loop)
    predicted = {"bandwidth_hz": _model_bandwidth(model, bandwidth_hz)}
    if loop == "position":
        predicted["overshoot_pct"] = 100 * _model_overshoot(model)
    result = {"controller": controller_name, "joint": joint, "loop": loop, "plant_source": source, "mass": mass,
              "damping": damping, "gravity_load": gravity, "effort_limit": effort_limit, "step": step,
              "spec": {"bandwidth_hz": bandwidth_hz, "zeta": zeta if loop == "position" else None,
                       "overshoot_pct": 100 * overshoot_of(zeta) if loop == "position" else None},
              "gains": gains, "model": predicted, "previous_gains": {"p": controller.pid.gains.p,
                                                                     "i": controller.pid.gains.i,
                                                                     "d": controller.pid.gains.d}}
    session.close()
    if check_on_robot:
        result["robot"] = _check_on_robot(scenario_for, controller_name, gains, loop, step, bandwidth_hz)
    if out_dir is not None:
        _write(out_dir, scenario, controller_name, gains, result)
    return result


def _gravity_load(session: Session, joint: str) -> float:
    """|gravity effort| on ``joint`` at the initial pose, from the robot model."""
    from jointctl.model.dynamics import RobotDynamics

    robot = session.robot
    dynamics = RobotDynamics(robot, gravity_m_s2=session.scenario.gravity_m_s2)
    names = [j.name for j in robot.movable_joints]
    hw = session.hardware
    dynamics.set_pose([hw.position[hw.joint_index(n)] for n in names])
    return float(abs(dynamics.gravity_at_pose()[names.index(joint)]))


def _achievable_hz(mass: float, damping: float, loop: str, zeta: float, p_max: float) -> float:
    if p_max <= 0:
        return 0.0
    if loop == "velocity":
        return (p_max + damping) / mass / (2 * math.pi)
    return math.sqrt(p_max / mass) * bandwidth_ratio(zeta) / (2 * math.pi)


def _model_bandwidth(model: LoopModel, around_hz: float) -> float:
    f = np.logspace(math.log10(around_hz / 10), math.log10(min(around_hz * 10, 0.45 / model.period_s)), 400)
    gain, _ = model.response(f)
    dc, _ = model.response([around_hz / 1000])
    return _crossing(f, gain - dc[0], -3.0103)


def _overrides(controller_name: str, gains: dict) -> list[str]:
    return [f"controllers.{controller_name}.pid.{k}={v!r}" for k, v in gains.items()]


def _check_on_robot(scenario_for, controller_name: str, gains: dict, loop: str, step: float,
                    bandwidth_hz: float) -> dict:
    """The robot with the new gains: a step from rest, and a sweep around the bandwidth."""
    scenario = scenario_for(_overrides(controller_name, gains))
    session = Session(scenario)
    controller = session.manager.controller(controller_name)
    hardware = session.hardware
    index = hardware.joint_index(controller.joint)
    measured = hardware.position if loop == "position" else hardware.velocity
    samples: list[float] = []
    start = {}

    def drive(time_s: float) -> None:
        if time_s >= 1.0:
            if "value" not in start:
                start["value"] = measured[index]
                start["reference"] = hardware.position[index] if loop == "position" else 0.0
            controller.set_reference(start["reference"] + step)

    session.loop.add_input(drive)
    session.loop.add_observer(lambda t: samples.append(measured[index]) if t >= 1.0 else None)
    with session:
        session.run(4.0)
    y = np.array(samples)
    final = float(y[-200:].mean())
    rise = final - start["value"]
    overshoot = 100 * (y.max() - final) / rise if rise > 0 else math.nan
    frequencies = np.logspace(math.log10(bandwidth_hz / 2.5), math.log10(bandwidth_hz * 2.5), 15)
    points, _ = measure(scenario, controller_name, frequencies, amplitude=step)
    gain = np.array([p.gain_db for p in points])
    low, _ = measure(scenario, controller_name, [bandwidth_hz / 20], amplitude=step)
    bandwidth = _crossing(frequencies, gain - low[0].gain_db, -3.0103)
    return {"step_overshoot_pct": float(overshoot) if loop == "position" else None,
            "step_zeta": zeta_of(overshoot / 100) if loop == "position" else None,
            "step_final": final, "step_start": start["value"], "bandwidth_hz": bandwidth}


def _write(out_dir, scenario: Scenario, controller_name: str, gains: dict, result: dict) -> None:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    source = Path(scenario.controller_file)
    document = yaml.safe_load(source.read_text())
    tuned = copy.deepcopy(document)
    found = False
    for namespace in tuned.values():
        if isinstance(namespace, dict) and controller_name in namespace:
            pid = namespace[controller_name].setdefault("pid", {})
            pid.update({k: round(v, 6) for k, v in gains.items()})
            found = True
    if not found:
        raise ConfigError("the controller is not in its file", source=str(source), field=controller_name)
    header = (f"# {source.name} with {controller_name} tuned by jointctl autotune for "
              f"{result['spec']['bandwidth_hz']:g} Hz" + (f", damping ratio {result['spec']['zeta']:g}"
                                                         if result["loop"] == "position" else "") + ".\n")
    path = out / source.name
    path.write_text(header + yaml.safe_dump(tuned, sort_keys=False))
    result["yaml"] = str(path)
    (out / "metrics.json").write_text(json.dumps(result, indent=2, default=float))


__all__ = ["autotune", "bandwidth_ratio", "design", "overshoot_of", "zeta_of"]
