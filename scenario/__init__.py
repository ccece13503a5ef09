"""Scenarios: the file that fixes a run, the rules between its sections, and the composition of the three cores
from it (what the flight software knows, what the universe makes true, what ground believes)."""
