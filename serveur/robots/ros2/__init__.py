"""The link to a ROS 2 robot: Nav2's navigate_to_pose, AMCL poses, teleop, over rosbridge 2.x.

Owns :mod:`~serveur.robots.ros2.messages` (rosbridge 2.x action ops and ROS 2 message JSON,
pure) and :mod:`~serveur.robots.ros2.link` (:class:`~serveur.robots.ros2.link.Nav2Link`: a
control and a goal connection per robot, goals accepted by their feedback, heartbeat by rosapi
calls, reconnect).

May import: serveur.clock, serveur.robots.rosbridge, serveur.robots.names,
serveur.robots.driver, serveur.robots.deadman, serveur.robots.reconnect,
serveur.robots.liveness, serveur.robots.sensor_reports.
"""

__all__: list[str] = []
