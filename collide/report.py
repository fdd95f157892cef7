"""Contact files as rows for people and pipelines (``collide report``), and
comparison of two contact files (``collide diff``).

Rows name objects by name (``a``, ``b``) as well as by index.
"""
from typing import NamedTuple

from .contacts import KIND_LABELS

WHATS = ("contacts", "pairs", "triangle-pairs")

CONTACT_FIELDS = ("a", "b", "object_a", "object_b", "t_begin", "t_end", "duration", "frame_begin",
                  "frame_end", "kind", "tri_a", "tri_b", "point_x", "point_y", "point_z")
PAIR_FIELDS = ("a", "b", "object_a", "object_b", "intervals", "first_contact", "last_contact",
               "time_in_contact", "swept_only")
TRIANGLE_PAIR_FIELDS = ("frame", "time", "a", "b", "object_a", "object_b", "tri_a", "tri_b")


def fields(what):
    return {"contacts": CONTACT_FIELDS, "pairs": PAIR_FIELDS, "triangle-pairs": TRIANGLE_PAIR_FIELDS}[what]


def contact_rows(cf):
    """One dict per contact interval of a Contacts (output.read_contacts) file."""
    c = cf.contacts
    names = cf.objects["name"]
    for k in range(c["object_a"].shape[0]):
        a, b = int(c["object_a"][k]), int(c["object_b"][k])
        yield {"a": names[a], "b": names[b], "object_a": a, "object_b": b,
               "t_begin": float(c["t_begin"][k]), "t_end": float(c["t_end"][k]),
               "duration": float(c["t_end"][k] - c["t_begin"][k]),
               "frame_begin": int(c["frame_begin"][k]), "frame_end": int(c["frame_end"][k]),
               "kind": KIND_LABELS.get(int(c["kind"][k]), str(int(c["kind"][k]))),
               "tri_a": int(c["tri_a"][k]), "tri_b": int(c["tri_b"][k]),
               "point_x": float(c["point_x"][k]), "point_y": float(c["point_y"][k]),
               "point_z": float(c["point_z"][k])}


def pair_rows(cf):
    """One dict per object pair in contact: interval count, first/last contact, total time."""
    rows = {}
    for r in contact_rows(cf):
        key = (r["object_a"], r["object_b"])
        if key not in rows:
            rows[key] = {"a": r["a"], "b": r["b"], "object_a": key[0], "object_b": key[1], "intervals": 0,
                         "first_contact": r["t_begin"], "last_contact": r["t_end"], "time_in_contact": 0.0,
                         "swept_only": 0}
        p = rows[key]
        p["intervals"] += 1
        p["first_contact"] = min(p["first_contact"], r["t_begin"])
        p["last_contact"] = max(p["last_contact"], r["t_end"])
        p["time_in_contact"] += r["duration"]
        p["swept_only"] += r["kind"] == "swept"
    return [rows[k] for k in sorted(rows)]


def triangle_pair_rows(cf):
    """One dict per intersecting triangle pair per frame (files scanned with --triangle-pairs)."""
    p = cf.triangle_pairs
    names = cf.objects["name"]
    for k in range(p["frame"].shape[0]):
        a, b, f = int(p["object_a"][k]), int(p["object_b"][k]), int(p["frame"][k])
        yield {"frame": f, "time": float(cf.frame_time[f]), "a": names[a], "b": names[b], "object_a": a,
               "object_b": b, "tri_a": int(p["tri_a"][k]), "tri_b": int(p["tri_b"][k])}


# --- diff ------------------------------------------------------------------------------------

def scan_filters(cf):
    """The pair filters a contacts file was scanned with, as a JSON-able dict ({"ignore":
    [[a, b], ...], "only": [...]}); none for files from scans without filters."""
    parameters = cf.provenance.get("parameters", {})  # parsed from JSON by read_contacts
    filters = parameters.get("filters") if isinstance(parameters, dict) else None
    if not isinstance(filters, dict):
        filters = {}
    return {"ignore": filters.get("ignore", []), "only": filters.get("only", [])}


class Difference(NamedTuple):
    change: str          #: "appeared", "disappeared" or "moved"
    a: str
    b: str
    before: tuple        #: (t_begin, t_end) in the baseline, or None
    after: tuple         #: (t_begin, t_end) in the new file, or None

    def describe(self):
        def span(iv):
            return f"[{iv[0]:.9g}, {iv[1]:.9g}]"
        pair = f"{self.a} - {self.b}"
        if self.change == "appeared":
            return f"appeared:    {pair}: contact {span(self.after)}"
        if self.change == "disappeared":
            return f"disappeared: {pair}: contact {span(self.before)}"
        shift = (self.after[0] - self.before[0], self.after[1] - self.before[1])
        return (f"moved:       {pair}: {span(self.before)} -> {span(self.after)} "
                f"(t_begin {shift[0]:+.3g}, t_end {shift[1]:+.3g})")


def _intervals_by_pair(cf):
    out = {}
    for r in contact_rows(cf):
        key = tuple(sorted((r["a"], r["b"])))
        out.setdefault(key, []).append((r["t_begin"], r["t_end"]))
    return {k: sorted(v) for k, v in out.items()}


def _close(x, y, tol):
    return abs(x[0] - y[0]) <= tol and abs(x[1] - y[1]) <= tol


def diff_contacts(baseline, new, time_tol=0.0):
    """Differences between two contact files, matched by object names (not indices).

    Intervals of a pair are matched in time order: equal counts compare one to
    one (moved when a time differs by more than time_tol); otherwise intervals
    that overlap (within time_tol) are matched first and the rest appeared or
    disappeared. Returns a sorted list of Difference.
    """
    before, after = _intervals_by_pair(baseline), _intervals_by_pair(new)
    diffs = []
    for key in sorted(set(before) | set(after)):
        old, cur = before.get(key, []), after.get(key, [])
        if len(old) == len(cur):
            diffs += [Difference("moved", *key, x, y) for x, y in zip(old, cur) if not _close(x, y, time_tol)]
            continue
        unmatched = list(cur)
        for x in old:
            match = next((y for y in unmatched if y[0] <= x[1] + time_tol and x[0] <= y[1] + time_tol), None)
            if match is None:
                diffs.append(Difference("disappeared", *key, x, None))
                continue
            unmatched.remove(match)
            if not _close(x, match, time_tol):
                diffs.append(Difference("moved", *key, x, match))
        diffs += [Difference("appeared", *key, None, y) for y in unmatched]
    order = {"disappeared": 0, "appeared": 1, "moved": 2}
    return sorted(diffs, key=lambda d: (d.a, d.b, (d.before or d.after)[0], order[d.change]))


def timeline(cf):
    """Per pair label 'a - b': list of (t_begin, t_end, kind) for plotting."""
    out = {}
    for r in contact_rows(cf):
        out.setdefault(f"{r['a']} - {r['b']}", []).append((r["t_begin"], r["t_end"], r["kind"]))
    return out
