"""Reader for the CCD benchmark query files (Wang et al. 2021 Sample-Queries format)."""
from fractions import Fraction
from pathlib import Path

import numpy as np

KINDS = ("vertex-face", "edge-edge")


def read_queries(csv_path):
    """-> (x_t0 (n, 4, 3), x_t1 (n, 4, 3), truth (n,) bool). Values are exact in float64."""
    rows = [line.strip().split(",") for line in Path(csv_path).read_text().splitlines() if line.strip()]
    values = []
    for r in rows:
        exact = [Fraction(int(r[2 * i]), int(r[2 * i + 1])) for i in range(3)]
        floats = [float(x) for x in exact]
        assert all(Fraction(f) == x for f, x in zip(floats, exact)), "query not exact in float64"
        values.append(floats)
    points = np.array(values, dtype=np.float64).reshape(-1, 8, 3)
    truth = np.array([int(r[6]) for r in rows]).reshape(-1, 8)[:, 0] == 1
    return np.ascontiguousarray(points[:, :4]), np.ascontiguousarray(points[:, 4:]), truth


def read_scene(folder, kind):
    """All queries of one kind in a scene folder, concatenated."""
    parts = [read_queries(p) for p in sorted((Path(folder) / kind).glob("*.csv"))]
    return tuple(np.concatenate(x) for x in zip(*parts))


def scenes(root):
    return sorted(p for p in Path(root).iterdir() if p.is_dir())
