"""ROS-free algorithm core of splitter_ik: never imports rclpy."""
