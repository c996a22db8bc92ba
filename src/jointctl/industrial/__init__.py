"""ROS-Industrial's simple_message: the codec, a simulated industrial controller, and the hardware
that drives one."""
