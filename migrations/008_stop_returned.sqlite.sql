-- 008 stop returned (SQLite): the dishes a skipped stop carried (issue 26).
--
-- A stop's dishes are the trip's orders for its table (orders.task_num, see 001_init). A stop
-- left unserved (staff's skip, the table's timeout, its trip cancelled) sends its dishes back to
-- the pass, off the trip, so it listed none: the trip's history no longer said what the robot
-- carried to that table. returned keeps those ids (a JSON array), written when the stop is
-- skipped; the dishes themselves are returned or pending again, with no trip.

ALTER TABLE task_stop ADD COLUMN returned TEXT NOT NULL DEFAULT '[]' CHECK (json_valid(returned));
