"""Exception types of sonar_embree.

Every error raised for bad user input is a ``ValueError`` subclass whose message is
one line naming the offending file, key or value, so the CLI can print it as is.
"""


class SonarEmbreeError(ValueError):
    """Base class of the input errors raised by sonar_embree."""


class ConfigError(SonarEmbreeError):
    """An impossible parameter value or an unknown configuration key."""


class SceneError(SonarEmbreeError):
    """A mesh file that is missing, unreadable or geometrically unusable."""
