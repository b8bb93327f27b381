"""Talking to robots: the rosbridge v2 wire, and a link per kind of robot.

Owns :mod:`~serveur.robots.rosbridge` (rosbridge ops and ROS message JSON, pure; shared with
the simulator so both ends build the same frames), :mod:`~serveur.robots.names` (a robot's
topic names, move_base action and map frame, from its registration options),
:mod:`~serveur.robots.driver` (the robot-driver interface the core talks to),
:mod:`~serveur.robots.deadman` (the joystick's dead man's switch every driver uses),
:mod:`~serveur.robots.liveness` (what proves a robot alive, when its goal is lost: the one
tracker both links use, pure), :mod:`~serveur.robots.reconnect` (their reconnect loop),
:mod:`~serveur.robots.sensing` (a pose's spread, the particle cloud, tf composed: pure) and
:mod:`~serveur.robots.sensor_reports` (the sensor topics both links read, handled once), the
camera sources :mod:`~serveur.robots.camera` (a CompressedImage over rosbridge) and
:mod:`~serveur.robots.mjpeg` (web_video_server's MJPEG over HTTP) with their reconnect loop
:mod:`~serveur.robots.camera_retry`, its two
implementations :mod:`serveur.robots.ros1` (move_base and AMCL) and :mod:`serveur.robots.ros2`
(Nav2 over rosbridge 2.x), and :mod:`~serveur.robots.factory` (which one a robot gets).
Nothing here knows about trips, orders or clients: the core listens to a link's reports and
tells it where to go.

May import: serveur.clock.
"""

__all__: list[str] = []
