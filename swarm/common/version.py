"""The package's version, for messages between hosts and the run's summary."""

__version__ = "0.1.0"
