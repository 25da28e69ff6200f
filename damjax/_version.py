"""The package version (a leaf, so that any module can name it without importing damjax)."""

__version__ = "0.1.0"
