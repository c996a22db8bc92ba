"""jointctl: joint-level robot control on a simulated or real robot.

Layers, lowest first: ``model`` (URDF/xacro -> RobotModel), ``sim`` (RobotModel
-> MuJoCo world), ``hardware`` (joint state and command handles), ``control``
(PID and ros_control-style controllers), ``runtime`` (the deterministic loop),
then the edges: ``tools`` (command sources, recorder, analysis, figures),
``scenario`` (experiments assembled from files) and ``cli``.

Importing the package first puts the environment's own site-packages ahead of a system
dist-packages directory on PYTHONPATH (:mod:`jointctl.python_path`): before any module of it imports numpy.
"""

from jointctl.python_path import prefer_environment

prefer_environment()

__version__ = "0.1.0"
