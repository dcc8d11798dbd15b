"""SPLITTER IK / tether allocator and actuator sizing."""
