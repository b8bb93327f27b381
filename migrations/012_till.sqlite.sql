-- 012 till (SQLite): orders from the restaurant's till (issue 33).
--
--  * till_job: a print job as the point of sale sent it to serveur's printer port (its bytes,
--    kept whole), or an order-intake API request; whether it reached the kitchen printer;
--  * till_ticket: each ticket of a job (a job may hold several, split at the cuts), as it
--    printed, what the owner's pattern read on it and what became of it: 'ordered' (its
--    dishes are orders), 'reprint' (a ticket already ordered, printed again: of_ticket),
--    'void' (it withdrew dishes), 'unread' (not understood: staff see it as printed),
--    'by_hand' (staff added its dishes themselves); first_key: the key of the first ticket
--    that ordered (or voided), UNIQUE: the database itself makes a ticket order once;
--  * till_name: the till's name for an item -> the dish on serveur's menu;
--  * till_setting: the printer port, the kitchen printer to forward to, the printer's code
--    page, the ticket pattern (one row each, the value as JSON);
--  * orders.ticket_id: the ticket a dish came from (the kitchen screen groups by it).

CREATE TABLE till_job (
    id           INTEGER PRIMARY KEY,
    received_at  REAL NOT NULL,
    source       TEXT NOT NULL,
    raw          BLOB NOT NULL,
    forwarded    INTEGER CHECK (forwarded IS NULL OR forwarded IN (0, 1))
) STRICT;

CREATE TABLE till_ticket (
    id           INTEGER PRIMARY KEY,
    job_id       INTEGER NOT NULL REFERENCES till_job (id),
    part         INTEGER NOT NULL DEFAULT 0,
    received_at  REAL NOT NULL,
    text         TEXT NOT NULL,
    status       TEXT NOT NULL DEFAULT 'unread'
                     CHECK (status IN ('unread', 'ordered', 'reprint', 'void', 'by_hand')),
    `key`        TEXT,
    first_key    TEXT UNIQUE,
    table_name   TEXT,
    reading      TEXT CHECK (reading IS NULL OR json_valid(reading)),
    problem      TEXT,
    of_ticket    INTEGER REFERENCES till_ticket (id),
    read_at      REAL,
    handled_by   TEXT
) STRICT;

CREATE INDEX till_ticket_key ON till_ticket (`key`);
CREATE INDEX till_ticket_status ON till_ticket (status, id);

CREATE TABLE till_name (
    pos_name     TEXT PRIMARY KEY NOT NULL CHECK (length(pos_name) > 0),
    dish         TEXT NOT NULL CHECK (length(dish) > 0),
    updated_at   REAL NOT NULL
) STRICT;

CREATE TABLE till_setting (
    name         TEXT PRIMARY KEY NOT NULL CHECK (length(name) > 0),
    value        TEXT NOT NULL CHECK (json_valid(value)),
    updated_at   REAL NOT NULL,
    updated_by   TEXT
) STRICT;

ALTER TABLE orders ADD COLUMN ticket_id INTEGER REFERENCES till_ticket (id);
