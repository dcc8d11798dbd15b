"""ROS-free algorithm core of splitter_mpc: never imports rclpy."""
