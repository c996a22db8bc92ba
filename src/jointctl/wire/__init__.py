"""Wire formats: pure codecs (no I/O) that hardware and the edges speak, such as ROS-Industrial's simple_message."""
