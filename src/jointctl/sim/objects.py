"""Rigid objects spawned into the world at a given time, like Gazebo's ``spawn_model``.

An :class:`ObjectSpec` is a free-floating body: a cylinder (axis along its
local z), box or sphere with a mass, an initial pose in the world frame and,
unless given, the inertia of a solid body of that shape. Sizes in metres,
mass in kg, inertia in kg·m² about the centre of mass.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from jointctl.errors import ConfigError

SHAPES = ("cylinder", "box", "sphere")


@dataclass(frozen=True)
class ObjectSpec:
    """A rigid body to add to the world at ``spawn_at_s`` seconds of loop time.

    ``size_m`` is (radius, length) for a cylinder, (x, y, z) full lengths for a
    box and (radius,) for a sphere. ``xyz``/``rpy`` place its centre in the world.
    """

    name: str
    shape: str
    size_m: tuple[float, ...]
    mass_kg: float
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia: tuple[float, float, float] | None = None
    spawn_at_s: float = 0.0
    friction: float = 1.0

    @property
    def principal_inertia(self) -> tuple[float, float, float]:
        """(ixx, iyy, izz) about the centre of mass in the body frame [kg·m²]."""
        if self.inertia is not None:
            return self.inertia
        return solid_inertia(self.shape, self.size_m, self.mass_kg)

    @property
    def half_height_m(self) -> float:
        """Half the body's vertical extent when placed upright (rpy = 0) [m]."""
        if self.shape == "cylinder":
            return self.size_m[1] / 2
        if self.shape == "box":
            return self.size_m[2] / 2
        return self.size_m[0]

    @property
    def mujoco_size(self) -> list[float]:
        if self.shape == "cylinder":
            return [self.size_m[0], self.size_m[1] / 2, 0.0]
        if self.shape == "box":
            return [s / 2 for s in self.size_m]
        return [self.size_m[0], 0.0, 0.0]


def solid_inertia(shape: str, size: tuple[float, ...], mass: float) -> tuple[float, float, float]:
    """Principal moments of a homogeneous solid [kg·m²]."""
    if shape == "cylinder":
        r, length = size
        side = mass * (3 * r * r + length * length) / 12
        return (side, side, mass * r * r / 2)
    if shape == "box":
        x, y, z = size
        return (mass * (y * y + z * z) / 12, mass * (x * x + z * z) / 12, mass * (x * x + y * y) / 12)
    r = size[0]
    moment = 2 * mass * r * r / 5
    return (moment, moment, moment)


_SIZE_KEYS = {"cylinder": ("radius_m", "length_m"), "box": ("size_m",), "sphere": ("radius_m",)}
_COMMON_KEYS = {"name", "shape", "mass_kg", "xyz", "rpy", "inertia", "spawn_at_s", "friction"}


def object_from_config(config: Any, *, field: str, source: str | None, floor: bool) -> ObjectSpec:
    """Read one entry of a scenario's ``objects`` list; errors name ``field.<key>``."""

    def error(message: str, key: str | None = None, value: Any = None, with_value: bool = True):
        where = f"{field}.{key}" if key else field
        if with_value:
            return ConfigError(message, source=source, field=where, value=value)
        return ConfigError(message, source=source, field=where)

    if not isinstance(config, Mapping):
        raise error("must be a mapping describing an object", value=config)

    def number(key: str, value: Any, *, positive: bool = False, minimum: float | None = None) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise error("must be a finite number", key, value)
        if positive and value <= 0:
            raise error("must be positive", key, value)
        if minimum is not None and value < minimum:
            raise error(f"must be at least {minimum}", key, value)
        return float(value)

    def vector(key: str, default=None, *, positive: bool = False) -> tuple[float, ...]:
        value = config.get(key, default)
        if value is None:
            raise error("is required", key, with_value=False)
        if not isinstance(value, (list, tuple)) or len(value) != 3:
            raise error("must be a list of three numbers", key, value)
        return tuple(number(f"{key}[{k}]", v, positive=positive) for k, v in enumerate(value))

    shape = config.get("shape")
    if shape not in SHAPES:
        raise error(f"must be one of {', '.join(SHAPES)}", "shape", shape)
    allowed = _COMMON_KEYS | set(_SIZE_KEYS[shape])
    for key in config:
        if key not in allowed:
            raise error(f"unknown field for a {shape} (known: {', '.join(sorted(allowed))})", str(key),
                        config[key])
    name = config.get("name")
    if not isinstance(name, str) or not name.isidentifier():
        raise error("must be a name made of letters, digits and underscores", "name", name)
    def required(key: str) -> Any:
        if key not in config:
            raise error("is required", key, with_value=False)
        return config[key]

    if shape == "box":
        size = vector("size_m", positive=True)
    else:
        size = tuple(number(k, required(k), positive=True) for k in _SIZE_KEYS[shape])
    mass = number("mass_kg", required("mass_kg"), positive=True)
    inertia = None
    if "inertia" in config:
        inertia = vector("inertia", positive=True)
        a, b, c = sorted(inertia)
        if a + b < c * (1 - 1e-9):
            raise error("principal moments must satisfy the triangle inequality (a + b >= c)",
                        "inertia", list(inertia))
    spec = ObjectSpec(
        name=name, shape=shape, size_m=size, mass_kg=mass, xyz=vector("xyz"),
        rpy=vector("rpy", (0.0, 0.0, 0.0)), inertia=inertia,
        spawn_at_s=number("spawn_at_s", config.get("spawn_at_s", 0.0), minimum=0.0),
        friction=number("friction", config.get("friction", 1.0), positive=True),
    )
    if floor and spec.xyz[2] - _lowest_extent(spec) < 0:
        raise error("the object would start below the ground (z = 0)", "xyz", list(spec.xyz))
    return spec


def _lowest_extent(spec: ObjectSpec) -> float:
    """How far the object reaches below its centre, for any orientation (a bounding sphere
    unless upright)."""
    if spec.rpy == (0.0, 0.0, 0.0):
        return spec.half_height_m
    return float(np.linalg.norm(spec.mujoco_size)) if spec.shape != "sphere" else spec.size_m[0]
