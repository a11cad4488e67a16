"""The notchfit version (one place: ``notchfit.__version__`` re-exports it)."""

__version__ = "0.1.0"
