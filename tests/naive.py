"""A slow, obviously correct, EXACT reference for closed triangle-triangle intersection,
plus hand-made degenerate test cases whose answers are known by construction.

Exactness: every finite float64 is a dyadic rational, so ``Fraction(float)`` is an exact
conversion; all arithmetic below is done on exact rationals (or on integers obtained from
them by one exact common scaling), so no answer here is affected by rounding.

Nothing here uses the usual edge/plane (Moller / Guigue-Devillers) predicates: the
intersection test is the Minkowski-difference / Caratheodory characterisation, which is
independent of them and has no special cases for degenerate or coplanar input.
"""
from fractions import Fraction
from itertools import combinations
from math import lcm

import numpy as np

__all__ = [
    "to_fractions",
    "orient3d_exact",
    "orient2d_exact",
    "triangles_intersect_exact",
    "triangle_pairs_exact",
    "hand_cases",
    "hand_case_certificates",
    "random_near_degenerate_cases",
]


# --------------------------------------------------------------------------------------
# exact scalars and small vector helpers (work on ints and Fractions alike)
# --------------------------------------------------------------------------------------

def _exact(x):
    """One number -> Fraction, exactly (ints/Fractions as is, floats bit-exactly)."""
    if isinstance(x, (int, Fraction)) and not isinstance(x, bool):
        return Fraction(x)
    x = float(x)
    if not np.isfinite(x):
        raise ValueError(f"non-finite coordinate {x!r}")
    return Fraction(x)


def to_fractions(P):
    """(k, 3) float64 array -> list of k tuples of 3 Fractions, each float converted exactly."""
    A = np.asarray(P, dtype=np.float64)
    if A.ndim != 2 or A.shape[1] != 3:
        raise ValueError(f"expected a (k, 3) array, got shape {A.shape}")
    if not np.all(np.isfinite(A)):
        raise ValueError("non-finite coordinates")
    return [tuple(Fraction(float(x)) for x in row) for row in A]


def _sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def _dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0])


def _sign(x):
    return (x > 0) - (x < 0)


def _det(m):
    """Determinant of a 1x1, 2x2 or 3x3 matrix (list of rows), exactly."""
    n = len(m)
    if n == 1:
        return m[0][0]
    if n == 2:
        return m[0][0] * m[1][1] - m[0][1] * m[1][0]
    if n == 3:
        return _dot(m[0], _cross(m[1], m[2]))
    raise ValueError("only sizes 1..3 are needed")


def orient3d_exact(a, b, c, d):
    """Exact sign (-1, 0, +1) of det[b - a; c - a; d - a] (rows), i.e. of
    ((b - a) x (c - a)) . (d - a).

    Convention: +1 when d lies on the side of the plane (a, b, c) that the right-hand
    normal (b - a) x (c - a) points to, i.e. when a, b, c appear counter-clockwise seen
    from d; 0 when the four points are coplanar.  Example:
    orient3d_exact(0, e_x, e_y, e_z) == +1.  (This is MINUS Shewchuk's orient3d, which is
    det[a - d; b - d; c - d].)  Inputs: length-3 sequences of floats/ints/Fractions.
    """
    a, b, c, d = ([_exact(x) for x in p] for p in (a, b, c, d))
    return _sign(_det([_sub(b, a), _sub(c, a), _sub(d, a)]))


def orient2d_exact(a, b, c):
    """Exact sign (-1, 0, +1) of det[b - a; c - a] for 2-D points (length-2 sequences):
    +1 when a, b, c are counter-clockwise, -1 clockwise, 0 collinear."""
    a, b, c = ([_exact(x) for x in p] for p in (a, b, c))
    if not (len(a) == len(b) == len(c) == 2):
        raise ValueError("orient2d_exact takes 2-D points")
    return _sign(_det([_sub(b, a), _sub(c, a)]))


# --------------------------------------------------------------------------------------
# the exact intersection test
# --------------------------------------------------------------------------------------

def _as_triangle(T):
    T = np.asarray(T, dtype=np.float64)
    if T.shape != (3, 3):
        raise ValueError(f"a triangle is a (3, 3) array of vertices, got shape {T.shape}")
    if not np.all(np.isfinite(T)):
        raise ValueError("non-finite triangle coordinates")
    return T


def _aabbs_overlap(P, Q):
    """Closed axis-aligned boxes of the vertex sets overlap.  Exact: it only compares
    the given floats with each other (no arithmetic)."""
    return bool(np.all(P.min(axis=0) <= Q.max(axis=0)) and np.all(Q.min(axis=0) <= P.max(axis=0)))


def _clear_denominators(points):
    """Scale exact rational points by one positive integer so that they become integer
    points.  Whether the origin lies in a convex hull does not change under a positive
    scaling, and integer arithmetic is much faster than Fraction arithmetic."""
    L = lcm(*(x.denominator for p in points for x in p))
    return [tuple(int(x * L) for x in p) for p in points]


def barycentric_of_origin(simplex):
    """Exact barycentric coordinates of the origin w.r.t. 1..4 points in 3-space.

    Returns a list of Fractions lam (summing to 1, with sum lam_i v_i == 0), or None if
    the points are affinely dependent or the origin is not in their affine hull.

    Method: write origin = v0 + sum_i mu_i e_i with e_i = v_i - v0 (i >= 1).  The e_i
    are linearly independent iff the points are affinely independent iff the Gram matrix
    G = [e_i . e_j] is non-singular (then det G > 0).  The normal equations
    G mu = [e_i . (-v0)] have the unique solution mu_i = det(G with column i replaced) /
    det G (Cramer); this mu is a true solution iff v0 + sum mu_i e_i is exactly 0, which
    is checked.  lam = (1 - sum mu, mu_1, ...).
    """
    v0 = simplex[0]
    if len(simplex) == 1:
        return [Fraction(1)] if all(x == 0 for x in v0) else None
    e = [_sub(v, v0) for v in simplex[1:]]
    b = tuple(-x for x in v0)
    m = len(e)
    G = [[_dot(e[i], e[j]) for j in range(m)] for i in range(m)]
    r = [_dot(e[i], b) for i in range(m)]
    g = _det(G)
    if g == 0:
        return None  # affinely dependent
    # Cramer numerators: mu_i = n[i] / g
    n = []
    for i in range(m):
        Gi = [[r[row] if col == i else G[row][col] for col in range(m)] for row in range(m)]
        n.append(_det(Gi))
    # is the least-squares solution an exact solution (origin in the affine hull)?
    for k in range(3):
        if sum(n[i] * e[i][k] for i in range(m)) != g * b[k]:
            return None
    return [Fraction(g - sum(n), g)] + [Fraction(ni, g) for ni in n]


def triangles_intersect_exact(P, Q):
    """Do the CLOSED triangles P and Q ((3, 3) float arrays, rows = vertices) share a
    point?  Exact for every finite input, including zero-area triangles (coincident or
    collinear vertices) and coplanar pairs.

    Why this is correct:
      * x is in P iff x = sum_i a_i p_i with a_i >= 0, sum a_i = 1; likewise y in Q with
        weights b_j.  P and Q meet iff some x - y = 0.  Since
        x - y = sum_{i,j} a_i b_j (p_i - q_j) with weights a_i b_j >= 0 summing to 1,
        every x - y lies in H = conv{p_i - q_j}; conversely every point of H is such a
        difference (H = P - Q, the Minkowski difference of two convex sets, is convex
        and contains the 9 points).  So P and Q meet iff the origin lies in H.
      * Caratheodory: a point of the convex hull of a set in R^3 lies in the convex hull
        of some affinely independent subset of at most 4 of its points (a simplex).
        Conversely any such simplex lies in H.
      * So: enumerate all subsets of 1..4 of the (distinct) difference points, skip the
        affinely dependent ones, compute the origin's barycentric coordinates exactly and
        accept iff they are all >= 0.
    Shortcuts, each a mere necessary condition: disjoint bounding boxes of P and Q mean
    no intersection; a simplex can only contain the origin if its own bounding box does.
    """
    P = _as_triangle(P)
    Q = _as_triangle(Q)
    if not _aabbs_overlap(P, Q):
        return False
    p = to_fractions(P)
    q = to_fractions(Q)
    diffs = sorted({_sub(pi, qj) for pi in p for qj in q})
    pts = _clear_denominators(diffs)
    for k in range(1, 5):
        for simplex in combinations(pts, k):
            if not all(min(v[c] for v in simplex) <= 0 <= max(v[c] for v in simplex)
                       for c in range(3)):
                continue
            lam = barycentric_of_origin(simplex)
            if lam is not None and all(x >= 0 for x in lam):
                return True
    return False


def triangle_pairs_exact(VA, FA, VB, FB):
    """All intersecting triangle pairs (i, j) (i indexes FA, j indexes FB) of two meshes,
    sorted.  Brute force with an exact float AABB prefilter; small meshes only."""
    VA = np.asarray(VA, dtype=np.float64)
    VB = np.asarray(VB, dtype=np.float64)
    FA = np.asarray(FA, dtype=np.int64).reshape(-1, 3)
    FB = np.asarray(FB, dtype=np.int64).reshape(-1, 3)
    TA = VA[FA]  # (na, 3, 3)
    TB = VB[FB]
    if len(TA) == 0 or len(TB) == 0:
        return []
    loA, hiA = TA.min(axis=1), TA.max(axis=1)
    loB, hiB = TB.min(axis=1), TB.max(axis=1)
    overlap = np.all((loA[:, None, :] <= hiB[None, :, :]) & (loB[None, :, :] <= hiA[:, None, :]),
                     axis=2)
    pairs = []
    for i, j in zip(*np.nonzero(overlap)):
        if triangles_intersect_exact(TA[i], TB[j]):
            pairs.append((int(i), int(j)))
    return sorted(pairs)


# --------------------------------------------------------------------------------------
# hand-made cases, each with a certificate of its answer
# --------------------------------------------------------------------------------------

F = Fraction


def _tri(*rows):
    """Three points given as exact numbers -> (3, 3) float64, asserting that every
    coordinate is represented exactly."""
    assert len(rows) == 3
    out = np.empty((3, 3), dtype=np.float64)
    for i, row in enumerate(rows):
        assert len(row) == 3
        for k, x in enumerate(row):
            want = _exact(x)
            out[i, k] = float(want)
            assert Fraction(float(out[i, k])) == want, f"{x!r} is not a float64"
    return out


def _point(x, y, z):
    return _tri((x, y, z), (x, y, z), (x, y, z))


def _shift(T, dx=0, dy=0, dz=0):
    """Exact translation (asserted exact by _tri)."""
    return _tri(*[(F(float(r[0])) + _exact(dx), F(float(r[1])) + _exact(dy),
                   F(float(r[2])) + _exact(dz)) for r in T])


def _up(x):
    """Next float64 above x (exactly representable by definition)."""
    return Fraction(float(np.nextafter(float(x), np.inf)))


def _down(x):
    return Fraction(float(np.nextafter(float(x), -np.inf)))


def _meet(wp, wq):
    """Certificate of intersection: barycentric weights of one common point in P and Q."""
    return ("meet", tuple(F(w) for w in wp), tuple(F(w) for w in wq))


def _apart(normal):
    """Certificate of disjointness: a direction along which the vertex projections of P
    and Q are strictly separated (a separating plane with that normal exists)."""
    return ("apart", tuple(F(x) for x in normal))


def _build_cases():
    cases = []

    def add(name, P, Q, expected, cert):
        cases.append((name, P, Q, expected, cert))

    T0 = _tri((0, 0, 0), (1, 0, 0), (0, 1, 0))       # unit right triangle in z = 0
    g40 = F(1, 2**40)
    den = F(float(np.nextafter(0.0, 1.0)))             # smallest positive subnormal
    q, h, e8 = F(1, 4), F(1, 2), F(1, 8)

    # ---- clear intersections and clear separations
    add("pierce: vertical Q edge through P interior at (1/4,1/4,0)",
        T0, _tri((q, q, -1), (q, q, 1), (-1, -1, 0)), True, _meet((h, q, q), (h, h, 0)))
    add("pierce: Q (plane x=1/4) crosses P through two of its edges",
        T0, _tri((q, -1, -1), (q, -1, 1), (q, 2, 0)), True, _meet((q, q, h), (q, q, h)))
    add("pierce: big triangles crossing along a segment through the origin",
        _tri((-2, -2, 0), (4, -2, 0), (-2, 4, 0)), _tri((-2, 0, -2), (4, 0, -2), (0, 0, 4)), True,
        _meet((F(1, 3), F(1, 3), F(1, 3)), (F(4, 9), F(2, 9), F(1, 3))))
    add("separate: parallel planes z=0 and z=1",
        T0, _shift(T0, dz=1), False, _apart((0, 0, 1)))
    add("separate: far apart, disjoint boxes",
        T0, _shift(T0, 10, 10, 10), False, _apart((1, 0, 0)))
    add("separate: boxes overlap but plane x+y=5/4 separates",
        T0, _tri((1, 1, -1), (1, 1, 1), (F(3, 4), F(3, 4), 0)), False, _apart((1, 1, 0)))

    # ---- vertex of Q on P's face
    add("vertex-face: Q vertex touches P interior, rest of Q above",
        T0, _tri((q, q, 0), (q, 0, 1), (0, q, 1)), True, _meet((h, q, q), (1, 0, 0)))
    add("vertex-face: Q vertex 2^-40 above P interior",
        T0, _tri((q, q, g40), (q, 0, 1), (0, q, 1)), False, _apart((0, 0, 1)))
    add("vertex-face: Q vertex one ulp (min subnormal) above P interior",
        T0, _tri((q, q, den), (q, 0, 1), (0, q, 1)), False, _apart((0, 0, 1)))
    P1 = _shift(T0, dz=1)
    add("vertex-face: P at z=1, Q vertex touches interior",
        P1, _tri((q, q, 1), (q, 0, 2), (0, q, 2)), True, _meet((h, q, q), (1, 0, 0)))
    add("vertex-face: P at z=1, Q vertex one ulp above (1+2^-52)",
        P1, _tri((q, q, _up(1)), (q, 0, 2), (0, q, 2)), False, _apart((0, 0, 1)))
    add("vertex-face: P at z=1, Q vertex one ulp below (1-2^-53), rest of Q below",
        P1, _tri((q, q, _down(1)), (q, 0, 0), (0, q, 0)), False, _apart((0, 0, 1)))

    # ---- vertex-vertex
    add("vertex-vertex: out of plane, common vertex at the origin",
        T0, _tri((0, 0, 0), (-1, 0, 1), (0, -1, 1)), True, _meet((1, 0, 0), (1, 0, 0)))
    add("vertex-vertex: coplanar, opposite quadrants, common vertex at the origin",
        T0, _tri((0, 0, 0), (-1, 0, 0), (0, -1, 0)), True, _meet((1, 0, 0), (1, 0, 0)))
    add("vertex-vertex: coplanar, gap 2^-40 in x",
        T0, _tri((-g40, 0, 0), (-1, 0, 0), (-g40, -1, 0)), False, _apart((1, 0, 0)))
    add("vertex-vertex: out of plane, Q vertex one ulp above P's vertex",
        T0, _tri((0, 0, den), (-1, 0, 1), (0, -1, 1)), False, _apart((0, 0, 1)))

    # ---- vertex-edge
    add("vertex-edge: Q vertex on midpoint of P's x-axis edge, out of plane",
        T0, _tri((h, 0, 0), (h, -1, 1), (q, -1, 1)), True, _meet((h, h, 0), (1, 0, 0)))
    add("vertex-edge: Q vertex one ulp (subnormal) outside P's x-axis edge",
        T0, _tri((h, -den, 0), (h, -1, 1), (q, -1, 1)), False, _apart((0, 1, 0)))
    add("vertex-edge: coplanar, Q vertex on P's hypotenuse from outside",
        T0, _tri((h, h, 0), (1, 1, 0), (F(3, 2), h, 0)), True, _meet((0, h, h), (1, 0, 0)))
    add("vertex-edge: coplanar, Q vertex one ulp outside P's hypotenuse",
        T0, _tri((h, _up(h), 0), (1, 1, 0), (F(3, 2), h, 0)), False, _apart((1, 1, 0)))
    add("vertex-edge: coplanar, Q vertex on P's x-axis edge from below",
        T0, _tri((h, 0, 0), (q, -1, 0), (F(3, 4), -1, 0)), True, _meet((h, h, 0), (1, 0, 0)))

    # ---- edge-edge crossing at one point
    add("edge-edge: Q's vertical edge crosses P's hypotenuse at (1/2,1/2,0)",
        T0, _tri((h, h, -1), (h, h, 1), (1, 1, 0)), True, _meet((0, h, h), (h, h, 0)))
    add("edge-edge: same, Q moved 2^-40 off the hypotenuse",
        T0, _tri((h, h + g40, -1), (h, h + g40, 1), (1, 1, 0)), False, _apart((1, 1, 0)))
    add("edge-edge: same, Q's crossing edge one ulp (2^-54) off the hypotenuse",
        T0, _tri((h, _up(h), -1), (h, _up(h), 1), (1, 1, 0)), False, _apart((1, 1, 0)))
    add("edge-edge: Q straddles P's plane, its edge misses P's vertex (1,0,0) by one ulp",
        T0, _tri((_up(1), 0, -1), (_up(1), 0, 1), (2, -1, 0)), False, _apart((1, 0, 0)))
    add("edge-edge: Q (plane x=1/2) edge crosses P's x-axis edge at (1/2,0,0)",
        T0, _tri((h, 0, -1), (h, 0, 1), (h, -1, 0)), True, _meet((h, h, 0), (h, h, 0)))
    add("edge-edge: same, Q one ulp (subnormal) off in y",
        T0, _tri((h, -den, -1), (h, -den, 1), (h, -1, 0)), False, _apart((0, 1, 0)))

    # ---- edge on face
    add("edge-face: Q edge lies in P's plane across P, rest of Q above",
        T0, _tri((-1, q, 0), (2, q, 0), (h, q, 1)), True,
        _meet((h, q, q), (F(7, 12), F(5, 12), 0)))
    add("edge-face: same, Q lifted by 2^-40",
        T0, _tri((-1, q, g40), (2, q, g40), (h, q, 1)), False, _apart((0, 0, 1)))

    # ---- coplanar
    add("coplanar: overlapping, Q = P shifted by (1/4,1/4)",
        T0, _shift(T0, q, q), True, _meet((h, q, q), (1, 0, 0)))
    add("coplanar: star of David, edges cross, no vertex inside the other",
        _tri((0, 0, 0), (4, 0, 0), (2, 3, 0)), _tri((0, 2, 0), (4, 2, 0), (2, -1, 0)), True,
        _meet((F(1, 3),) * 3, (F(1, 3),) * 3))
    add("coplanar: Q strictly inside P",
        T0, _tri((e8, e8, 0), (q, e8, 0), (e8, q, 0)), True, _meet((F(3, 4), e8, e8), (1, 0, 0)))
    add("coplanar: P strictly inside big Q",
        T0, _tri((-1, -1, 0), (3, -1, 0), (-1, 3, 0)), True, _meet((1, 0, 0), (h, q, q)))
    add("coplanar: shared edge (adjacent triangles of a square)",
        T0, _tri((1, 0, 0), (0, 1, 0), (1, 1, 0)), True, _meet((0, h, h), (h, h, 0)))
    add("coplanar: partial edge overlap along the x axis",
        T0, _tri((h, 0, 0), (2, 0, 0), (1, -1, 0)), True, _meet((0, 1, 0), (F(2, 3), F(1, 3), 0)))
    add("coplanar: gap 2^-40 across P's x-axis edge",
        T0, _tri((0, -g40, 0), (1, -g40, 0), (h, -1, 0)), False, _apart((0, 1, 0)))
    add("coplanar: gap of (at least) one subnormal ulp across the hypotenuse",
        T0, _tri((_up(1), 0, 0), (den, 1, 0), (1, 1, 0)), False, _apart((1, 1, 0)))

    # ---- parallel planes, tiny gaps
    add("parallel: identical footprint, z gap 2^-40",
        T0, _shift(T0, dz=g40), False, _apart((0, 0, 1)))
    add("parallel: identical footprint, z gap one subnormal ulp",
        T0, _shift(T0, dz=den), False, _apart((0, 0, 1)))
    add("parallel: at z=1e6, gap one ulp (2^-33)",
        _shift(T0, dz=10**6), _shift(T0, dz=_up(10**6)), False, _apart((0, 0, 1)))

    # ---- identical
    add("identical triangles",
        T0, T0.copy(), True, _meet((1, 0, 0), (1, 0, 0)))
    add("identical triangles, vertices cyclically permuted",
        T0, T0[[2, 0, 1]], True, _meet((1, 0, 0), (0, 1, 0)))
    add("identical triangles in a tilted plane, reversed orientation",
        _tri((1, 0, 0), (0, 1, 0), (0, 0, 1)), _tri((0, 0, 1), (0, 1, 0), (1, 0, 0)), True,
        _meet((F(1, 3),) * 3, (F(1, 3),) * 3))

    # ---- tilted plane x+y+z = 1
    S = _tri((1, 0, 0), (0, 1, 0), (0, 0, 1))
    add("tilted: Q vertex touches the interior of P (plane x+y+z=1)",
        S, _tri((q, q, h), (1, 1, 1), (1, 1, 0)), True, _meet((q, q, h), (1, 0, 0)))
    add("tilted: Q vertex one ulp beyond P's plane (z=1/2+2^-53)",
        S, _tri((q, q, _up(h)), (1, 1, 1), (1, 1, 0)), False, _apart((1, 1, 1)))
    add("tilted: Q vertex one ulp short of P's plane (z=1/2-2^-54), rest below",
        S, _tri((q, q, _down(h)), (0, 0, 0), (-1, 0, 0)), False, _apart((1, 1, 1)))
    add("tilted: coplanar, shared edge",
        S, _tri((1, 0, 0), (0, 1, 0), (1, 1, -1)), True, _meet((1, 0, 0), (1, 0, 0)))
    add("tilted: coplanar, overlapping",
        S, _tri((h, h, 0), (-1, 1, 1), (1, -1, 1)), True,
        _meet((F(1, 6), F(1, 6), F(2, 3)), (F(1, 3),) * 3))

    # ---- degenerate: point triangles (three equal vertices)
    add("point-triangle: point inside P",
        T0, _point(q, q, 0), True, _meet((h, q, q), (1, 0, 0)))
    add("point-triangle: point on P's edge",
        T0, _point(h, 0, 0), True, _meet((h, h, 0), (1, 0, 0)))
    add("point-triangle: point on P's vertex",
        T0, _point(1, 0, 0), True, _meet((0, 1, 0), (1, 0, 0)))
    add("point-triangle: point one subnormal ulp above P's interior",
        T0, _point(q, q, den), False, _apart((0, 0, 1)))
    add("point-triangle: coplanar point one ulp outside the hypotenuse",
        T0, _point(h, _up(h), 0), False, _apart((1, 1, 0)))
    add("point-point: equal points",
        _point(1, 2, 3), _point(1, 2, 3), True, _meet((1, 0, 0), (1, 0, 0)))
    add("point-point: points one ulp apart in z",
        _point(1, 2, 3), _point(1, 2, _up(3)), False, _apart((0, 0, 1)))

    # ---- degenerate: needles (collinear vertices)
    add("needle: collinear Q pierces P's interior",
        T0, _tri((q, q, -1), (q, q, h), (q, q, 1)), True, _meet((h, q, q), (h, 0, h)))
    add("needle: collinear Q passes beside P",
        T0, _tri((F(3, 4), F(3, 4), -1), (F(3, 4), F(3, 4), 0), (F(3, 4), F(3, 4), 1)), False,
        _apart((1, 1, 0)))
    add("needle: coplanar needle touches P's edge with its end",
        T0, _tri((h, 0, 0), (h, -h, 0), (h, -1, 0)), True, _meet((h, h, 0), (1, 0, 0)))
    add("needle: coplanar needle lies inside P",
        T0, _tri((e8, e8, 0), (q, q, 0), (F(3, 8), F(3, 8), 0)), True,
        _meet((F(3, 4), e8, e8), (1, 0, 0)))
    add("needle: coplanar needle crosses P's x-axis edge (unsorted vertices)",
        T0, _tri((h, -1, 0), (h, 1, 0), (h, 0, 0)), True, _meet((h, h, 0), (0, 0, 1)))
    add("needle: parallel to P's x-axis edge, one subnormal ulp above",
        T0, _tri((0, 0, den), (h, 0, den), (1, 0, den)), False, _apart((0, 0, 1)))
    add("needle: continues P's y-axis edge, touching at (0,1,0)",
        T0, _tri((0, 1, 0), (0, 2, 0), (0, 3, 0)), True, _meet((0, 0, 1), (1, 0, 0)))
    add("needle: continues P's y-axis edge, one ulp gap",
        T0, _tri((0, _up(1), 0), (0, 2, 0), (0, 3, 0)), False, _apart((0, 1, 0)))
    add("needle-needle: segments (repeated vertex) cross at (1,1,0)",
        _tri((0, 0, 0), (2, 2, 0), (2, 2, 0)), _tri((0, 2, 0), (2, 0, 0), (0, 2, 0)), True,
        _meet((h, h, 0), (h, h, 0)))
    add("needle-needle: skew segments, z gap 2^-40",
        _tri((0, 0, 0), (2, 2, 0), (1, 1, 0)), _tri((0, 2, g40), (2, 0, g40), (1, 1, g40)), False,
        _apart((0, 0, 1)))
    add("needle-needle: collinear, overlapping on [3/2, 2]",
        _tri((0, 0, 0), (1, 0, 0), (2, 0, 0)), _tri((F(3, 2), 0, 0), (3, 0, 0), (F(5, 2), 0, 0)),
        True, _meet((0, 0, 1), (F(2, 3), F(1, 3), 0)))
    add("needle-needle: collinear, touching end to end at x=2",
        _tri((0, 0, 0), (1, 0, 0), (2, 0, 0)), _tri((2, 0, 0), (3, 0, 0), (4, 0, 0)), True,
        _meet((0, 0, 1), (1, 0, 0)))
    add("needle-needle: collinear, one ulp gap after x=2",
        _tri((0, 0, 0), (1, 0, 0), (2, 0, 0)), _tri((_up(2), 0, 0), (3, 0, 0), (4, 0, 0)), False,
        _apart((1, 0, 0)))
    add("point-needle: point on the needle's interior (diagonal x=y=z)",
        _tri((0, 0, 0), (1, 1, 1), (2, 2, 2)), _point(h, h, h), True,
        _meet((h, h, 0), (1, 0, 0)))
    add("point-needle: point one ulp off the diagonal needle",
        _tri((0, 0, 0), (1, 1, 1), (2, 2, 2)), _point(h, h, _up(h)), False, _apart((-1, 0, 1)))

    # ---- large coordinates (offset 1e6) with tiny features (2^-20 triangles, ulp 2^-33)
    B, s = 10**6, F(1, 2**20)
    PB = _tri((B, B, B), (B + s, B, B), (B, B + s, B))
    sq = s / 4
    add("large: Q vertex touches P interior at offset 1e6",
        PB, _tri((B + sq, B + sq, B), (B + sq, B, B + s), (B, B + sq, B + s)), True,
        _meet((h, q, q), (1, 0, 0)))
    add("large: Q vertex one ulp (2^-33) above P interior at offset 1e6",
        PB, _tri((B + sq, B + sq, _up(B)), (B + sq, B, B + s), (B, B + sq, B + s)), False,
        _apart((0, 0, 1)))
    add("large: Q edge pierces P interior at offset 1e6",
        PB, _tri((B + sq, B + sq, B - s), (B + sq, B + sq, B + s), (B - s, B - s, B)), True,
        _meet((h, q, q), (h, h, 0)))
    add("large: coplanar shared edge at offset 1e6",
        PB, _tri((B + s, B, B), (B, B + s, B), (B + s, B + s, B)), True,
        _meet((0, h, h), (h, h, 0)))
    u = F(1, 2**33)
    add("large: coplanar, one ulp gap across the hypotenuse at offset 1e6",
        PB, _tri((B + s + u, B, B), (B + u, B + s, B), (B + s, B + s, B)), False,
        _apart((1, 1, 0)))
    add("large: needle pierces P at offset 1e6",
        PB, _tri((B + sq, B + sq, B - s), (B + sq, B + sq, B + s / 2), (B + sq, B + sq, B + s)),
        True, _meet((h, q, q), (h, 0, h)))
    return cases


_CASES = None


def _cases():
    global _CASES
    if _CASES is None:
        _CASES = _build_cases()
    return _CASES


def hand_cases():
    """[(name, P, Q, expected_bool)]: hand-made cases, answers known by construction
    (each also carries a certificate, see hand_case_certificates).  All coordinates are
    exactly representable float64 values."""
    return [(name, P.copy(), Q.copy(), expected) for name, P, Q, expected, _ in _cases()]


def hand_case_certificates():
    """{name: certificate} for hand_cases():
    ("meet", wp, wq): sum wp_i P_i == sum wq_j Q_j exactly, weights >= 0 summing to 1;
    ("apart", n): max over one triangle of n.v < min over the other of n.v, exactly."""
    return {name: cert for name, _, _, _, cert in _cases()}


def check_certificate(P, Q, cert):
    """Exactly verify a hand-case certificate; returns the bool it certifies, or raises
    AssertionError if the certificate is invalid."""
    p, q = to_fractions(P), to_fractions(Q)
    if cert[0] == "meet":
        _, wp, wq = cert
        for w in (wp, wq):
            assert len(w) == 3 and all(x >= 0 for x in w) and sum(w) == 1, w
        x = tuple(sum(wp[i] * p[i][k] for i in range(3)) for k in range(3))
        y = tuple(sum(wq[j] * q[j][k] for j in range(3)) for k in range(3))
        assert x == y, (x, y)
        return True
    if cert[0] == "apart":
        n = cert[1]
        sp = [_dot(n, v) for v in p]
        sq = [_dot(n, v) for v in q]
        assert max(sp) < min(sq) or max(sq) < min(sp), (sp, sq)
        return False
    raise AssertionError(f"unknown certificate {cert!r}")


# --------------------------------------------------------------------------------------
# random grid cases where touching / coplanarity is frequent
# --------------------------------------------------------------------------------------

def random_near_degenerate_cases(rng, n, size=4):
    """n random triangle pairs [(P, Q)] with small integer coordinates in [0, size]^3
    (occasionally scaled by a power of two and offset by 1e6, still exact), built so
    that shared vertices/edges, coplanar pairs, touching configurations and zero-area
    triangles are frequent."""
    rng = np.random.default_rng(rng)

    def grid(k):
        return rng.integers(0, size + 1, size=(k, 3)).astype(np.float64)

    out = []
    for _ in range(n):
        mode = int(rng.integers(0, 8))
        P, Q = grid(3), grid(3)
        if mode == 1:    # shared vertex
            Q[rng.integers(0, 3)] = P[rng.integers(0, 3)]
        elif mode == 2:  # shared edge (possibly reversed)
            i, j = rng.choice(3, size=2, replace=False)
            Q[0], Q[1] = P[i], P[j]
            if rng.random() < 0.5:
                Q[[0, 1]] = Q[[1, 0]]
        elif mode == 3:  # coplanar in an axis plane
            axis = rng.integers(0, 3)
            c = rng.integers(0, size + 1)
            P[:, axis] = c
            Q[:, axis] = c
        elif mode == 4:  # coplanar in the tilted plane x + y + z = c
            c = rng.integers(0, 2 * size + 1)
            for T in (P, Q):
                T[:, 2] = c - T[:, 0] - T[:, 1]
        elif mode == 5:  # a zero-area triangle: repeated vertex or collinear grid points
            T = P if rng.random() < 0.5 else Q
            if rng.random() < 0.5:
                T[rng.integers(0, 3)] = T[rng.integers(0, 3)]
            else:
                a = grid(1)[0]
                d = rng.integers(-1, 2, size=3).astype(np.float64)
                T[:] = a + np.outer(rng.integers(-2, 3, size=3), d)
        elif mode == 6:  # Q's vertex on P's plane z = c, rest of Q on one side
            c = rng.integers(0, size + 1)
            P[:, 2] = c
            Q[0, 2] = c
            Q[1:, 2] = c + rng.integers(0, 3, size=2) * (1 if rng.random() < 0.5 else -1)
        # mode 0 (and 7): independent grid triangles
        if rng.random() < 0.15:  # exact rescale + large offset: tiny features far away
            scale = 2.0 ** -int(rng.integers(8, 20))
            P = P * scale + 1e6
            Q = Q * scale + 1e6
        out.append((P, Q))
    return out
