"""The software version, recorded in every recording and calibration file."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("flexvox")
except PackageNotFoundError:  # running from a source tree that was not installed
    __version__ = "0.0.0+unknown"
