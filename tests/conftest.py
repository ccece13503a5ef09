"""Test-wide settings: Hypothesis never times an example against the wall clock (a loaded CI machine would fail
tests that are right); each test still bounds its examples with ``max_examples``."""

from hypothesis import settings

settings.register_profile("flyby", deadline=None)
settings.load_profile("flyby")
