"""A simulated industrial robot controller: the robot in MuJoCo behind ROS-Industrial's simple_message
(the motion program, its interpolator, and the server application ``jointctl controller``)."""
