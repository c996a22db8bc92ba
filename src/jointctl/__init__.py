"""jointctl: joint-level robot control on a simulated or real robot.

Layers, lowest first: ``model`` (URDF/xacro -> RobotModel), ``sim`` (RobotModel
-> MuJoCo world), ``hardware`` (joint state and command handles), ``control``
(PID and ros_control-style controllers), ``runtime`` (the deterministic loop),
then the edges: ``tools`` (command sources, recorder, analysis, figures),
``scenario`` (experiments assembled from files) and ``cli``.
"""

__version__ = "0.1.0"
