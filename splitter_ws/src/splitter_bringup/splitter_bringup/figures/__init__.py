"""Figures of runs, campaigns and actuator sizing (PNG, matplotlib Agg; ROS-free)."""
