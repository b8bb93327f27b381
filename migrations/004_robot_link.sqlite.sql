-- 004 robot_link (SQLite): how the server reaches a robot's ROS graph beyond its URL.
--
-- A JSON object of the robot's link options (serveur.robots.names: a namespace, renamed topics,
-- the move_base action, the map frame); '{}' means the default names. Real robots on one ROS
-- master are namespaced (/r1/move_base), so the options must survive a restart with the robot.

ALTER TABLE robot_info ADD COLUMN link TEXT NOT NULL DEFAULT '{}';
