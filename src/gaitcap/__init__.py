"""gaitcap: markerless 3D gait analysis from two or more calibrated cameras."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("gaitcap")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+src"

__all__ = ["__version__"]
