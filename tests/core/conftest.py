"""The core's tests run on virtual time: an event loop whose clock jumps to the next timer
when every task waits (serveur.replay.vtime, after trio's autojump clock).

A robot driving to a table, a table timeout of three minutes, a hand-over after two: each costs
the CPU time of the frames exchanged, not seconds of wall time, and no test waits on the
wall clock for something that is a matter of rules. Sockets stay real (loopback: a frame sent
is readable by its peer before ``send`` returns); SQLite's thread holds time still while a
query runs.

The loop factory and the store's hold on time live in tests/conftest.py, which lists the
folders and modules that run on virtual time.
"""
