"""Discrete scans of scenes whose contacts are known analytically."""
import numpy as np
import pytest
from conftest import identity_quaternions, quaternion_rotation, write_box, write_trajectory

import collide


def test_two_boxes_touch_exactly_when_faces_meet(two_boxes, tmp_path):
    meshes, traj = two_boxes
    result = collide.scan(meshes, traj, mode="discrete", triangle_pairs=True, workers=2)
    c = result.contacts
    # x = -3 + 0.5 k; unit boxes touch iff |x| <= 1 (touching faces count): k = 4..8
    assert c["object_a"].tolist() == [0]          # mover is object 0, static 'fixed' object 1
    assert c["object_b"].tolist() == [1]
    assert c["frame_begin"].tolist() == [4] and c["frame_end"].tolist() == [8]
    assert c["t_begin"][0] == pytest.approx(0.4) and c["t_end"][0] == pytest.approx(0.8)
    assert c["kind"].tolist() == [0]
    # the reported point is on both boxes at the first contact frame (x = -1: the face x = -0.5)
    point = np.array([c["point_x"][0], c["point_y"][0], c["point_z"][0]])
    assert point[0] == pytest.approx(-0.5) and np.all(np.abs(point[1:]) <= 0.5 + 1e-12)
    pairs = result.triangle_pairs
    assert sorted(set(pairs["frame"].tolist())) == [4, 5, 6, 7, 8]
    assert result.object_names == ["mover", "fixed"]


def test_contact_intervals_split_on_gaps(tmp_path):
    """A box that enters, leaves and re-enters: two intervals, with exact frame bounds."""
    meshes = tmp_path / "m"
    meshes.mkdir()
    write_box(meshes / "a.stl")
    write_box(meshes / "b.stl")
    x = np.array([3, 1, 0.5, 2, 2.5, 1.0, 0.75, 3])  # contact iff |x| <= 1
    pos = np.zeros((x.size, 1, 3))
    pos[:, 0, 0] = x
    traj = write_trajectory(tmp_path / "t.h5", np.arange(x.size, dtype=float), ["b"], pos,
                            identity_quaternions(x.size, 1))
    c = collide.scan(meshes, traj, mode="discrete").contacts
    assert list(zip(c["frame_begin"].tolist(), c["frame_end"].tolist())) == [(1, 2), (5, 6)]
    assert c["t_begin"].tolist() == [1.0, 5.0] and c["t_end"].tolist() == [2.0, 6.0]


def test_one_ulp_gap_is_not_contact(tmp_path):
    """Touching faces are a contact; the next float over is not."""
    meshes = tmp_path / "m"
    meshes.mkdir()
    write_box(meshes / "a.stl")
    write_box(meshes / "b.stl")
    x = np.array([1.0, np.nextafter(1.0, 2.0), -1.0, np.nextafter(-1.0, -2.0)])
    pos = np.zeros((4, 1, 3))
    pos[:, 0, 0] = x
    traj = write_trajectory(tmp_path / "t.h5", np.arange(4.0), ["b"], pos, identity_quaternions(4, 1))
    pairs = collide.scan(meshes, traj, mode="discrete", triangle_pairs=True).triangle_pairs
    assert sorted(set(pairs["frame"].tolist())) == [0, 2]


def test_shared_mesh_and_static_pairs(tmp_path):
    """Two objects share one mesh via objects/mesh; two static meshes touch each other at
    every frame (tested once, reported for the whole range)."""
    meshes = tmp_path / "m"
    meshes.mkdir()
    write_box(meshes / "peg.stl")
    write_box(meshes / "wall_left.stl", centre=(-5, 0, 0))
    write_box(meshes / "wall_right.stl", centre=(-4, 0, 0))   # touches wall_left (faces at x=-4.5)
    n = 5
    pos = np.zeros((n, 2, 3))
    pos[:, 0, 1] = 10.0                      # first peg: far away always
    pos[:, 1, 0] = [10, 10, -3.0, 10, 10]    # second peg touches wall_right at frame 2
    traj = write_trajectory(tmp_path / "t.h5", np.arange(n) * 0.5, ["peg1", "peg2"], pos,
                            identity_quaternions(n, 2), mesh=["peg.stl", "peg"])
    result = collide.scan(meshes, traj, mode="discrete")
    assert result.object_names == ["peg1", "peg2", "wall_left", "wall_right"]
    assert result.object_meshes == ["peg.stl", "peg.stl", "wall_left.stl", "wall_right.stl"]
    c = result.contacts
    rows = list(zip(c["object_a"].tolist(), c["object_b"].tolist(),
                    c["frame_begin"].tolist(), c["frame_end"].tolist()))
    assert rows == [(1, 3, 2, 2), (2, 3, 0, 4)]
    # continuous mode: the static pair is one interval over the whole range too
    c = collide.scan(meshes, traj).contacts
    static_rows = [(b, e) for a, o, b, e in zip(c["object_a"], c["object_b"], c["t_begin"], c["t_end"])
                   if (a, o) == (2, 3)]
    assert static_rows == [(0.0, 2.0)]


def test_frames_option_selects_a_range(two_boxes):
    meshes, traj = two_boxes
    result = collide.scan(meshes, traj, mode="discrete", frames="5:7")
    assert result.frame_index.tolist() == [5, 6]
    c = result.contacts
    assert c["frame_begin"].tolist() == [0] and c["frame_end"].tolist() == [1]
    assert c["t_begin"][0] == pytest.approx(0.5)


def test_rotated_poses_matrix_and_quaternion_orders_agree(tmp_path):
    """The same motion as wxyz quaternions, xyzw quaternions and 4x4 matrices gives the same pairs."""
    meshes = tmp_path / "m"
    meshes.mkdir()
    write_box(meshes / "a.stl", extents=(2, 0.2, 0.2))
    write_box(meshes / "b.stl", extents=(2, 0.2, 0.2))
    n = 24
    angle = np.linspace(0, np.pi, n)
    c, s = np.cos(angle), np.sin(angle)
    pos = np.zeros((n, 1, 3))
    pos[:, 0] = [0.0, 0.5, 0.0]  # a bar spinning about z beside another: touch when crossing
    zero = np.zeros(n)
    wxyz = np.stack([np.cos(angle / 2), zero, zero, np.sin(angle / 2)], axis=-1)[:, None, :]
    xyzw = np.roll(wxyz, -1, axis=-1)
    mat = np.zeros((n, 1, 4, 4))
    mat[:, 0, :3, :3] = np.stack([np.stack([c, -s, zero], -1), np.stack([s, c, zero], -1),
                                  np.stack([zero, zero, zero + 1], -1)], axis=1)
    mat[:, 0, :3, 3] = pos[:, 0]
    mat[:, 0, 3, 3] = 1
    results = []
    for name, kwargs in [("w", dict(position=pos, orientation=wxyz, order="wxyz")),
                         ("x", dict(position=pos, orientation=xyzw, order="xyzw")),
                         ("m", dict(matrix=mat))]:
        traj = write_trajectory(tmp_path / f"{name}.h5", np.arange(n, dtype=float), ["b"], **kwargs)
        results.append(collide.scan(meshes, traj, mode="discrete").contacts)
    frames = [(r["frame_begin"].tolist(), r["frame_end"].tolist()) for r in results]
    assert frames[0] == frames[1] == frames[2]
    # analytic: bar b (half-length 1, half-width 0.1) centred at y = 0.5 crosses bar a
    # (|y| <= 0.1) iff sin(angle) * 1 + 0.1 * |cos(angle)| >= 0.4
    touching = np.flatnonzero(np.abs(np.sin(angle)) + 0.1 * np.abs(np.cos(angle)) >= 0.4 - 1e-9)
    assert frames[0] == ([int(touching[0])], [int(touching[-1])])


def test_empty_result_has_empty_columns(tmp_path):
    meshes = tmp_path / "m"
    meshes.mkdir()
    write_box(meshes / "a.stl")
    write_box(meshes / "b.stl", centre=(5, 0, 0))
    traj = write_trajectory(tmp_path / "t.h5", [0.0], ["a"], np.zeros((1, 1, 3)), identity_quaternions(1, 1))
    out = tmp_path / "c.h5"
    result = collide.scan(meshes, traj, mode="discrete", triangle_pairs=True, output=out)
    assert all(col.size == 0 for col in result.contacts.values())
    back = collide.read_contacts(out)
    assert set(back.contacts) == set(result.contacts) and back.contacts["t_begin"].size == 0
    assert back.triangle_pairs["frame"].size == 0


@pytest.mark.parametrize("mode", ["discrete", "continuous"])
def test_contacts_do_not_depend_on_workers_or_chunks(monkeypatch, mode):
    """The frame tests reuse the triangle pair that touched at the previous frame of their
    chunk, so their first-found pairs depend on the chunking; the contacts must not. Each
    contact that begins at a frame reports the smallest touching triangle pair there (the
    reference: every touching pair of that frame, from a --triangle-pairs scan)."""
    from conftest import REPO

    from collide import pipeline
    fixture = REPO / "examples" / "fixture"
    runs = []
    for workers, size in ((1, None), (2, None), (3, 5), (1, 1)):
        with monkeypatch.context() as patch:
            if size is not None:
                patch.setattr(pipeline, "_chunk_size", lambda *args, size=size: size)
            runs.append(collide.scan(fixture / "meshes", fixture / "traj.h5", mode=mode, workers=workers).contacts)
    for other in runs[1:]:
        for name, column in runs[0].items():
            np.testing.assert_array_equal(other[name], column, err_msg=name)
    every = collide.scan(fixture / "meshes", fixture / "traj.h5", mode="discrete", triangle_pairs=True)
    p = every.triangle_pairs
    c = runs[0]
    checked = 0
    for k in np.flatnonzero(c["kind"] == 0):
        at = ((p["frame"] == c["frame_begin"][k]) & (p["object_a"] == c["object_a"][k])
              & (p["object_b"] == c["object_b"][k]))
        if mode == "continuous" and not at.any():
            continue  # the interval began between frames
        smallest = min(zip(p["tri_a"][at].tolist(), p["tri_b"][at].tolist()))
        assert (c["tri_a"][k], c["tri_b"][k]) == smallest
        checked += 1
    assert checked > 0 or mode == "continuous"  # the fixture's continuous contacts begin between frames


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_smallest_touching_pair_equals_the_smallest_of_all_pairs(seed):
    """The branch-and-bound search against every intersecting pair enumerated (two spheres
    and a box, deeply overlapping, at random poses; leaf size 1 and 4)."""
    import trimesh

    from collide.discrete import scan_frames, smallest_touching_pairs
    from collide.filters import build_filters
    from collide.load import Mesh
    from collide.packed import pack_scene
    from collide.rows import PAIR_A, PAIR_B, PAIR_FRAME, PAIR_TRI_A, PAIR_TRI_B
    rng = np.random.default_rng(seed)
    sphere = trimesh.creation.icosphere(subdivisions=3)
    box = trimesh.creation.box(extents=(1.5, 0.4, 0.4))
    meshes = [Mesh(name, None, np.asarray(m.vertices, float), np.asarray(m.faces, np.int64))
              for name, m in (("sphere", sphere), ("box", box))]
    n_frames = 6
    poses = np.zeros((n_frames, 3, 3, 4))
    for f in range(n_frames):
        for o in range(3):
            q = rng.normal(size=4)
            q /= np.linalg.norm(q)
            poses[f, o, :, :3] = quaternion_rotation(q)
            poses[f, o, :, 3] = rng.uniform(-0.6, 0.6, size=3)
    static = np.zeros(3, bool)
    pairs = build_filters(["a", "b", "c"]).kernel_filter()
    for leaf_size in (1, 4):
        ps, _ = pack_scene(meshes, np.array([0, 0, 1]), leaf_size=leaf_size)
        _, every, _ = scan_frames(ps, poses, static, pairs, 0, n_frames, True, False)
        # every (frame, pair) in one call, frames interleaved (each item places its own frame's
        # vertices), asked for in two chunks
        items = rng.permutation([(f, a, b) for f in range(n_frames) for a, b in ((0, 1), (0, 2), (1, 2))])
        rows, wanted = np.ascontiguousarray(items[:, 0]), np.ascontiguousarray(items[:, 1:])
        half = len(items) // 2
        found = np.concatenate([smallest_touching_pairs(ps, poses, static, rows, wanted, 0, half),
                                smallest_touching_pairs(ps, poses, static, rows, wanted, half, len(items))])
        for (f, a, b), got in zip(items, found):
            at = every[(every[:, PAIR_FRAME] == f) & (every[:, PAIR_A] == a) & (every[:, PAIR_B] == b)]
            expected = min(map(tuple, at[:, [PAIR_TRI_A, PAIR_TRI_B]].tolist())) if at.size else (-1, -1)
            assert tuple(got) == expected, (leaf_size, f, a, b)


@pytest.mark.parametrize("seed", [0, 1])
def test_step_scan_names_the_smallest_pair_at_its_first_frame(seed, monkeypatch):
    """A continuous chunk that starts at frame 0 reports, for each pair touching there,
    the smallest intersecting triangle pair (every pair enumerated by scan_frames as the
    reference) and marks it so (HIT_SMALLEST); other frames' hits, and those of a chunk
    starting later, keep the first pair found, unmarked. A scan then leaves no contact
    beginning at frame 0 to the search for smallest pairs after it."""
    import trimesh

    from collide import config, pipeline
    from collide.discrete import scan_frames
    from collide.filters import build_filters
    from collide.load import Mesh
    from collide.motion import INTERPOLATIONS
    from collide.packed import pack_scene
    from collide.rows import HIT_A, HIT_B, HIT_FRAME, HIT_SMALLEST, HIT_TRI_A, HIT_TRI_B, PAIR_A, PAIR_B, PAIR_FRAME
    from collide.swept import scan_intervals
    rng = np.random.default_rng(seed)
    sphere = trimesh.creation.icosphere(subdivisions=3)
    box = trimesh.creation.box(extents=(1.5, 0.4, 0.4))
    meshes = [Mesh(name, None, np.asarray(m.vertices, float), np.asarray(m.faces, np.int64))
              for name, m in (("sphere", sphere), ("box", box))]
    poses = np.zeros((3, 3, 3, 4))
    for o in range(3):  # deeply overlapping at frame 0, then a small drift
        q = rng.normal(size=4)
        poses[:, o, :, :3] = quaternion_rotation(q / np.linalg.norm(q))
        poses[:, o, :, 3] = rng.uniform(-0.6, 0.6, size=3) + np.outer(np.arange(3), rng.uniform(-0.05, 0.05, 3))
    static, pairs = np.zeros(3, bool), build_filters(["a", "b", "c"]).kernel_filter()
    ps, _ = pack_scene(meshes, np.array([0, 0, 1]), leaf_size=4)
    _, every, _ = scan_frames(ps, poses, static, pairs, 0, 3, True, False)
    no_keys, no_tris = np.zeros(0, np.int64), np.zeros((0, 2), np.int64)
    for start in (0, 1):
        hits = scan_intervals(ps, poses, static, pairs, no_keys, no_tris, start, 2, True, INTERPOLATIONS["screw"],
                              config.TIME_TOL, 1e-9, config.ONE_SIDED_LEAVES, config.PROBED_FACES,
                              config.PROBE_LEAF_PAIRS)[0]
        assert (hits[:, HIT_FRAME] == start).any()
        for f, a, b, tri_a, tri_b, smallest in hits[:, [HIT_FRAME, HIT_A, HIT_B, HIT_TRI_A, HIT_TRI_B, HIT_SMALLEST]]:
            at = every[(every[:, PAIR_FRAME] == f) & (every[:, PAIR_A] == a) & (every[:, PAIR_B] == b)]
            assert (tri_a, tri_b) in set(map(tuple, at[:, 3:5].tolist()))  # touching there
            assert smallest == (f == 0)
            if f == 0:
                assert (tri_a, tri_b) == min(map(tuple, at[:, 3:5].tolist()))
    searched = []
    original = pipeline.smallest_pairs_at_frames

    def recording(contacts, where, *args):
        searched.append(where)
        return original(contacts, where, *args)
    monkeypatch.setattr(pipeline, "smallest_pairs_at_frames", recording)
    frame_0 = {(int(a), int(b)): min(map(tuple, every[(every[:, PAIR_FRAME] == 0) & (every[:, PAIR_A] == a)
                                                    & (every[:, PAIR_B] == b)][:, 3:5].tolist()))
               for a, b in {tuple(r) for r in every[every[:, PAIR_FRAME] == 0][:, 1:3].tolist()}}
    result = collide.scan({m.name: (m.vertices, m.faces) for m in meshes},
                          {"time": [0.0, 1.0, 2.0], "names": ["a", "b", "c"], "mesh": ["sphere", "sphere", "box"],
                                   "matrix": np.concatenate([poses, np.tile([0, 0, 0, 1.0], (3, 3, 1, 1))], axis=2)},
                          mode="continuous", workers=1, leaf_size=4)
    c = result.contacts
    begins_at_0 = c["t_begin"] == 0.0
    (steps, u, first_found), = searched
    assert begins_at_0.any() and not (first_found & (steps == 0)).any()  # nothing left to search at frame 0
    for k in np.flatnonzero(begins_at_0):
        assert (c["tri_a"][k], c["tri_b"][k]) == frame_0[(c["object_a"][k], c["object_b"][k])]


@pytest.mark.parametrize("n_rows", [1, 1023, 1024, 1025, 5000])
def test_lazy_stamps_answer_like_stamps_set_to_minus_one_up_front(n_rows):
    """narrow.new_stamps / stamp_is (the world buffers' stamps, set a block at a time on
    first use) against a plain array filled with -1 ('not computed') at the start:
    random questions and writes, and only the blocks of rows asked about are set."""
    from collide.narrow import STAMP_BLOCK, new_stamps, stamp_is
    rng = np.random.default_rng(n_rows)
    stamps, reference = new_stamps(n_rows), np.full(n_rows, -1, np.int64)
    asked = set()
    for _ in range(400):
        row, key = int(rng.integers(n_rows)), int(rng.choice([-2, 0, 1, 7]))
        assert stamp_is(stamps, np.int64(row), np.int64(key)) == (reference[row] == key)
        asked.add(row // STAMP_BLOCK)
        if rng.random() < 0.5:
            stamps[row] = reference[row] = key
    n_blocks = -(-n_rows // STAMP_BLOCK)
    flags = stamps[n_blocks * STAMP_BLOCK:][::-1]
    assert flags.size == n_blocks and set(np.flatnonzero(flags).tolist()) == asked
    for block in asked:  # every row of a set block answers as the reference does
        rows = np.arange(block * STAMP_BLOCK, min((block + 1) * STAMP_BLOCK, n_rows))
        assert np.array_equal(stamps[rows], reference[rows])


@pytest.mark.parametrize("seed", range(4))
def test_sweep_and_prune_finds_exactly_the_overlapping_boxes(seed):
    """broad.sweep_and_prune (object pairs whose world boxes overlap, the first cull of
    every frame and step) against all N^2 pairs tested directly: closed boxes, so boxes
    that only touch count; equal coordinates, boxes of zero size and many boxes stacked
    along one axis included."""
    from collide.broad import sweep_and_prune
    rng = np.random.default_rng(seed)
    n = [1, 2, 60, 400][seed]
    lo = np.round(rng.uniform(0, 10, (n, 3)), 1)  # coarse grid: many equal coordinates
    hi = lo + np.round(rng.choice([0.0, 0.3, 2.0], (n, 3)), 1)
    if seed == 3:
        lo[:, 0] = 0.0  # stacked along x: the sweep axis is another one
        hi[:, 0] = 1.0
    expected = [(a, b) for a in range(n) for b in range(a + 1, n)
                if (lo[a] <= hi[b]).all() and (lo[b] <= hi[a]).all()]
    found = sweep_and_prune(np.ascontiguousarray(lo), np.ascontiguousarray(hi), np.arange(n))
    assert [tuple(row) for row in found.tolist()] == expected
    if n > 2:
        assert expected  # the scene has overlaps to find


def test_sweep_and_prune_carried_from_frame_to_frame():
    """The sweep order carried between calls (as the scans do from frame to frame) gives
    the same pairs as all N^2 pairs tested directly: boxes drifting a little per frame
    (the order nearly sorted), a jump that reshuffles them, the sweep axis changing, and a
    random order to start from (the sort then falls back to a merge sort)."""
    from collide.broad import sort_nearly_sorted, sweep_and_prune
    rng = np.random.default_rng(11)
    n = 300
    lo = rng.uniform(0, 10, (n, 3)) * np.array([3.0, 1.0, 1.0])  # spread most along x
    size = rng.choice([0.0, 0.3, 1.5], (n, 3))
    order = rng.permutation(n)
    for frame in range(40):
        if frame == 20:
            lo = lo[:, [1, 0, 2]] * np.array([1.0, 3.0, 1.0]) / np.array([3.0, 1.0, 1.0])  # now widest along y
        elif frame == 30:
            lo = rng.uniform(0, 30, (n, 3))  # everything moves far
        else:
            lo = lo + rng.normal(0, 0.05, (n, 3))
        hi = lo + size
        lo_c, hi_c = np.ascontiguousarray(lo), np.ascontiguousarray(hi)
        expected = [(a, b) for a in range(n) for b in range(a + 1, n)
                    if (lo[a] <= hi[b]).all() and (lo[b] <= hi[a]).all()]
        found = sweep_and_prune(lo_c, hi_c, order)
        assert [tuple(row) for row in found.tolist()] == expected, frame
        assert sorted(order.tolist()) == list(range(n))  # still a permutation
    # the sort itself, from any start, with ties
    for start in (np.arange(50), rng.permutation(50), np.arange(50)[::-1].copy()):
        keys = rng.choice([0.0, 1.0, 2.5, -1.0], 50)
        order = start.copy()
        sort_nearly_sorted(keys, order)
        assert np.all(np.diff(keys[order]) >= 0) and sorted(order.tolist()) == list(range(50))


def _two_spheres(leaf_size=None):
    """PackedScene of two objects sharing one icosphere (radius 1, 1280 triangles)."""
    import trimesh

    from collide.load import Mesh
    from collide.packed import pack_scene
    sphere = trimesh.creation.icosphere(subdivisions=3)
    mesh = Mesh("sphere", None, np.asarray(sphere.vertices, float), np.asarray(sphere.faces, np.int64))
    return pack_scene([mesh], np.array([0, 0]), leaf_size=leaf_size)[0]


def _sliding_poses(n_frames, turn):
    """Poses (n_frames, 2, 3, 4): sphere 0 still at the origin, sphere 1 sliding from x = -1.6
    to x = 1.6 at y = 0.3, turning by ``turn`` radians per frame about z: the two overlap
    throughout, their intersection circle moving a little between frames."""
    poses = np.zeros((n_frames, 2, 3, 4))
    poses[:, 0, :, :3] = np.eye(3)
    for f in range(n_frames):
        c, s = np.cos(turn * f), np.sin(turn * f)
        poses[f, 1, :, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
        poses[f, 1, :, 3] = (-1.6 + 3.2 * f / (n_frames - 1), 0.3, 0.0)
    return poses


@pytest.mark.parametrize("seed", range(3))
def test_a_descent_toward_points_finds_the_same_leaf_pairs_after_the_same_work(seed):
    """broad.overlapping_leaves guided ``toward`` two points only reorders the descent: the same leaf
    pairs (as a set) after testing as many node pairs as without it (two overlapping
    spheres, random guide points, leaf sizes 1 and 4)."""
    from collide.broad import RULE_POSE, overlapping_leaves
    from collide.discrete import pair_scratch, start_descent
    from collide.motion import MOTION_WIDTH
    from collide.rows import COUNT_NODE_PAIRS, COUNT_WIDTH
    rng = np.random.default_rng(seed)
    poses = _sliding_poses(9, 0.3)[rng.integers(1, 8)]
    for leaf_size in (1, 4):
        ps = _two_spheres(leaf_size)
        found = []
        toward = rng.uniform(-1.0, 1.0, (2, 3))
        for guided in (False, True):
            scratch, stack, out = pair_scratch(), np.empty((4, 2), np.int64), np.empty((4, 2), np.int64)
            top = start_descent(ps, poses, poses, np.zeros((2, MOTION_WIDTH)), 0, 1, scratch, stack)
            counts = np.zeros(COUNT_WIDTH, np.int64)
            _, _, out, k = overlapping_leaves(ps.node_lo, ps.node_hi, ps.node_first, ps.node_count, ps.leaf_box,
                                              *ps.leaf_box_shift[ps.object_mesh], scratch.pose, scratch.motion,
                                              RULE_POSE, 1e-9, stack, top, out, np.iinfo(np.int64).max, counts,
                                              toward, guided)
            found.append((out[:k], counts[COUNT_NODE_PAIRS]))
        (plain, plain_work), (near_first, near_first_work) = found
        assert plain.shape[0] > 20
        assert not np.array_equal(plain, near_first)  # the order did change
        assert sorted(map(tuple, plain.tolist())) == sorted(map(tuple, near_first.tolist()))
        assert plain_work == near_first_work


def test_first_hit_descent_looks_near_the_last_frames_pair_first():
    """scan_frames' first-hit descent for a pair that touched at the frame before, when that
    frame's triangle pair no longer touches (discrete._pair_triangles given the pair):
    it finds an intersecting pair exactly when the exhaustive search finds any, one of
    those, and, looking near the last one first, tests fewer node pairs than a descent
    from the roots in its fixed order (a sphere sliding and turning through another)."""
    from collide.discrete import _pair_triangles, pair_scratch
    from collide.motion import MOTION_WIDTH
    from collide.narrow import new_stamps
    from collide.rows import COUNT_NODE_PAIRS, COUNT_WIDTH
    ps = _two_spheres()
    poses = _sliding_poses(60, 0.05)
    still, static = np.zeros((2, MOTION_WIDTH)), np.zeros(2, bool)
    world, stamp = np.empty((ps.world_start[2], 3)), new_stamps(ps.world_start[2])
    scratch, stack, leaves = pair_scratch(), np.empty((4, 2), np.int64), np.empty((4, 2), np.int64)

    def search(f, first_only, near):
        counts = np.zeros(COUNT_WIDTH, np.int64)
        *_, tri, n = _pair_triangles(ps, poses[f], still, f, 0, 1, 1e-9, static, stamp, world, first_only, near[0],
                                     near[1], scratch, stack, leaves, np.empty((4, 2), np.int64), counts)
        return set(map(tuple, tri[:n].tolist())), counts[COUNT_NODE_PAIRS]

    work = {"near": 0, "roots": 0}
    previous, compared = None, 0
    for f in range(poses.shape[0]):
        every, _ = search(f, False, (-1, -1))
        if previous is not None and previous not in every:
            for how, near in (("near", previous), ("roots", (-1, -1))):
                one, node_pairs = search(f, True, near)
                assert len(one) == min(len(every), 1) and one <= every
                work[how] += node_pairs
            compared += 1
        previous = search(f, True, previous or (-1, -1))[0].pop() if every else None
    assert compared >= 20
    assert work["near"] < 0.8 * work["roots"], work


def test_probe_gives_up_after_its_budget_of_leaf_pairs():
    """swept._probe_hit (a probe of swept._probed_window: the frame test's first-hit
    descent on a budget) reports an intersecting pair only if the exhaustive search has
    it, none after testing max_leaf_pairs leaf pairs (plus the rest of the batch that
    reached them) without finding one, and, with no limit, one whenever any exists; with
    no guide and with the last frame's pair as one."""
    from collide.discrete import _pair_triangles, pair_scratch
    from collide.motion import MOTION_WIDTH
    from collide.narrow import new_stamps
    from collide.rows import COUNT_LEAF_PAIRS, COUNT_WIDTH
    from collide.swept import Buffers, FrameTests, _probe_hit
    ps = _two_spheres()
    poses = _sliding_poses(30, 0.05)
    still, static = np.zeros((2, MOTION_WIDTH)), np.zeros(2, bool)
    n_world = ps.world_start[2]
    frame = FrameTests(np.empty((n_world, 3)), new_stamps(n_world), np.full(2, 1e-9 / 2), still)
    scratch = pair_scratch()

    def every_pair(f):
        counts = np.zeros(COUNT_WIDTH, np.int64)
        *_, tri, n = _pair_triangles(ps, poses[f], still, f, 0, 1, 1e-9, static, frame.stamp, frame.world, False, -1,
                                     -1, scratch, np.empty((4, 2), np.int64), np.empty((4, 2), np.int64),
                                     np.empty((4, 2), np.int64), counts)
        return set(map(tuple, tri[:n].tolist()))

    def probe(f, near, budget):
        counts = np.zeros(COUNT_WIDTH, np.int64)
        buffers = Buffers(*(np.empty((4, 2), np.int64) for _ in range(4)))
        _, tri_a, tri_b = _probe_hit(ps, poses[f], f, 0, 1, static, frame, near[0], near[1], scratch, buffers,
                                     counts, budget)
        return ({(tri_a, tri_b)} if tri_a >= 0 else set()), counts[COUNT_LEAF_PAIRS]

    gave_up, previous = 0, (-1, -1)
    for f in range(poses.shape[0]):
        every = every_pair(f)
        assert every
        for near in ((-1, -1), previous):
            found, _ = probe(f, near, np.iinfo(np.int64).max)
            assert len(found) == 1 and found <= every
            for budget in (1, 4, 16):
                found, tested = probe(f, near, budget)
                assert found <= every
                if not found:
                    gave_up += 1
                    assert tested < budget + 8  # FIRST_HIT_BATCH leaf pairs at a time
        previous = min(every)
    assert gave_up > 0  # some searches did give up
