"""Robot descriptions: URDF / xacro in, a :class:`RobotModel` out."""

from jointctl.model.robot_model import (
    Geometry,
    Inertial,
    Joint,
    JointLimits,
    Link,
    Pose,
    RobotModel,
    SensorSpec,
    Shape,
    Transmission,
)
from jointctl.model.loader import load_robot_model

__all__ = [
    "Geometry",
    "Inertial",
    "Joint",
    "JointLimits",
    "Link",
    "Pose",
    "RobotModel",
    "SensorSpec",
    "Shape",
    "Transmission",
    "load_robot_model",
]
