"""Shared contracts of the three nodes: bus keys and messages, the TM/TC dictionary and its codec, CUC time,
the clock, seeding, errors and exit codes. It imports no node: every other package may import it."""
