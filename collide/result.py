"""What a scan found, in memory: the same type from ``collide.scan`` and ``collide.read_contacts``."""
from dataclasses import dataclass, field

import numpy as np


@dataclass
class ScanResult:
    """A scan's result (or a contacts file's content).

    ``contacts`` and ``triangle_pairs`` (None unless scanned with --triangle-pairs; also
    None when a scan with ``output`` streamed them into that file to keep memory bounded:
    read_contacts(output) has them)
    are dicts of numpy columns, as in the file's contacts/ and triangle_pairs/ groups;
    object_* describe the objects (trajectory order, then static meshes), frame_time
    float64 (T,) the analysed frame times and frame_index int64 (T,) their indices in
    the trajectory. ``stats`` (timings, work counts) exists only for a fresh scan.
    """
    object_names: list
    object_meshes: list
    object_triangles: np.ndarray
    frame_time: np.ndarray
    frame_index: np.ndarray
    contacts: dict
    triangle_pairs: dict
    mode: str
    interpolation: str
    provenance: dict
    versions: dict
    stats: dict = field(default_factory=dict)
    attrs: dict = field(default_factory=dict)   #: the file's attributes (read results)

    @property
    def objects(self):
        """{"name": list, "mesh": list, "triangles": int64 (N,)}: the file's objects/ group."""
        return {"name": self.object_names, "mesh": self.object_meshes, "triangles": self.object_triangles}

    def to_dataframe(self, what="contacts"):
        """A pandas DataFrame of the contacts (what="contacts") or of the triangle pairs
        ("triangle-pairs"), with the objects' names in columns ``a`` and ``b`` next to
        their indices. Needs pandas (``pip install pandas``)."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("to_dataframe needs pandas: pip install pandas") from None
        if what == "contacts":
            columns = self.contacts
        elif what == "triangle-pairs":
            if self.triangle_pairs is None:
                raise ValueError("this result has no triangle pairs (scan with triangle_pairs=True; with "
                                 "output=, read them back with collide.read_contacts)")
            columns = self.triangle_pairs
        else:
            raise ValueError(f"what={what!r}: expected 'contacts' or 'triangle-pairs'")
        frame = pd.DataFrame({name: np.asarray(column) for name, column in columns.items()})
        names = np.asarray(self.object_names, dtype=object)
        frame.insert(0, "b", names[frame["object_b"].to_numpy()] if len(frame) else np.zeros(0, object))
        frame.insert(0, "a", names[frame["object_a"].to_numpy()] if len(frame) else np.zeros(0, object))
        if what == "triangle-pairs":
            frame.insert(2, "time", self.frame_time[frame["frame"].to_numpy()] if len(frame) else np.zeros(0))
        return frame

    @classmethod
    def from_file(cls, contacts, objects, frame_time, frame_index, triangle_pairs, attrs, provenance):
        """The result of a contacts file's groups (see output.read_contacts)."""
        versions = provenance.get("versions", {})  # parsed from JSON by read_contacts
        return cls(object_names=list(objects["name"]), object_meshes=list(objects["mesh"]),
                   object_triangles=np.asarray(objects["triangles"]), frame_time=frame_time,
                   frame_index=frame_index, contacts=contacts, triangle_pairs=triangle_pairs,
                   mode=str(attrs.get("mode", "")), interpolation=str(attrs.get("interpolation", "")),
                   provenance=provenance, versions=versions if isinstance(versions, dict) else {}, attrs=attrs)
