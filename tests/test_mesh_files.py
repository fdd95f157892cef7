"""Triangle i of a mesh is the file's i-th face (polygons fanned from their first corner in
turn), whatever the format: results name triangles by these indices."""
import numpy as np
import pytest
import trimesh
from conftest import identity_quaternions, write_box, write_trajectory

import collide
from collide.errors import InputError
from collide.load import fans_in_order, load_mesh

# faces of every size, mixed, each polygon a flat fan around its first corner; the sizes
# are chosen so that trimesh's own triangulation (triangles, then quads' first halves,
# then second halves, then larger polygons) would give another order
SIZES = [3, 4, 3, 5, 4, 3, 6, 4]


def _polygons(seed=3, sizes=SIZES):
    """(vertices float64 (V, 3), polygons [list of vertex indices]) of these sizes, each
    polygon on its own vertices, spread out so that every triangle is told apart."""
    rng = np.random.default_rng(seed)
    vertices, polygons = [], []
    for k, size in enumerate(sizes):
        angles = rng.uniform(0.0, 2.0 * np.pi) + 2.0 * np.pi * np.arange(size) / size  # regular, turned
        ring = np.stack([np.cos(angles), np.sin(angles), np.full(size, float(k))], axis=1) + [3.0 * k, 0.0, 0.0]
        polygons.append(list(range(len(vertices), len(vertices) + size)))
        vertices.extend(ring.tolist())
    return np.array(vertices), polygons


def _reference_triangles(vertices, polygons):
    """(T, 3, 3) corners of the fans, polygon by polygon, by a plain loop."""
    out = []
    for p in polygons:
        for j in range(1, len(p) - 1):
            out.append(vertices[[p[0], p[j], p[j + 1]]])
    return np.array(out)


def _write_off(path, vertices, polygons):
    lines = ["OFF", f"{len(vertices)} {len(polygons)} 0"]
    lines += [" ".join(repr(float(c)) for c in v) for v in vertices]
    lines += [" ".join(str(i) for i in [len(p)] + p) for p in polygons]
    path.write_text("\n".join(lines) + "\n")


def _write_ply(path, vertices, polygons):
    header = ["ply", "format ascii 1.0", f"element vertex {len(vertices)}", "property double x",
              "property double y", "property double z", f"element face {len(polygons)}",
              "property list uchar int vertex_indices", "end_header"]
    lines = header + [" ".join(repr(float(c)) for c in v) for v in vertices]
    lines += [" ".join(str(i) for i in [len(p)] + p) for p in polygons]
    path.write_text("\n".join(lines) + "\n")


def _write_obj(path, vertices, polygons):
    """With a material switch before every face, materials coming back, and "usemtl" in a
    comment and an object name too (trimesh splits the faces at each, and would put the
    parts in another order)."""
    lines = ["mtllib none.mtl", "o part_usemtl_a"] + ["v " + " ".join(repr(float(c)) for c in v) for v in vertices]
    for k, p in enumerate(polygons):
        lines.append(f"usemtl m{k % 3}" if k % 2 else f"# usemtl m{k % 3}")
        lines.append("f " + " ".join(str(i + 1) for i in p))
    path.write_text("\n".join(lines) + "\n")


WRITERS = {"off": _write_off, "ply": _write_ply, "obj": _write_obj}


def test_fans_in_order_match_a_loop():
    rng = np.random.default_rng(0)
    for _ in range(50):
        sizes = rng.integers(0, 8, rng.integers(1, 12))
        polygons = [list(rng.integers(0, 100, s)) for s in sizes]
        expected = [[p[0], p[j], p[j + 1]] for p in polygons for j in range(1, len(p) - 1)]
        got = fans_in_order(polygons)
        assert got.dtype == np.int64 and got.tolist() == expected
        assert fans_in_order([[str(i) for i in p] for p in polygons]).tolist() == expected  # OFF gives text
    same = rng.integers(0, 100, (6, 5))
    assert fans_in_order(same).tolist() == [[p[0], p[j], p[j + 1]] for p in same.tolist() for j in (1, 2, 3)]


@pytest.mark.parametrize("sizes", [SIZES, [4] * 5], ids=["mixed", "quads"])
@pytest.mark.parametrize("suffix", sorted(WRITERS))
def test_faces_keep_the_file_order(suffix, sizes, tmp_path):
    vertices, polygons = _polygons(sizes=sizes)
    path = tmp_path / f"part.{suffix}"
    WRITERS[suffix](path, vertices, polygons)
    mesh = load_mesh(path)
    got, expected = mesh.vertices[mesh.faces], _reference_triangles(vertices, polygons)
    if suffix == "obj":  # trimesh's OBJ reader splits a quad (c0, c1, c2), (c2, c3, c0): the same triangle
        got, expected = _first_corner_smallest(got), _first_corner_smallest(expected)
    np.testing.assert_array_equal(got, expected)


def _first_corner_smallest(triangles):
    """(T, 3, 3) triangles with their corners turned (orientation kept) so that the
    lexicographically smallest comes first."""
    out = np.empty_like(triangles)
    for i, t in enumerate(triangles):
        turns = [np.roll(t, -r, axis=0) for r in range(3)]
        out[i] = min(turns, key=lambda x: tuple(x[0]))
    return out


@pytest.mark.parametrize("suffix", sorted(WRITERS))
def test_contacts_name_the_file_face_that_touches(suffix, tmp_path):
    """A small box resting on each polygon in turn (frame k: polygon k, whose inscribed
    circle holds the box's bottom face): the contact names a triangle of that polygon's fan."""
    vertices, polygons = _polygons()
    folder = tmp_path / "meshes"
    folder.mkdir()
    WRITERS[suffix](folder / f"part.{suffix}", vertices, polygons)
    write_box(folder / "box.stl", extents=(0.5, 0.5, 0.5))
    triangles = _reference_triangles(vertices, polygons)
    fan_of = np.repeat(np.arange(len(polygons)), [len(p) - 2 for p in polygons])
    n = len(polygons)
    position = np.zeros((2 * n, 2, 3))
    position[:, 1] = [[3.0 * k, 0.0, k + 0.25] for k in range(n) for _ in (0, 1)]  # box on polygon k
    position[1::2, 1, 1] = 5.0  # and away between them
    traj = write_trajectory(tmp_path / "traj.h5", np.arange(2 * n, dtype=float), ["part", "box"], position,
                            identity_quaternions(2 * n, 2))
    contacts = collide.scan(folder, traj, mode="discrete", workers=1).contacts
    assert sorted(contacts["frame_begin"].tolist()) == list(range(0, 2 * n, 2))
    for row in range(n):
        frame = int(contacts["frame_begin"][row]) // 2
        assert contacts["object_a"][row] == 0  # the part (object 0) and the box
        tri = int(contacts["tri_a"][row])
        assert fan_of[tri] == frame, (suffix, frame, tri)
        assert abs(triangles[tri][:, 2] - frame).max() == 0.0


def test_a_cut_off_binary_stl_says_so(tmp_path):
    data = trimesh.creation.box().export(file_type="stl")  # 12 triangles: 84 + 12 * 50 bytes
    assert len(data) == 684
    path = tmp_path / "cut.stl"
    path.write_bytes(data[:344])
    with pytest.raises(InputError, match=r"cut.stl: binary STL header counts 12 triangles \(684 bytes\) but the "
                                         r"file has 344 bytes \(cut off\?\); expected a complete STL file"):
        load_mesh(path)
    solid = b"solid exported by a CAD tool".ljust(80) + data[80:]  # binary headers may start with "solid"
    path.write_bytes(solid[:344])
    with pytest.raises(InputError, match=r"counts 12 triangles \(684 bytes\) but the file has 344 bytes"):
        load_mesh(path)
    path.write_bytes(solid)
    assert load_mesh(path).faces.shape == (12, 3)
    path.write_bytes(data)
    assert load_mesh(path).faces.shape == (12, 3)
