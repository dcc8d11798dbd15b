"""Run a scenario variant: the library loop, one process per node, every node in one process;
the launcher, the process supervisor, the recorded bag read back and the MPC replay."""
