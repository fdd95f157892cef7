"""Slow, obviously correct references in exact rational arithmetic (fractions.Fraction).

Every float64 is a rational number, so converting inputs with Fraction and computing
exactly gives the true answer for the float inputs, with no rounding anywhere.
"""
from fractions import Fraction
from itertools import combinations

import numpy as np


def exact(points):
    """(k, 3) floats -> list of k tuples of Fractions (exact)."""
    return [tuple(Fraction(float(x)) for x in p) for p in np.asarray(points, dtype=np.float64)]


def sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def det3(a, b, c):
    return dot(a, cross(b, c))


def sign(x):
    return (x > 0) - (x < 0)


def orient3d_exact(a, b, c, d):
    """Sign of det[a-d; b-d; c-d] for float points (the convention of collide.predicates)."""
    a, b, c, d = exact([a, b, c, d])
    return sign(det3(sub(a, d), sub(b, d), sub(c, d)))


def orient2d_exact(ax, ay, bx, by, cx, cy):
    ax, ay, bx, by, cx, cy = (Fraction(float(v)) for v in (ax, ay, bx, by, cx, cy))
    return sign((ax - cx) * (by - cy) - (ay - cy) * (bx - cx))


def _origin_in_simplex(pts):
    """Origin lies in the closed simplex of these 1-4 affinely independent points;
    None if they are affinely dependent (a smaller subset then covers the case)."""
    zero = (0, 0, 0)
    if len(pts) == 1:
        return pts[0] == zero
    if len(pts) == 2:
        a, b = pts
        if a == b:
            return None
        return cross(a, b) == zero and dot(a, b) <= 0
    if len(pts) == 3:
        a, b, c = pts
        n = cross(sub(b, a), sub(c, a))
        if n == zero:
            return None
        if det3(a, b, c) != 0:  # origin not in the plane
            return False
        s = [sign(dot(n, cross(p, q))) for p, q in ((a, b), (b, c), (c, a))]
        return min(s) >= 0 or max(s) <= 0
    a, b, c, d = pts
    volume = det3(sub(b, a), sub(c, a), sub(d, a))
    if volume == 0:
        return None
    o = zero
    parts = [det3(sub(b, o), sub(c, o), sub(d, o)), det3(sub(o, a), sub(c, a), sub(d, a)),
             det3(sub(b, a), sub(o, a), sub(d, a)), det3(sub(b, a), sub(c, a), sub(o, a))]
    return all(sign(p) * sign(volume) >= 0 for p in parts)


def triangles_intersect_exact(p, q):
    """Closed triangles p, q ((3, 3) float arrays) share a point, decided exactly.

    p and q meet iff some p_i-weighted point equals some q_j-weighted point, i.e. iff the
    origin lies in the convex hull of the 9 differences p_i - q_j (their Minkowski
    difference). By Carathéodory's theorem that holds iff the origin lies in a simplex
    spanned by at most 4 affinely independent differences: try them all. This shares no
    logic with collide's edge/plane predicates and covers every degenerate case.
    """
    p, q = np.asarray(p, dtype=np.float64), np.asarray(q, dtype=np.float64)
    if (p.max(axis=0) < q.min(axis=0)).any() or (q.max(axis=0) < p.min(axis=0)).any():
        return False  # exact: comparisons of the same floats
    diffs = list({sub(a, b) for a in exact(p) for b in exact(q)})
    for k in range(1, 5):
        for subset in combinations(diffs, k):
            if _origin_in_simplex(subset):
                return True
    return False
