"""ROS-free algorithm core of splitter_sim: never imports rclpy."""
