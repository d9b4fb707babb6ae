"""The package version: a leaf module, so any layer can stamp results without importing the face."""

__all__ = ["__version__"]

__version__ = "0.1.0"
