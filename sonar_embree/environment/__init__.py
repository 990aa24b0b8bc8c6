"""The medium: :class:`Environment` and its absorption models (later: surface, profile)."""
from .medium import ABSORPTION_MODELS, Environment

__all__ = ["ABSORPTION_MODELS", "Environment"]
