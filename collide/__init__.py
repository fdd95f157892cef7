"""collide: when, where and for how long do triangle meshes touch along rigid-body trajectories.

Pipeline (one module per stage): load -> bvh -> broad -> narrow -> contacts -> output,
wired by pipeline.py. Public API::

    import collide
    result = collide.scan("meshes/", "traj.h5", mode="discrete")
    result.contacts                     # dict of numpy columns (SPEC §4)
    collide.read_contacts("contacts.h5")
"""
from ._version import __version__
from .errors import CollideError, InputError, UsageError
from .output import read_contacts, write_contacts
from .pipeline import ScanResult, scan

__all__ = ["__version__", "scan", "ScanResult", "read_contacts", "write_contacts",
           "CollideError", "InputError", "UsageError"]
