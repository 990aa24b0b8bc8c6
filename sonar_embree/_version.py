"""The package version (one place; read by setup.cfg and the file writers)."""
__version__ = "0.1.0"
