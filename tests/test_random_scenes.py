"""Whole scans of small random scenes against independent references.

Discrete: every (frame, object pair) in contact, the triangle pair reported where each
contact begins and (with triangle_pairs) every intersecting triangle pair, against
brute force in exact rational arithmetic (naive.py) on the world vertices the scan
computes (packed.world_vertices).
Continuous: every sampled moment at which the moving meshes touch (screw motion by
scipy's matrix exponential, or straight vertex paths) lies in a reported interval of
its pair, every frame contact does too, and each interval begins where its pair is
touching (python-fcl distance).
Reading the poses a few frames at a time, with two workers, or scanning on a local Dask
cluster changes no contact.

The scenes are made to hit the hard cases often: boxes, flat squares and triangle
soups with repeated or collinear corners, on a 1/8 grid; most discrete scenes are
posed by signed axis permutations and grid translations, so faces touch exactly, lie
in one plane or meet at an edge or a vertex; some objects stay at the identity pose
throughout (static objects, tested once). A few seeds run by default, hundreds under
``-m slow``.
"""
import itertools

import numpy as np
import pytest
from conftest import meshes_touch, quaternion_rotation, rigid_transform, rotation_about, write_trajectory
from naive import triangle_pairs_exact

import collide
from collide import config
from collide.packed import world_vertices

BOX_FACES = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
#: a sampled contact may lie this far (in frames) outside the reported interval: the
#: samples' poses are rounded differently from the scan's
SLACK = 1e-9
ONE_SIDED_LEAVES = config.ONE_SIDED_LEAVES  #: the default (some tests draw it or 0)


def seed_blocks(default, slow_blocks, block):
    """Parameters for a test over seeds: range(default) by default, then ``slow_blocks``
    blocks of ``block`` seeds under the slow marker."""
    return [range(default)] + [pytest.param(range(default + k * block, default + (k + 1) * block),
                                            marks=pytest.mark.slow, id=f"slow{k}") for k in range(slow_blocks)]


# --- scenes -------------------------------------------------------------------------------------

def box(rng):
    extents = rng.integers(1, 9, 3) / 8.0
    centre = rng.integers(-4, 5, 3) / 8.0
    corners = np.array(list(itertools.product([0.0, 1.0], repeat=3)))
    return corners * extents + centre - extents / 2, BOX_FACES.copy()


def square(rng):
    side = rng.integers(1, 9) / 8.0
    corners = np.array([[0.0, 0, 0], [side, 0, 0], [side, side, 0], [0, side, 0]]) - side / 2
    return corners, np.array([[0, 1, 2], [0, 2, 3]])


def soup(rng):
    """1-6 separate triangles on the grid, some with a repeated or a collinear corner."""
    n = int(rng.integers(1, 7))
    vertices = rng.integers(-6, 7, (3 * n, 3)) / 8.0
    for i in range(n):
        kind = rng.random()
        if kind < 0.15:
            vertices[3 * i + 1] = vertices[3 * i]
        elif kind < 0.3:
            vertices[3 * i + 2] = 0.5 * (vertices[3 * i] + vertices[3 * i + 1])
    return vertices, np.arange(3 * n).reshape(n, 3)


def rotation(rng, grid):
    """A signed axis permutation (grid) or a uniformly random rotation (3, 3)."""
    if grid:
        r = np.eye(3)[rng.permutation(3)] * rng.choice([-1.0, 1.0], 3)[:, None]
        return r if np.linalg.det(r) > 0 else -r
    q = rng.normal(size=4)
    return quaternion_rotation(q / np.linalg.norm(q))


def random_meshes(rng):
    n_objects = int(rng.integers(2, 5))
    return {f"m{i}": (box, square, soup)[rng.integers(3)](rng) for i in range(n_objects)}


def keep_some_static(rng, matrix):
    """Objects 0 and 1 each stay at the identity pose with probability 0.4."""
    for o in range(min(2, matrix.shape[1])):
        if rng.random() < 0.4:
            matrix[:, o] = np.eye(4)
    return matrix


def jumping_scene(rng, n_frames=4):
    """Meshes and a trajectory of unrelated poses (for frame tests)."""
    meshes = random_meshes(rng)
    grid = rng.random() < 0.6
    matrix = np.zeros((n_frames, len(meshes), 4, 4))
    matrix[..., 3, 3] = 1.0
    for k, o in itertools.product(range(n_frames), range(len(meshes))):
        matrix[k, o, :3, :3] = rotation(rng, grid)
        matrix[k, o, :3, 3] = rng.integers(-6, 7, 3) / 8.0 if grid else rng.uniform(-0.7, 0.7, 3)
    return meshes, {"time": np.arange(n_frames, dtype=float), "names": list(meshes),
                    "matrix": keep_some_static(rng, matrix)}


def moving_scene(rng, n_frames=4, max_turn_deg=60.0):
    """Meshes and a trajectory turning up to ``max_turn_deg`` degrees and moving up to 0.4
    per frame."""
    meshes = random_meshes(rng)
    matrix = np.zeros((n_frames, len(meshes), 4, 4))
    for o in range(len(meshes)):
        pose = rigid_transform(rotation_about(rng.normal(size=3), rng.uniform(0, np.pi)), rng.uniform(-0.5, 0.5, 3))
        for k in range(n_frames):
            matrix[k, o] = pose
            step = rigid_transform(rotation_about(rng.normal(size=3), rng.uniform(0, np.radians(max_turn_deg))),
                                   rng.uniform(-0.4, 0.4, 3))
            pose = step @ pose
    return meshes, {"time": np.arange(n_frames, dtype=float), "names": list(meshes),
                    "matrix": keep_some_static(rng, matrix)}


# --- references ---------------------------------------------------------------------------------

def exact_frame_contacts(meshes, trajectory):
    """{(frame, a, b): every intersecting (tri_a, tri_b), sorted} by exact brute force."""
    names, matrix = trajectory["names"], trajectory["matrix"]
    found = {}
    for k in range(matrix.shape[0]):
        world = [world_vertices(meshes[name][0], matrix[k, o, :3]) for o, name in enumerate(names)]
        for a, b in itertools.combinations(range(len(names)), 2):
            pairs = triangle_pairs_exact(world[a], meshes[names[a]][1], world[b], meshes[names[b]][1])
            if pairs:
                found[(k, a, b)] = pairs
    return found


def motion_of(matrix, k, o, interpolation):
    """The world vertices of object o along step k, as a function of (body vertices (V, 3),
    fraction t of the step): screw motion by scipy's matrix logarithm and exponential, or
    straight paths between the frames' vertices."""
    if interpolation == "screw":
        import scipy.linalg
        twist = np.real(scipy.linalg.logm(matrix[k + 1, o] @ np.linalg.inv(matrix[k, o])))

        def at(vertices, t):
            m = scipy.linalg.expm(t * twist) @ matrix[k, o]
            return np.ascontiguousarray(vertices @ m[:3, :3].T + m[:3, 3])
        return at

    def along_chords(vertices, t):
        start, end = world_vertices(vertices, matrix[k, o, :3]), world_vertices(vertices, matrix[k + 1, o, :3])
        return np.ascontiguousarray((1 - t) * start + t * end)
    return along_chords


def sampled_contacts(meshes, trajectory, interpolation, samples):
    """[(time in frames, a, b)] at which the moving meshes touch, ``samples`` per step."""
    names, matrix = trajectory["names"], trajectory["matrix"]
    faces = [np.ascontiguousarray(meshes[name][1], dtype=np.int64) for name in names]
    found = []
    for k in range(matrix.shape[0] - 1):
        motions = [motion_of(matrix, k, o, interpolation) for o in range(len(names))]
        for s in range(samples + 1):
            world = [motions[o](meshes[name][0], s / samples) for o, name in enumerate(names)]
            for a, b in itertools.combinations(range(len(names)), 2):
                if meshes_touch(world[a], faces[a], world[b], faces[b]):
                    found.append((k + s / samples, a, b))
    return found


def gap(fcl, vertices_a, faces_a, vertices_b, faces_b):
    """Distance between two triangle sets in world coordinates (python-fcl)."""
    from fcl_poses import fcl_model

    from collide.load import Mesh
    objects = [fcl.CollisionObject(fcl_model(fcl, Mesh("", None, v, f)), fcl.Transform())
               for v, f in ((vertices_a, faces_a), (vertices_b, faces_b))]
    return fcl.distance(*objects, fcl.DistanceRequest(), fcl.DistanceResult())


def has_flat_triangle(vertices, faces):
    corners = vertices[faces]
    return (np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
            < 1e-9).any()


# --- tests --------------------------------------------------------------------------------------

@pytest.mark.parametrize("seeds", seed_blocks(8, 4, 250))
def test_discrete_scan_matches_exact_brute_force(seeds):
    positives = 0
    for seed in seeds:
        rng = np.random.default_rng(seed)
        meshes, trajectory = jumping_scene(rng)
        result = collide.scan(meshes, trajectory, mode="discrete", workers=int(rng.integers(1, 3)),
                              triangle_pairs=bool(rng.random() < 0.5))
        c = result.contacts
        expected = exact_frame_contacts(meshes, trajectory)
        found = {(k, a, b) for a, b, first, last in zip(c["object_a"].tolist(), c["object_b"].tolist(),
                                                        c["frame_begin"].tolist(), c["frame_end"].tolist())
                 for k in range(first, last + 1)}
        assert found == set(expected), (seed, sorted(found ^ set(expected)))
        for a, b, first, tri_a, tri_b in zip(c["object_a"], c["object_b"], c["frame_begin"], c["tri_a"], c["tri_b"]):
            assert (tri_a, tri_b) == expected[(first, a, b)][0], (seed, first, a, b)   # the smallest
        if result.triangle_pairs is not None:   # every intersecting pair, in (frame, a, b, tri_a, tri_b) order
            t = result.triangle_pairs
            rows = list(zip(*(t[name].tolist() for name in ("frame", "object_a", "object_b", "tri_a", "tri_b"))))
            assert rows == sorted((*key, *pair) for key, pairs in expected.items() for pair in pairs), seed
        # intervals are maximal: one pair's intervals are separated by frames apart
        for (a, b), rows in itertools.groupby(sorted(zip(c["object_a"].tolist(), c["object_b"].tolist(),
                                                         c["frame_begin"].tolist(), c["frame_end"].tolist())),
                                              key=lambda row: row[:2]):
            rows = list(rows)
            assert all(later[2] > earlier[3] + 1 for earlier, later in zip(rows, rows[1:])), (seed, rows)
        positives += len(expected)
    assert positives >= len(seeds) // 2   # the scenes touch often: the checks above are not empty


@pytest.mark.parametrize("interpolation, search", [("screw", "searches-at-once"), ("screw", "one-sided-in-time-order"),
                                                   ("screw", "probed"), ("screw", "best-first"),
                                                   ("linear-vertex", "searches-at-once"),
                                                   ("linear-vertex", "one-sided-in-time-order")])
@pytest.mark.parametrize("seeds", seed_blocks(2, 2, 250))
def test_continuous_scan_holds_every_sampled_contact(seeds, interpolation, search, monkeypatch):
    """Every contact of the motion sampled 30 times per step lies in a reported interval,
    and so does every frame contact; where an interval begins its pair touches (python-fcl's
    distance). Searches of one end of a contact: all candidates at once, in time order
    however few leaf pairs (config.ONE_SIDED_LEAVES = 0), or, however small the meshes
    (config.PROBED_FACES = 0; screw motion only), starting with probes (meshes with leaf
    boxes) or best first (none: config.LEAF_BOX_TRIANGLES = 0). Those two turn at most 2
    degrees per frame (faster turns take sub-steps, which search the whole step); they
    also agree with the whole search to within the time tolerance, and each block of
    seeds has one where they change the work (so they ran)."""
    fcl = pytest.importorskip("fcl")
    pytest.importorskip("scipy")
    one_end = search in ("probed", "best-first")
    if search == "one-sided-in-time-order":
        monkeypatch.setattr(config, "ONE_SIDED_LEAVES", 0)
    elif one_end:
        monkeypatch.setattr(config, "PROBED_FACES", 0)
        if search == "best-first":
            monkeypatch.setattr(config, "LEAF_BOX_TRIANGLES", 0)
    sampled_total = searched = 0
    for seed in seeds:
        rng = np.random.default_rng(seed)
        meshes, trajectory = moving_scene(rng, max_turn_deg=2.0 if one_end else 60.0)
        names = trajectory["names"]
        workers = int(rng.integers(1, 3))
        result = collide.scan(meshes, trajectory, mode="continuous", interpolation=interpolation, warn_angle=180,
                              workers=workers)
        c = result.contacts
        if one_end:
            with monkeypatch.context() as patch:
                patch.setattr(config, "PROBED_FACES", 10 ** 9)
                whole = collide.scan(meshes, trajectory, mode="continuous", warn_angle=180, workers=workers)
            searched += whole.stats["work"] != result.stats["work"]
            for name in ("object_a", "object_b", "frame_begin", "frame_end"):
                np.testing.assert_array_equal(c[name], whole.contacts[name], err_msg=f"{seed} {name}")
            for name in ("t_begin", "t_end"):
                np.testing.assert_allclose(c[name], whole.contacts[name], rtol=0, atol=config.TIME_TOL + 1e-15,
                                           err_msg=f"{seed} {name}")

        def covered(time, a, b):
            return ((c["object_a"] == a) & (c["object_b"] == b) & (c["t_begin"] <= time + SLACK)
                    & (time - SLACK <= c["t_end"])).any()
        sampled = sampled_contacts(meshes, trajectory, interpolation, samples=30)
        for time, a, b in sampled:
            assert covered(time, a, b), (seed, time, a, b)
        frame = collide.scan(meshes, trajectory, mode="discrete").contacts
        for a, b, first, last in zip(frame["object_a"], frame["object_b"], frame["frame_begin"], frame["frame_end"]):
            for k in range(first, last + 1):
                assert covered(float(k), a, b), (seed, k, a, b)
        # no invented contact: where an interval begins (or a time tolerance later) its pair touches
        matrix, n_steps = trajectory["matrix"], trajectory["matrix"].shape[0] - 1
        for a, b, begin in zip(c["object_a"], c["object_b"], c["t_begin"]):
            (va, fa), (vb, fb) = meshes[names[a]], meshes[names[b]]
            if has_flat_triangle(va, fa) or has_flat_triangle(vb, fb):
                continue   # python-fcl's distance is not defined for them
            k = min(int(begin), n_steps - 1)
            move_a, move_b = motion_of(matrix, k, a, interpolation), motion_of(matrix, k, b, interpolation)
            gaps = [gap(fcl, move_a(va, t), fa, move_b(vb, t), fb)
                    for t in (begin - k, min(begin - k + config.TIME_TOL, 1.0))]
            assert min(gaps) < 1e-6, (seed, a, b, begin, gaps)
        sampled_total += len(sampled)
    assert sampled_total > 0
    assert searched > 0 or not one_end


@pytest.mark.parametrize("seeds", seed_blocks(4, 1, 300))
def test_pose_blocks_and_workers_leave_the_contacts_unchanged(seeds, tmp_path, monkeypatch):
    """Poses read from the file two or three frames at a time (each block also holds the
    next one's first frame), with two workers: the same contacts, bit for bit, as one
    block in memory with one worker."""
    from collide.load import POSE_VALUES
    for seed in seeds:
        rng = np.random.default_rng(seed)
        meshes, trajectory = moving_scene(rng, n_frames=7)
        mode = "continuous" if rng.random() < 0.7 else "discrete"
        interpolation = "linear-vertex" if rng.random() < 0.3 else "screw"
        monkeypatch.setattr(config, "ONE_SIDED_LEAVES", 0 if rng.random() < 0.5 else ONE_SIDED_LEAVES)
        whole = collide.scan(meshes, trajectory, mode=mode, interpolation=interpolation, warn_angle=180,
                             workers=1).contacts
        path = write_trajectory(tmp_path / f"t{seed}.h5", trajectory["time"], trajectory["names"],
                                matrix=trajectory["matrix"])
        frames_per_block = int(rng.integers(2, 4))
        with monkeypatch.context() as patch:
            patch.setattr(config, "POSE_BLOCK_BYTES", frames_per_block * len(meshes) * POSE_VALUES * 8)
            blocked = collide.scan(meshes, path, mode=mode, interpolation=interpolation, warn_angle=180,
                                   workers=2).contacts
        for name, column in whole.items():
            np.testing.assert_array_equal(blocked[name], column, err_msg=f"seed {seed}, {name}")


@pytest.mark.parametrize("seeds", seed_blocks(4, 1, 300))
def test_frame_contacts_from_the_discrete_scan_give_the_same_contacts(seeds, monkeypatch):
    """--triangle-pairs takes a continuous scan's frame contacts from the discrete scan
    instead of finding them in the swept kernel: the same contacts, bit for bit, with the
    searches of one end of a contact in time order or not (config.ONE_SIDED_LEAVES)."""
    for seed in seeds:
        rng = np.random.default_rng(seed)
        meshes, trajectory = moving_scene(rng, n_frames=6)
        interpolation = "linear-vertex" if rng.random() < 0.3 else "screw"
        monkeypatch.setattr(config, "ONE_SIDED_LEAVES", 0 if rng.random() < 0.5 else ONE_SIDED_LEAVES)
        found = collide.scan(meshes, trajectory, mode="continuous", interpolation=interpolation, warn_angle=180)
        given = collide.scan(meshes, trajectory, mode="continuous", interpolation=interpolation, warn_angle=180,
                             triangle_pairs=True)
        for name, column in found.contacts.items():
            np.testing.assert_array_equal(given.contacts[name], column, err_msg=f"seed {seed}, {name}")


@pytest.mark.parametrize("seeds", seed_blocks(3, 1, 300))
def test_a_dask_cluster_finds_the_same_contacts(seeds):
    """The same scans as tasks on a local Dask cluster (two single-thread workers in this
    process): the same contacts, bit for bit, in both modes, with and without
    triangle_pairs."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        for seed in seeds:
            rng = np.random.default_rng(seed)
            meshes, trajectory = moving_scene(rng, n_frames=5)
            options = {"mode": ("continuous", "discrete")[rng.integers(2)], "warn_angle": 180,
                       "triangle_pairs": bool(rng.random() < 0.3)}
            local = collide.scan(meshes, trajectory, workers=1, **options)
            remote = collide.scan(meshes, trajectory, scheduler=cluster.scheduler_address, **options)
            for name, column in local.contacts.items():
                np.testing.assert_array_equal(remote.contacts[name], column, err_msg=f"seed {seed}, {name}")
            if options["triangle_pairs"]:
                for name, column in local.triangle_pairs.items():
                    np.testing.assert_array_equal(remote.triangle_pairs[name], column, err_msg=f"seed {seed}, {name}")
