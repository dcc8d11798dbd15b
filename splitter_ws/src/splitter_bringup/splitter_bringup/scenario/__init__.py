"""Scenarios: the scenario files, their variants and the paper's numbers, and the node graph
and parameter files a scenario sets up (ROS-free)."""
