"""Shared contract of the flyby emulator: bus keys, messages, scenario schema, clock and launcher."""
