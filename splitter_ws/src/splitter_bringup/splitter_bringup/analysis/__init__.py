"""Analysis of runs (ROS-free): time series, metrics, jump metrics, campaigns, replay
accounting, graph progress, actuator sizing."""
