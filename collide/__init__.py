"""collide: when, where and for how long do triangle meshes touch along rigid-body trajectories.

Pipeline (one module per stage): load -> bvh -> broad -> narrow -> contacts -> output,
wired by pipeline.py. Public API::

    import collide
    result = collide.scan("meshes/", "traj.h5", mode="discrete")
    result.contacts                     # dict of numpy columns
    collide.read_contacts("contacts.h5")

``import collide`` is light: the engine (numba, h5py, trimesh) is imported on first
use of ``scan``, ``ScanResult``, ``read_contacts`` or ``write_contacts`` (PEP 562), so
that ``collide --help`` and shell completion start quickly.
"""
import importlib as _importlib
import importlib.util as _importlib_util

from ._version import __version__
from .errors import CollideError, InputError, UsageError

#: public names imported on first use -> the submodule that defines them
_LAZY = {"scan": "pipeline", "ScanResult": "result",
         "read_contacts": "output", "write_contacts": "output"}

__all__ = ["__version__", "scan", "ScanResult", "read_contacts", "write_contacts",
           "CollideError", "InputError", "UsageError"]


def __getattr__(name):
    """The lazy public names, and submodules not imported yet (``collide.ccd``)."""
    module = _LAZY.get(name)
    if module is not None:
        value = getattr(_importlib.import_module(f"{__name__}.{module}"), name)
        globals()[name] = value  # later look-ups skip this function
        return value
    if (name.isidentifier() and not name.startswith("__")
            and _importlib_util.find_spec(f"{__name__}.{name}") is not None):
        return _importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
