"""collide: batch collision analysis of triangle meshes along rigid-body trajectories."""
from ._version import __version__
