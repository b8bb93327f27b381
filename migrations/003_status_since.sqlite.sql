-- 003 status_since (SQLite): when each robot entered its current status.
--
-- ``updated_at`` moves with every pose the server saves, so it cannot say how long a robot has
-- been Offline; the hand-over of a trip after ``handover_after`` must count from the drop,
-- also across a server restart (serveur.core), and staff see "Offline for 3 min".
-- Existing rows start from their last update, the best guess there is.

ALTER TABLE robot_info ADD COLUMN status_since REAL NOT NULL DEFAULT 0;
UPDATE robot_info SET status_since = updated_at;
