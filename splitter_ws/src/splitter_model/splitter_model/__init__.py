"""The one SPLITTER model every layer shares (ROS-free, never imports rclpy).

* :mod:`.model`: masses, geometry, principal inertia <-> radii, tether tension,
  gravity names (:class:`~splitter_model.model.RobotModel`, paper Table I).
* :mod:`.kinematics`: limb forward/inverse kinematics, joint positions <-> radii.
* :mod:`.actuators`: the actuator limits derived from the model.
"""
