"""The package version (one place; ``gatetwin.__version__`` re-exports it)."""

__version__ = "0.1.0"
