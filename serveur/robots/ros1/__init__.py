"""The link to a ROS1 robot: move_base goals, AMCL poses, teleop, over rosbridge v2.

Owns :mod:`~serveur.robots.ros1.link` (:class:`~serveur.robots.ros1.link.RobotLink`: one
websocket client per robot, goals with acknowledgement, heartbeat, reconnect).

May import: serveur.clock, serveur.robots.rosbridge, serveur.robots.names,
serveur.robots.driver, serveur.robots.deadman, serveur.robots.reconnect,
serveur.robots.liveness, serveur.robots.sensor_reports.
"""

__all__: list[str] = []
