"""ROS nodes of the bringup package that are tools of the graph (the graph watchdog)."""
