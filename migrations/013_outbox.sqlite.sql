-- 013 outbox (SQLite): every event numbered for the chain's central dashboard (issue 34).
--
--  * outbox: one row per ``events`` row, written in the event's own transaction
--    (serveur.store.rows.add_event) with the site's next sequence number: gapless and in
--    commit order, so the centre can tell "all of them, in order" from "one is missing".
--    Rows go only after the centre confirmed them and a retention period passed
--    (serveur.store.outbox); the events themselves stay (statistics read them);
--  * outbox_state: one row: ``head`` the last number given, ``sent`` the last the broker
--    acknowledged (the shipper resumes after it), ``confirmed`` the last the centre stored.
--
-- The events already recorded are numbered in id order, so a site that joins a chain ships
-- its whole history once.

CREATE TABLE outbox (
    seq       INTEGER PRIMARY KEY CHECK (seq > 0),
    event_id  INTEGER NOT NULL UNIQUE,
    at        REAL NOT NULL
) STRICT;

CREATE TABLE outbox_state (
    id         INTEGER PRIMARY KEY CHECK (id = 1),
    head       INTEGER NOT NULL CHECK (head >= 0),
    sent       INTEGER NOT NULL DEFAULT 0 CHECK (sent >= 0),
    sent_at    REAL,
    confirmed  INTEGER NOT NULL DEFAULT 0 CHECK (confirmed >= 0)
) STRICT;

INSERT INTO outbox (seq, event_id, at)
    SELECT ROW_NUMBER() OVER (ORDER BY id), id, ts FROM events;

INSERT INTO outbox_state (id, head) SELECT 1, COUNT(*) FROM events;
