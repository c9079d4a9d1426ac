"""The package version, on the ground floor so that checkpoint writers can record it without
importing the package's face (``trumans/__init__``)."""

__version__ = "0.1.0"
