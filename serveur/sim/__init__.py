"""The simulator's parts: one robot's ROS graph, its rosbridge server, its physics.

Owns :mod:`~serveur.sim.robot` (move_base or Nav2, AMCL, odometry, laser, battery of one
robot: its construction, control cycle and physics step) and the parts the robot is made of,
each an object it creates and hands what it needs: :mod:`~serveur.sim.state` (what they share),
:mod:`~serveur.sim.outbox` (subscriptions and frames), :mod:`~serveur.sim.sensors` (what is
published, at which rates; :mod:`~serveur.sim.camera` renders what the camera sees),
:mod:`~serveur.sim.video_server` (web_video_server's MJPEG streams),
:mod:`~serveur.sim.navigator` (a goal's life and plan),
:mod:`~serveur.sim.inbox` (what clients send), :mod:`~serveur.sim.floor` (other robots) and
:mod:`~serveur.sim.docking` (a ROS 2 robot's docking server, and where its chargers are);
:mod:`~serveur.sim.bridge` (its rosbridge v2 server: ops, subscriptions, queues, and
rosbridge 2.x's action ops), :mod:`~serveur.sim.ros2` (the ROS 2 dialect's names and shapes),
:mod:`~serveur.sim.topics` (frames and subscriptions both share) and
:mod:`~serveur.sim.kinematics` (omni / differential drive, path following, odometry).
:mod:`serveur.robot_sim` assembles a fleet from these and is the simulator's entry.

May import: serveur.clock, serveur.maps.navigation, serveur.robots.rosbridge.
"""

__all__: list[str] = []
