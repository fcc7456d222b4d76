"""ChakaMo's estimators: pure numerics (numpy, scipy, numba), no I/O, no web, no file paths."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("chakamo")
except PackageNotFoundError:  # running from a source tree that was not installed
    __version__ = "0.0.0+source"
