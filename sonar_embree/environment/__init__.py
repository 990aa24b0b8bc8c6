"""The medium: :class:`Environment`, its absorption models and sound-speed profiles (their ray map; the
renderer does not cast curved rays yet)."""
from .medium import ABSORPTION_MODELS, Environment
from .noise import AmbientNoise
from .profile import SoundSpeedProfile
from .surface import SeaSurface

__all__ = ["ABSORPTION_MODELS", "AmbientNoise", "Environment", "SeaSurface", "SoundSpeedProfile"]
