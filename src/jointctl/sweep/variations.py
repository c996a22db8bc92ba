"""What a sweep varies, and the runs it makes.

``--vary FIELD=VALUES``, where FIELD is a scenario field, as ``--set`` reaches it in every command (the scenario
owns them all; a sweep only iterates over them):

==========================  ====================================================================================
``payload_kg``              a point mass [kg] at the tool: the origin of the robot.yaml's ``payload_link``, else
                            of the description's last link (the 1-DOF robot's sensor disk, the arm's flange sensor)
``latency_cycles``          commands reach the robot this many control cycles late (whole numbers, 0 or more)
``noise.position``          white noise on each measured joint position: standard deviation [m or rad]
``noise.velocity``          white noise on each measured joint velocity: standard deviation [m/s or rad/s]
``model.LINK.FIELD``        the simulated robot's link: ``mass`` [kg] (its inertia scaled with it: the same
                            shape, denser) or one entry of its inertia tensor ``ixx iyy izz ixy ixz iyz`` [kg·m²]
``model.JOINT.FIELD``       the simulated robot's joint: ``damping`` [N·s/m or N·m·s/rad], ``friction``
                            [N or N·m], ``armature`` [kg or kg·m²]
any other                   ``gravity``, ``duration_s``, ``controllers.joint1_position_controller.pid.p``,
                            ``initial_positions.joint1``...
==========================  ====================================================================================

and VALUES is a grid ``a:b:n`` (n values from a to b, evenly spaced), a list ``a,b,c`` or ``[a, b, c]`` (YAML:
numbers, true/false, words), or a distribution ``uniform(a, b)`` or ``normal(mu, sigma)``.

``model.*``, ``payload_kg``, latency and noise change the simulated robot only: the controllers and their
feed-forward keep the robot's nominal model, as on a real robot whose model is an estimate.

The runs: every combination of the grids' and lists' values (a full factorial, the first ``--vary``
varying slowest), each with ``samples`` draws of the distributions (default 1). Draw ``k`` comes from a
generator seeded with ``(seed, k)``, so every grid point sees the same sampled plants (common random
numbers: differences between grid points are not sampling noise), and a run's sensor noise from
``(seed, run index)``: the table depends on the seed and the arguments only, never on the workers.
"""

from __future__ import annotations

import itertools
import json
import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import yaml

from jointctl.control.manager import load_yaml_text
from jointctl.control.params import unknown_field_message
from jointctl.errors import ConfigError
from jointctl.scenario.plant import MODEL_PREFIX, PAYLOAD
from jointctl.scenario.spec import LATENCY, NOISE_FIELDS, SCENARIO_FIELDS

#: The scenario's fields of the sensors' noise (standard deviations).
NOISE_POSITION = "noise.position"
NOISE_VELOCITY = "noise.velocity"
DISTRIBUTIONS = ("uniform", "normal")
#: What a VALUES that is none of the forms is told.
FORMS = "a grid a:b:n, a list a,b,... or [a, b, ...], uniform(a, b) or normal(mu, sigma)"

_CALL = re.compile(r"^\s*([A-Za-z_]\w*)\s*\((.*)\)\s*$")


@dataclass(frozen=True)
class Variation:
    """One ``--vary``: ``field`` and either its ``values`` (a grid or a list) or a ``distribution``
    (``"uniform"``: ``params`` (low, high); ``"normal"``: (mean, standard deviation)), in the field's units."""

    field: str
    text: str
    values: tuple[Any, ...] = ()
    distribution: str | None = None
    params: tuple[float, float] = (0.0, 0.0)

    @property
    def is_distribution(self) -> bool:
        return self.distribution is not None

    @property
    def representative(self) -> Any:
        """A value standing for the variation when the sweep is checked: the first of a grid or list,
        a distribution's centre."""
        if self.distribution is None:
            return self.values[0]
        a, b = self.params
        return (a + b) / 2 if self.distribution == "uniform" else a

    def draw(self, rng: np.random.Generator) -> float:
        """One sample of the distribution."""
        a, b = self.params
        return float(rng.uniform(a, b) if self.distribution == "uniform" else rng.normal(a, b))

    def describe(self) -> str:
        """``0:5:6 (6 values)``, ``normal(10, 3)``: for summaries."""
        if self.distribution is not None:
            return f"{self.distribution}({self.params[0]:g}, {self.params[1]:g})"
        return f"{self.text} ({len(self.values)} value{'s' if len(self.values) != 1 else ''})"


def parse_variation(item: str) -> Variation:
    """``"FIELD=VALUES"`` (see the module) -> :class:`Variation`; ConfigError naming ``--vary``, the field
    and what was given when it is malformed. Whether FIELD exists is checked against the target later."""
    field, sep, text = item.partition("=")
    field = field.strip()
    if not sep or not field or any(not part for part in field.split(".")):
        raise ConfigError(f"expected FIELD=VALUES, VALUES {FORMS}", source="--vary", value=item)
    text = text.strip()
    call = _CALL.match(text)
    if call:
        return _distribution(field, text, call.group(1), call.group(2))
    if text.startswith("["):
        return _list(field, text)
    if "," in text:
        return _list(field, f"[{text}]", text)
    if ":" in text:
        return _grid(field, text)
    raise ConfigError(f"expected {FORMS} (a single value is a --set)", source="--vary", field=field, value=text)


def _number(text: str, field: str, whole: str, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise ConfigError(f"{what} must be a finite number", source="--vary", field=field, value=whole)
    return value


def _grid(field: str, text: str) -> Variation:
    parts = text.split(":")
    if len(parts) != 3:
        raise ConfigError("a grid is a:b:n (from a to b in n evenly spaced values)", source="--vary", field=field,
                          value=text)
    start = _number(parts[0], field, text, "a grid's start")
    stop = _number(parts[1], field, text, "a grid's end")
    count = _number(parts[2], field, text, "a grid's number of values")
    if count != int(count) or count < 2:
        raise ConfigError("a grid's number of values must be a whole number, 2 or more (a list [a] for one)",
                          source="--vary", field=field, value=text)
    values = tuple(float(v) for v in np.linspace(start, stop, int(count)))
    return Variation(field, text, values=values)


def _list(field: str, text: str, given: str | None = None) -> Variation:
    """The list ``text`` (YAML ``[a, b, ...]``), as the user gave it (``given``: ``a,b,...``)."""
    given = text if given is None else given
    try:
        values = load_yaml_text(text)
    except yaml.YAMLError:
        values = None
    if not isinstance(values, list) or not values:
        raise ConfigError("a list is a,b,... or [a, b, ...] with one value or more", source="--vary", field=field,
                          value=given)
    for value in values:
        if isinstance(value, (dict, list)) or value is None or (isinstance(value, float) and not math.isfinite(value)):
            raise ConfigError("a list's values must be finite numbers, true/false or words", source="--vary",
                              field=field, value=given)
    return Variation(field, given, values=tuple(values))


def _distribution(field: str, text: str, name: str, arguments: str) -> Variation:
    if name not in DISTRIBUTIONS:
        raise ConfigError(unknown_field_message(name, DISTRIBUTIONS).replace("unknown field", "unknown distribution"),
                          source="--vary", field=field, value=text)
    parts = arguments.split(",")
    if len(parts) != 2:
        raise ConfigError(f"{name} takes two numbers: " + ("uniform(a, b)" if name == "uniform" else
                                                           "normal(mu, sigma)"), source="--vary", field=field,
                          value=text)
    a = _number(parts[0], field, text, f"{name}'s first argument")
    b = _number(parts[1], field, text, f"{name}'s second argument")
    if name == "uniform" and not b > a:
        raise ConfigError("uniform(a, b) needs a < b", source="--vary", field=field, value=text)
    if name == "normal" and not b > 0:
        raise ConfigError("normal(mu, sigma) needs a positive sigma", source="--vary", field=field, value=text)
    return Variation(field, text, distribution=name, params=(a, b))


def variations_from(items: Iterable[str | Variation]) -> tuple[Variation, ...]:
    """Parse ``--vary`` items (or take Variations as they are); refuse an empty sweep and a field varied twice."""
    found = tuple(item if isinstance(item, Variation) else parse_variation(item) for item in items)
    if not found:
        raise ConfigError("nothing to vary: give one --vary FIELD=VALUES or more", field="--vary")
    fields = [v.field for v in found]
    for k, field in enumerate(fields):
        if field in fields[:k]:
            raise ConfigError("is varied twice", source="--vary", field=field, value=found[k].text)
    for variation in found:
        check_field_name(variation.field)
    # A grid of latencies is of whole cycles (2.0 is 2; a 0.5 stays, for the target's check to refuse).
    return tuple(Variation(v.field, v.text, values=tuple(int(x) if isinstance(x, float) and x == int(x) else x
                                                          for x in v.values))
                 if v.field == LATENCY and not v.is_distribution else v for v in found)


def check_field_name(field: str) -> None:
    """Refuse a FIELD that is no scenario field (and a ``noise.*`` that is none of its fields), with the nearest
    known name. (``model.*`` names are checked against the robot, other fields below the top by the scenario.)"""
    top, _, below = field.partition(".")
    noise = [f"noise.{name}" for name in NOISE_FIELDS]
    if top not in SCENARIO_FIELDS:
        known = sorted({*SCENARIO_FIELDS, *noise, "model.LINK_OR_JOINT.FIELD"} - {"noise", "model"})
        raise ConfigError(unknown_field_message(field, known), source="--vary", field=field)
    if top == "noise" and below not in NOISE_FIELDS:
        raise ConfigError(unknown_field_message(field, noise), source="--vary", field=field)


def check_samples(samples: int | None, seed: int, variations: Sequence[Variation]) -> int:
    """The draws per grid point: ``samples``, required (1 or more) when a distribution is varied, default 1."""
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ConfigError("must be a whole number, 0 or more", field="--seed", value=seed)
    if samples is None:
        if any(v.is_distribution for v in variations):
            raise ConfigError("a distribution needs the number of samples to draw", field="--samples")
        return 1
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
        raise ConfigError("must be a whole number, 1 or more", field="--samples", value=samples)
    return samples


def expand(variations: Sequence[Variation], samples: int, seed: int) -> list[dict[str, Any]]:
    """Every run's values, in run order: the grids' full factorial (the first variation slowest), each
    grid point with ``samples`` draws of the distributions (draw k seeded with (seed, k)). Each dict
    has the variations' fields in their order."""
    grids = [v for v in variations if not v.is_distribution]
    distributions = [v for v in variations if v.is_distribution]
    draws = []
    for k in range(samples):
        rng = np.random.default_rng([seed, k])
        draws.append({v.field: _as_drawn(v.field, v.draw(rng)) for v in distributions})
    runs = []
    for combination in itertools.product(*(g.values for g in grids)):
        point = dict(zip((g.field for g in grids), combination))
        for k in range(samples):
            values = {**point, **draws[k]}
            runs.append({v.field: values[v.field] for v in variations})
    return runs


def _as_drawn(field: str, value: float) -> float | int:
    """A draw as the run uses it: a latency rounded to the nearest whole cycle."""
    return int(round(value)) if field == LATENCY else value


def noise_seed(seed: int, index: int) -> tuple[int, int, int]:
    """The seed of run ``index``'s sensor noise (a stream apart from the distributions' draws; index -1 is the
    sweep's check of its target, before the runs)."""
    return (seed, index + 1, 1)


def yaml_text(value: Any) -> str:
    """``value`` as the YAML a ``--set`` reads back as the same value."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    return json.dumps(str(value))


__all__ = ["DISTRIBUTIONS", "FORMS", "LATENCY", "MODEL_PREFIX", "NOISE_POSITION", "NOISE_VELOCITY", "PAYLOAD",
           "Variation", "check_field_name", "check_samples", "expand", "noise_seed",
           "parse_variation", "variations_from", "yaml_text"]
