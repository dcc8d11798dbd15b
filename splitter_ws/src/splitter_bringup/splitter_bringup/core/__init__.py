"""ROS-free algorithm core of splitter_bringup: never imports rclpy."""
