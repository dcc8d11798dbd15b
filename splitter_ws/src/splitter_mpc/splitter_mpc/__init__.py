"""SPLITTER inertial-morphing MPC and gait phase manager."""
