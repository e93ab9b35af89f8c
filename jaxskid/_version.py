"""The package version (one place: the package, pyproject.toml and every generated file read it)."""

__version__ = "0.1.0"
