"""ROS-free algorithm core of splitter_msgs_py: never imports rclpy."""
