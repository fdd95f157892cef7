"""Continuous mode on scenes whose contact times are known exactly.

All coordinates and times are dyadic rationals, so the exact contact times below are
exact for the float64 inputs too. SPEC §3: t_begin <= exact <= t_begin + tol and
t_end >= exact >= t_end - tol, with tol = time_tol * frame interval.
"""
import math

import h5py
import numpy as np
import pytest
from conftest import identity_quaternions, rotation_about, write_box, write_trajectory

import collide
from collide import config


def scene(tmp_path, boxes, mover, z_or_pos, times):
    """boxes: {name: (extents, centre)} static meshes plus the mover's mesh; the mover
    follows positions z_or_pos (T, 3)."""
    meshes = tmp_path / "meshes"
    meshes.mkdir(exist_ok=True)
    for name, (extents, centre) in boxes.items():
        write_box(meshes / f"{name}.stl", extents, centre)
    pos = np.asarray(z_or_pos, dtype=float)[:, None, :]
    traj = write_trajectory(tmp_path / "traj.h5", times, [mover], pos,
                            identity_quaternions(len(times), 1))
    return meshes, traj


def test_a_short_one_worker_scan_is_one_kernel_call_that_tests_its_first_frame(tmp_path, monkeypatch):
    """Each kernel call costs a little on its own (its buffers, pages of the meshes' size):
    a short scan with one worker makes one call of the step kernel, which runs the frame
    tests itself, the first frame's included, and none of the frame kernel."""
    from collide import pipeline
    calls = {"scan_intervals": 0, "scan_frames": 0}
    for name in calls:
        def counted(*args, kernel=getattr(pipeline, name), name=name):
            calls[name] += 1
            return kernel(*args)
        monkeypatch.setattr(pipeline, name, counted)
    z = np.linspace(-1.0, 1.0, 40)
    meshes, traj = scene(tmp_path, {"plate": ((10, 10, 0.125), (0, 0, 0)), "cube": ((0.25,) * 3, (0, 0, 0))},
                         "cube", [[0, 0, v] for v in z], np.arange(40.0))
    c = collide.scan(meshes, traj, workers=1).contacts
    calls_made = dict(calls)
    # the cube touches the plate while |z| <= 3/16: frames 17 to 22 (z = -0.18 ... 0.18)
    touching = np.flatnonzero(np.abs(z) <= 3 / 16)
    assert c["frame_begin"].tolist() == [touching[0] - 1] and c["frame_end"].tolist() == [touching[-1]]
    assert calls_made["scan_intervals"] == 2  # the kernels' compile (or cache load) call, then the scan's
    assert calls_made["scan_frames"] == 1  # the compile call only


def check_interval(c, k, begin, end, dt, time_tol=config.TIME_TOL):
    tol = time_tol * dt
    assert c["t_begin"][k] <= begin <= c["t_begin"][k] + tol, (c["t_begin"][k], begin)
    assert c["t_end"][k] >= end >= c["t_end"][k] - tol, (c["t_end"][k], end)


def test_fast_cube_through_thin_plate_tunnels_in_discrete_mode(tmp_path):
    # plate: z in [-1/16, 1/16]; cube of side 1/4 moving z from -4 to 4 within one frame step
    meshes, traj = scene(tmp_path, {"plate": ((10, 10, 0.125), (0, 0, 0)), "cube": ((0.25,) * 3, (0, 0, 0))},
                         "cube", [[0, 0, -4.0], [0, 0, 4.0]], [0.0, 2.0])
    assert collide.scan(meshes, traj, mode="discrete").contacts["t_begin"].size == 0
    c = collide.scan(meshes, traj).contacts                         # continuous is the default
    assert c["t_begin"].size == 1 and c["kind"].tolist() == [1]
    # top face z = -3.875 + 8u reaches -1/16 at u = 0.4765625; bottom face -4.125 + 8u leaves
    # 1/16 at u = 0.5234375; times are 2u
    check_interval(c, 0, 2 * 0.4765625, 2 * 0.5234375, dt=2.0)
    assert c["frame_begin"].tolist() == [0] and c["frame_end"].tolist() == [0]
    assert abs(c["point_z"][0] + 1 / 16) < 1e-5                     # contact at the plate's bottom face


def test_crossing_rods_touch_edge_to_edge(tmp_path):
    # rod a along x (static), rod b along y moving down in z: edges meet first
    h = 0.0625
    meshes, traj = scene(tmp_path, {"a": ((4, 2 * h, 2 * h), (0, 0, 0)), "b": ((2 * h, 4, 2 * h), (0, 0, 0))},
                         "b", [[0, 0, 1.0], [0, 0, -1.0]], [0.0, 1.0])
    c = collide.scan(meshes, traj).contacts
    check_interval(c, 0, (1 - 2 * h) / 2, (1 + 2 * h) / 2, dt=1.0)
    assert c["kind"].tolist() == [1]


def test_repeated_crossings_give_one_interval_each(tmp_path):
    z = [-1.0, 1.0, -1.0, 1.0, -1.0]
    meshes, traj = scene(tmp_path, {"plate": ((10, 10, 0.125), (0, 0, 0)), "cube": ((0.25,) * 3, (0, 0, 0))},
                         "cube", [[0, 0, v] for v in z], [0.0, 0.5, 1.0, 1.5, 2.0])
    c = collide.scan(meshes, traj).contacts
    assert c["t_begin"].size == 4 and set(c["kind"].tolist()) == {1}
    # moving up (-1 -> 1 over 0.5 s): touch while |z| <= 3/16 -> u in [13/32, 19/32]
    for k in range(4):
        lo, hi = 13 / 32, 19 / 32
        check_interval(c, k, 0.5 * (k + lo), 0.5 * (k + hi), dt=0.5)
        assert c["frame_begin"][k] == k


def test_near_miss_by_two_ten_thousandths_of_the_scene_is_not_reported(tmp_path):
    # the cube passes beside the plate's edge (x = 5) with a gap of 0.02 % of the scene size
    size = np.sqrt(10.25 ** 2 + 10 ** 2 + 8.25 ** 2)
    gap = 2e-4 * size
    x = 5 + 0.125 + gap
    meshes, traj = scene(tmp_path, {"plate": ((10, 10, 0.125), (0, 0, 0)), "cube": ((0.25,) * 3, (0, 0, 0))},
                         "cube", [[x, 0, -4.0], [x, 0, 4.0]], [0.0, 1.0])
    assert collide.scan(meshes, traj).contacts["t_begin"].size == 0
    # and the same path moved onto the edge does touch (grazing)
    touching = tmp_path / "touching"
    touching.mkdir()
    meshes2, traj2 = scene(touching, {"plate": ((10, 10, 0.125), (0, 0, 0)), "cube": ((0.25,) * 3, (0, 0, 0))},
                           "cube", [[5.125, 0, -4.0], [5.125, 0, 4.0]], [0.0, 1.0])
    c = collide.scan(meshes2, traj2).contacts
    check_interval(c, 0, (4 - 0.125 - 0.0625) / 8, (4 + 0.125 + 0.0625) / 8, dt=1.0)


def test_no_motion_equals_discrete(tmp_path, two_boxes):
    meshes, traj = two_boxes
    discrete = collide.scan(meshes, traj, mode="discrete").contacts
    # the same scene, continuous: the mover's steps (0.5 apart) also touch between frames,
    # entering at x = -1 exactly (a frame) and leaving at x = 1 (a frame)
    cont = collide.scan(meshes, traj).contacts
    assert cont["kind"].tolist() == [0]
    assert cont["t_begin"][0] <= discrete["t_begin"][0] and cont["t_end"][0] >= discrete["t_end"][0]
    check_interval(cont, 0, 0.4, 0.8, dt=0.1)


def test_still_touching_objects_stay_in_contact(tmp_path):
    """A box resting on the plate (faces touching exactly) and sliding along it: one interval."""
    xs = np.linspace(-2, 2, 9)
    meshes, traj = scene(tmp_path, {"plate": ((10, 10, 0.125), (0, 0, 0)), "cube": ((0.25,) * 3, (0, 0, 0))},
                         "cube", [[x, 0, 0.1875] for x in xs], np.arange(9) * 0.25)
    c = collide.scan(meshes, traj).contacts
    assert c["t_begin"].tolist() == [0.0] and c["t_end"].tolist() == [2.0] and c["kind"].tolist() == [0]


def test_time_tol_option_changes_the_precision(tmp_path):
    meshes, traj = scene(tmp_path, {"plate": ((10, 10, 0.125), (0, 0, 0)), "cube": ((0.25,) * 3, (0, 0, 0))},
                         "cube", [[0, 0, -4.0], [0, 0, 4.0]], [0.0, 1.0])
    c = collide.scan(meshes, traj, time_tol=1e-3).contacts
    check_interval(c, 0, 0.4765625, 0.5234375, dt=1.0, time_tol=1e-3)


def _without_frame_contacts(monkeypatch):
    """Make scan search every step of every pair in full, as if the frame tests had found
    nothing."""
    from collide import pipeline
    original = pipeline.frame_contacts

    def nothing_known(hits, static, n_objects):
        keys, tris = original(hits, static, n_objects)
        return keys[:0], tris[:0]
    monkeypatch.setattr(pipeline, "frame_contacts", nothing_known)


@pytest.mark.parametrize("one_sided", [False, True], ids=["searches-at-once", "one-sided-in-time-order"])
@pytest.mark.parametrize("interpolation", ["screw", "linear-vertex"])
def test_frame_contacts_spare_searches_with_the_same_contacts(tmp_path, monkeypatch, interpolation, one_sided):
    """A box slides along a bar that bounces and turns, and the bar hits a post: contacts
    lasting several frames each (five intervals). Steps touching at both frames are not
    searched, steps touching at one frame are searched for the other end only; the
    contacts equal those of the full certified search of every step, with less work
    (the --triangle-pairs path, which takes the frame contacts from the discrete scan
    rather than from the swept kernel, with those contacts hidden from the swept
    kernel). With ``one_sided``, every search for one end opens its leaf pairs in time
    order (config.ONE_SIDED_LEAVES = 0), which must not change a bit either."""
    if one_sided:
        monkeypatch.setattr(config, "ONE_SIDED_LEAVES", 0)
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    write_box(meshes / "bar.stl", extents=(4.0, 0.5, 0.5))
    write_box(meshes / "box.stl", extents=(0.5, 0.5, 0.5))
    write_box(meshes / "post.stl", extents=(0.25, 0.25, 2.0), centre=(0.0, 1.5, 0.0))
    n = 40
    t = np.arange(n) * 0.05
    position = np.zeros((n, 2, 3))
    position[:, 0, 0] = np.linspace(-1.5, 1.5, n)          # box slides along the bar, overlapping it
    position[:, 0, 1] = 0.4
    position[:, 1, 1] = 1.2 + 0.6 * np.sin(7.0 * t)       # bar bounces against the post
    orientation = identity_quaternions(n, 2)
    angle = 0.3 * np.sin(3.0 * t)                            # the bar turns about z
    orientation[:, 1, 0] = np.cos(angle / 2)
    orientation[:, 1, 3] = np.sin(angle / 2)
    traj = write_trajectory(tmp_path / "traj.h5", t, ["box", "bar"], position, orientation)
    fast = collide.scan(meshes, traj, mode="continuous", interpolation=interpolation)
    with monkeypatch.context() as patch:
        _without_frame_contacts(patch)
        full = collide.scan(meshes, traj, mode="continuous", interpolation=interpolation, triangle_pairs=True)
    assert fast.contacts["object_a"].size == 5
    for name, column in full.contacts.items():
        np.testing.assert_array_equal(fast.contacts[name], column, err_msg=name)
    assert fast.stats["work"]["ccd_queries"] < full.stats["work"]["ccd_queries"]


def _wavy_plate(n, height, sign=1.0):
    """A square surface of 2 n^2 triangles over [-1, 1]^2 at z = sign * height(x, y)."""
    import trimesh
    xs = np.linspace(-1.0, 1.0, n + 1)
    x, y = np.meshgrid(xs, xs, indexing="ij")
    vertices = np.stack([x.ravel(), y.ravel(), sign * height(x, y).ravel()], axis=-1)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * (n + 1) + j).ravel()
    faces = np.concatenate([np.stack([a, a + n + 1, a + 1], -1), np.stack([a + 1, a + n + 1, a + n + 2], -1)])
    return trimesh.Trimesh(vertices, faces, process=False)


def _chattering_plates(tmp_path, n_frames, turn_deg, clear=0.02):
    """A wavy plate (ground, static) and a lid of nearly its shape above it (2 x 40^2
    triangles each), the lid pressed 0.02 into the ground at even frames and lifted
    ``clear`` clear of it at odd ones (pressed in at all frames if negative), sliding 0.01
    and turning turn_deg about z per frame: at every step a contact over much of the
    plates ends or begins."""
    def ground(x, y):
        return 0.1 * np.sin(3.0 * x) * np.sin(2.0 * y)

    def lid(x, y):  # the ground's shape plus ripples of 0.03: the gap varies by 0.06 over the lid
        return ground(x, y) + 0.03 * np.sin(5.0 * x + 1.0) * np.cos(4.0 * y)

    meshes = tmp_path / "meshes"
    meshes.mkdir()
    _wavy_plate(40, ground).export(meshes / "ground.ply")
    plate = _wavy_plate(40, lid)
    plate.export(meshes / "lid.ply")
    angle = np.radians(turn_deg) * np.arange(n_frames)
    shift = 0.01 * np.arange(n_frames)
    matrix = np.tile(np.eye(4), (n_frames, 1, 1, 1))
    for k in range(n_frames):
        c, s = np.cos(angle[k]), np.sin(angle[k])
        matrix[k, 0, :2, :2] = [[c, -s], [s, c]]
        world = plate.vertices @ matrix[k, 0, :3, :3].T
        world[:, 0] += shift[k]
        gap = world[:, 2] - ground(world[:, 0], world[:, 1])  # lid over ground at z offset 0
        matrix[k, 0, :3, 3] = [shift[k], 0.0, -gap.min() + (-0.02 if k % 2 == 0 else clear)]
    traj = write_trajectory(tmp_path / "traj.h5", 0.01 * np.arange(n_frames), ["lid"], matrix=matrix)
    return meshes, traj


@pytest.mark.parametrize("interpolation", ["screw", "linear-vertex"])
def test_contact_ending_or_beginning_over_a_large_patch_is_searched_in_time_order(tmp_path, monkeypatch,
                                                                                    interpolation):
    """A lid pressed into a plate and lifted off it at every other frame: each step searches
    when a contact over hundreds of leaf pairs ends (begins). Those searches open the leaf
    pairs in the order they can meet and stop at the contact (config.ONE_SIDED_LEAVES):
    the same contacts, bit for bit, as the same scan trying every candidate at once (the
    threshold raised above any search), with under half the triangle pairs tested (the
    swept descent's check of leaf normals already spares the reference most of the pairs
    apart) and the same certified searches; the same again with two workers and through the
    --triangle-pairs path (frame contacts from the discrete scan)."""
    meshes, traj = _chattering_plates(tmp_path, 7, 0.5 if interpolation == "screw" else 0.0)
    ordered = collide.scan(meshes, traj, mode="continuous", interpolation=interpolation, workers=1)
    with monkeypatch.context() as patch:
        patch.setattr(config, "ONE_SIDED_LEAVES", 10 ** 9)
        at_once = collide.scan(meshes, traj, mode="continuous", interpolation=interpolation, workers=1)
    c = ordered.contacts
    assert c["t_begin"].size == 4  # frames 0, 2, 4, 6, each touching into the steps around it
    assert (c["t_begin"][1:] < 0.01 * np.array([2, 4, 6])).all()  # begins inside the steps, not at frames
    assert (c["t_end"][:3] > 0.01 * np.array([0, 2, 4])).all()
    work, reference_work = ordered.stats["work"], at_once.stats["work"]
    assert work["triangle_pairs"] < reference_work["triangle_pairs"] / 2
    assert work["ccd_pairs"] == reference_work["ccd_pairs"] and work["ccd_queries"] == reference_work["ccd_queries"]
    for other in (at_once,
                  collide.scan(meshes, traj, mode="continuous", interpolation=interpolation, workers=2),
                  collide.scan(meshes, traj, mode="continuous", interpolation=interpolation, triangle_pairs=True)):
        for name, column in c.items():
            np.testing.assert_array_equal(other.contacts[name], column, err_msg=name)


def _screw_poses(m0, m1, samples):
    """Poses (samples + 1, 4, 4) at fractions s / samples of the screw motion from m0 to
    m1 (4, 4), by scipy's matrix logarithm and exponential."""
    from scipy import linalg
    twist = np.real(linalg.logm(m1 @ np.linalg.inv(m0)))
    return np.stack([linalg.expm(s / samples * twist) @ m0 for s in range(samples + 1)])


@pytest.mark.parametrize("turn_deg", [0.0, 0.5])
@pytest.mark.parametrize("search", ["probed", "best-first"])
def test_search_for_one_end_of_a_patch_lifting_off_keeps_every_sampled_contact(tmp_path, monkeypatch, search,
                                                                               turn_deg):
    """A lid pressed into a plate and lifted off it at every other frame, each end of a
    contact searched for on its own (config.PROBED_FACES lowered below the plates' 3 200
    triangles). "probed" (the plates have leaf boxes): frame tests inside each step find
    a moment the plates touch, and the swept descent covers only the rest of the step.
    "best-first" (no leaf boxes: config.LEAF_BOX_TRIANGLES = 0): node pairs taken in the
    order their windows reach the contact found, not a whole swept descent. Against the
    discrete scan of the same motion sampled 64 times per step (scipy's screw
    interpolation; an exact predicate at each sample): every sampled contact lies in a
    reported interval, and each interval's ends lie within a sample (plus the time
    tolerance) of the sampled ones. Against the same scan with a whole descent: the same
    intervals to within the time tolerance, with fewer leaf pairs tested; with two
    workers and through --triangle-pairs, the same output bit for bit."""
    if search == "best-first":
        monkeypatch.setattr(config, "LEAF_BOX_TRIANGLES", 0)
    meshes, traj = _chattering_plates(tmp_path, 7, turn_deg)
    with h5py.File(traj, "r") as f:
        matrix = f["poses/matrix"][:]
        dt = float(f["time"][1] - f["time"][0])
    with monkeypatch.context() as patch:
        patch.setattr(config, "PROBED_FACES", 10 ** 9)
        plain = collide.scan(meshes, traj, mode="continuous", workers=1)
    monkeypatch.setattr(config, "PROBED_FACES", 0)
    searched = collide.scan(meshes, traj, mode="continuous", workers=1)
    c = searched.contacts
    assert c["t_begin"].size == 4
    tol = config.TIME_TOL * dt
    for name in ("t_begin", "t_end"):
        np.testing.assert_allclose(c[name], plain.contacts[name], rtol=0, atol=tol + 1e-15, err_msg=name)
    assert searched.stats["work"]["leaf_pairs"] < plain.stats["work"]["leaf_pairs"] / 2
    for other in (collide.scan(meshes, traj, mode="continuous", workers=2),
                  collide.scan(meshes, traj, mode="continuous", triangle_pairs=True)):
        for name, column in c.items():
            np.testing.assert_array_equal(other.contacts[name], column, err_msg=name)

    samples = 64
    poses = np.concatenate([_screw_poses(matrix[k, 0], matrix[k + 1, 0], samples)[:-1]
                            for k in range(matrix.shape[0] - 1)] + [matrix[-1:, 0]])
    times = dt * np.arange(poses.shape[0]) / samples
    sampled = write_trajectory(tmp_path / "sampled.h5", times, ["lid"], matrix=poses[:, None])
    reference = collide.scan(meshes, sampled, mode="discrete").contacts
    assert reference["t_begin"].size == 4  # one run of touching samples per interval
    step = dt / samples
    for k in range(4):
        begin, end = c["t_begin"][k], c["t_end"][k]
        first, last = reference["t_begin"][k], reference["t_end"][k]
        assert begin <= first + 1e-12 and first - step <= begin + tol, (k, begin, first)
        assert end >= last - 1e-12 and end <= last + step + tol, (k, end, last)


def _record_frame_hits(monkeypatch):
    """A list that gets, per scan, the sorted (frame, a, b) of the kernel's frame tests' hits."""
    from collide import pipeline
    from collide.rows import HIT_A, HIT_B, HIT_FRAME
    frames_touching = []
    run_steps = pipeline._run_steps

    def recording(*args, **kwargs):
        hits, *rest = run_steps(*args, **kwargs)
        frames_touching.append(sorted(map(tuple, hits[:, [HIT_FRAME, HIT_A, HIT_B]].tolist())))
        return (hits, *rest)
    monkeypatch.setattr(pipeline, "_run_steps", recording)
    return frames_touching


@pytest.mark.parametrize("search", ["probed", "best-first"])
@pytest.mark.parametrize("backwards", [False, True], ids=["contact-begins", "contact-ends"])
def test_search_for_one_end_follows_the_arc_below_the_chord(monkeypatch, search, backwards):
    """A thin rod (0.004 x 0.004 x 1, 768 triangles) over a flat static plate turns by 0.1
    radian about a horizontal axis through its middle while sinking by 6e-4: its tip
    starts 3e-4 above the plate and ends 3e-4 in it, but on the way it swings down by 6e-4
    below the straight line between its two ends, so it reaches the plate at about a
    tenth of the step, not at half of it. Backwards (the same motion reversed), the
    contact ends at about nine tenths. Each end is searched on its own
    (config.PROBED_FACES = 0; best first without leaf boxes). Reference: the lowest corner
    of the rod along the exact screw motion (scipy's matrix exponential): the first (last)
    moment it reaches the plate, and the first (last) it comes within the distance
    tolerance of it (scene size below 10), by bisection on a grid of 2 001 moments: t_begin
    lies between the latter less the time tolerance and the former, t_end likewise after.
    A search whose node windows left out the arc (no deviation bound) answers about 0.54
    (0.46)."""
    import trimesh
    from scipy import linalg, optimize
    monkeypatch.setattr(config, "PROBED_FACES", 0)
    if search == "best-first":
        monkeypatch.setattr(config, "LEAF_BOX_TRIANGLES", 0)
    rod = trimesh.creation.box(extents=(0.004, 0.004, 1.0)).subdivide().subdivide().subdivide()
    corners = np.array([[x, y, -0.5] for x in (-0.002, 0.002) for y in (-0.002, 0.002)])  # the tip's
    plate = _wavy_plate(20, lambda x, y: 0.0 * x)
    poses = []
    for angle, height in ((-0.05, 3e-4), (0.05, -3e-4)):
        pose = np.eye(4)
        pose[:3, :3] = rotation_about([0.0, 1.0, 0.0], angle)
        pose[:3, 3] = [0.3, 0.0, height - (corners @ pose[:3, :3].T)[:, 2].min()]  # lowest corner at height
        poses.append(pose)
    if backwards:
        poses.reverse()
    matrix = np.stack([np.stack([np.eye(4), pose]) for pose in poses])
    meshes = {"plate": (np.asarray(plate.vertices), np.asarray(plate.faces)),
              "rod": (np.asarray(rod.vertices), np.asarray(rod.faces))}
    c = collide.scan(meshes, {"time": np.array([0.0, 1.0]), "names": ["plate", "rod"], "matrix": matrix},
                     mode="continuous", workers=1).contacts
    twist = np.real(linalg.logm(poses[1] @ np.linalg.inv(poses[0])))

    def lowest(t):  # the rod's lowest point (a tip corner: the rod is convex) at fraction t
        pose = linalg.expm(t * twist) @ poses[0]
        return (corners @ pose[:3, :3].T + pose[:3, 3])[:, 2].min()
    grid = np.linspace(0.0, 1.0, 2001)
    heights = np.array([lowest(t) for t in grid])

    def reaching(level):  # the first (backwards: last) moment the rod's lowest point is at level
        below = np.flatnonzero(heights <= level)
        k = below.max() if backwards else below.min() - 1
        return optimize.brentq(lambda t: lowest(t) - level, grid[k], grid[k + 1], xtol=1e-14)
    touching, near = reaching(0.0), reaching(10.0 * config.DIST_TOL_REL)
    if backwards:
        assert 0.8 < touching < 0.95 and c["t_begin"].tolist() == [0.0]
        assert touching - 1e-12 <= c["t_end"][0] <= near + config.TIME_TOL
    else:
        assert 0.05 < touching < 0.2 and c["t_end"].tolist() == [1.0]
        assert near - config.TIME_TOL <= c["t_begin"][0] <= touching + 1e-12


@pytest.mark.parametrize("clear", [0.02, -0.01], ids=["lifted-at-odd-frames", "pressed-throughout"])
def test_probed_search_whose_probes_all_give_up_is_the_plain_search(tmp_path, monkeypatch, clear):
    """With config.PROBE_LEAF_PAIRS = 0 every probe gives up at once, and so does the frame
    test at a step's end of a pair apart at its start (which then takes the search
    without probes, its frame test from the swept leaf pairs): each probed search then
    covers the whole step, from the step's poses (the sub-screw over [0, 1] is the
    step's own), and the output equals the scan without probes bit for bit (and so do
    the frames found touching), both when contact ends or begins in every step and when
    the plates touch throughout."""
    frames_touching = _record_frame_hits(monkeypatch)
    meshes, traj = _chattering_plates(tmp_path, 7, 0.5, clear)
    with monkeypatch.context() as patch:
        patch.setattr(config, "PROBED_FACES", 10 ** 9)
        plain = collide.scan(meshes, traj, mode="continuous")
    monkeypatch.setattr(config, "PROBED_FACES", 0)
    monkeypatch.setattr(config, "PROBE_LEAF_PAIRS", 0)
    gave_up = collide.scan(meshes, traj, mode="continuous")
    assert plain.contacts["t_begin"].size == (4 if clear > 0 else 1)
    for name, column in plain.contacts.items():
        np.testing.assert_array_equal(gave_up.contacts[name], column, err_msg=name)
    if clear > 0:
        assert gave_up.stats["work"]["object_pairs"] > plain.stats["work"]["object_pairs"]  # the probes ran
    else:  # touching at both ends of every step: nothing to search, no probe, no extra work
        assert gave_up.stats["work"] == plain.stats["work"]
    assert len(frames_touching) == 2 and frames_touching[0] == frames_touching[1]
    assert len(frames_touching[0]) == (4 if clear > 0 else 7)  # the frames the lid is pressed in


@pytest.mark.parametrize("clear", [0.02, -0.01], ids=["lifted-at-odd-frames", "pressed-throughout"])
def test_frame_tests_on_a_budget_that_give_up_change_no_contact(tmp_path, monkeypatch, clear):
    """Between big meshes without leaf boxes (config.LEAF_BOX_TRIANGLES = 0: the ends of a
    contact are searched best first) apart at a step's start, the frame test at its end
    runs on a budget of leaf pairs (config.PROBE_LEAF_PAIRS). With a budget of 0 every such test gives
    up at once, and the pair takes the search without it (its frame test from the swept
    leaf pairs, the beginning of a contact found by the whole search rather than best
    first): the same frames found touching, and the same contacts to within the time
    tolerance, as with the default budget, both when contact ends or begins in every step
    and when the plates touch throughout (then nothing is searched, and the work is the
    same)."""
    frames_touching = _record_frame_hits(monkeypatch)
    monkeypatch.setattr(config, "LEAF_BOX_TRIANGLES", 0)
    meshes, traj = _chattering_plates(tmp_path, 7, 0.5, clear)
    with h5py.File(traj, "r") as f:
        dt = float(f["time"][1] - f["time"][0])
    monkeypatch.setattr(config, "PROBED_FACES", 0)
    budgeted = collide.scan(meshes, traj, mode="continuous")
    monkeypatch.setattr(config, "PROBE_LEAF_PAIRS", 0)
    gave_up = collide.scan(meshes, traj, mode="continuous")
    assert budgeted.contacts["t_begin"].size == (4 if clear > 0 else 1)
    for name, column in budgeted.contacts.items():
        if name in ("t_begin", "t_end"):
            np.testing.assert_allclose(gave_up.contacts[name], column, rtol=0, atol=config.TIME_TOL * dt + 1e-15)
        elif name in ("object_a", "object_b", "frame_begin", "frame_end", "kind"):
            np.testing.assert_array_equal(gave_up.contacts[name], column, err_msg=name)
    if clear > 0:  # the frame tests that gave up leave contacts that begin to the whole search
        assert gave_up.stats["work"]["leaf_pairs"] > budgeted.stats["work"]["leaf_pairs"]
    else:  # touching at both ends of every step: nothing to search, no budget, no extra work
        assert gave_up.stats["work"] == budgeted.stats["work"]
    assert len(frames_touching) == 2 and frames_touching[0] == frames_touching[1]
    assert len(frames_touching[0]) == (4 if clear > 0 else 7)  # the frames the lid is pressed in


def test_frame_contacts_are_keyed_by_frame_and_pair():
    from collide.pipeline import frame_contacts
    from collide.rows import HIT_TRI_A, HIT_TRI_B, HIT_WIDTH
    from collide.swept import step_pair_key
    # (frame, a, b): pair (0, 1) at frames 2, 0, 1 (unsorted), pair (1, 2) at frame 1; static pair (2, 3)
    found = [(2, 0, 1), (0, 0, 1), (1, 0, 1), (1, 1, 2), (0, 2, 3), (1, 2, 3)]
    hits = np.zeros((len(found), HIT_WIDTH), np.int64)
    hits[:, :3] = found
    hits[:, HIT_TRI_A] = np.arange(len(found))
    hits[:, HIT_TRI_B] = 10 + np.arange(len(found))
    keys, tris = frame_contacts(hits, np.array([False, False, True, True]), 4)
    assert keys.tolist() == sorted(step_pair_key(k, a, b, 4) for k, a, b in found[:4])
    assert tris.tolist() == [[1, 11], [2, 12], [3, 13], [0, 10]]


def _triangle_distance(p, q):
    """Distance between two triangles (3, 3) by python-fcl (a peer library); <= 0 when
    they intersect."""
    fcl = pytest.importorskip("fcl")

    def body(t):
        model = fcl.BVHModel()
        model.beginModel(3, 1)
        model.addSubModel(np.ascontiguousarray(t), np.array([[0, 1, 2]]))
        model.endModel()
        return fcl.CollisionObject(model, fcl.Transform())
    return fcl.distance(body(p), body(q), fcl.DistanceRequest(), fcl.DistanceResult())


def test_moving_window_holds_every_moment_the_triangles_come_close():
    """windows.swept_window against sampling with python-fcl's triangle distance:
    wherever two linearly moving triangles come within the margin, t lies inside the
    window. A third of the pairs are nearly parallel faces a small gap apart (where the
    normal axes, not the boxes, decide), a third edges crossing a small gap apart
    (where the edges' cross products decide)."""
    from collide.windows import swept_window
    rng = np.random.default_rng(11)
    samples = np.linspace(0.0, 1.0, 201)
    inside = empty = 0
    for k in range(180):
        p0 = rng.normal(size=(3, 3))
        if k % 3 == 2:
            q0 = _edge_crossing(p0, rng.uniform(-0.2, 0.2), rng)
            p1 = p0 + rng.normal(size=3) * 0.2 + rng.normal(size=(3, 3)) * 0.02
            q1 = q0 + rng.normal(size=3) * 0.2
        elif k % 3 == 1:
            normal = np.cross(p0[1] - p0[0], p0[2] - p0[0])
            normal /= np.linalg.norm(normal)
            q0 = p0 + normal * rng.uniform(-0.2, 0.2) + rng.normal(size=(3, 3)) * 0.02 + rng.normal(size=3) * 0.3
            p1 = p0 + rng.normal(size=3) * 0.3 + rng.normal(size=(3, 3)) * 0.02
            q1 = q0 + rng.normal(size=3) * 0.3
        else:
            q0 = rng.normal(size=(3, 3)) + rng.normal(size=3) * 2
            p1 = p0 + rng.normal(size=3) * 2 + rng.normal(size=(3, 3)) * 0.3
            q1 = q0 + rng.normal(size=3) * 2
        margin = abs(rng.normal()) * 0.05
        t_lo, t_hi = swept_window(p0, p1, q0, q1, margin)
        empty += t_lo > t_hi
        for t in samples:
            if _triangle_distance(p0 + t * (p1 - p0), q0 + t * (q1 - q0)) <= margin * (1 - 1e-9):
                inside += 1
                assert t_lo <= t <= t_hi, (k, t, t_lo, t_hi)
    assert inside > 0 and empty > 0


def _window_by_formula(p0, p1, q0, q1, margin):
    """windows.swept_window_of's documented formula in plain Python floats, one axis at a
    time, each operation in the kernel's order: the window along x, y, z, both normals
    and the nine edge cross products, each clipped from the blended extents at both ends
    of the step, widened by margin |n| and a few ulps."""
    ulps = 8.0 * 2.0 ** -52
    p0, p1, q0, q1 = ([[float(c) for c in corner] for corner in t] for t in (p0, p1, q0, q1))

    def clip(f0, f1, t_lo, t_hi):
        if f0 >= 0.0 and f1 >= 0.0:
            return t_lo, t_hi
        if f0 < 0.0 and f1 < 0.0:
            return 1.0, 0.0
        root = f0 / (f0 - f1)
        return (max(t_lo, root - 1e-12), t_hi) if f0 < 0.0 else (t_lo, min(t_hi, root + 1e-12))

    t_lo, t_hi = 0.0, 1.0
    for c in range(3):
        lo = [min(t[i][c] for i in range(3)) for t in (p0, p1, q0, q1)]
        hi = [max(t[i][c] for i in range(3)) for t in (p0, p1, q0, q1)]
        m = margin + ulps * max(max(abs(lo[0]), abs(hi[0]), abs(lo[1]), abs(hi[1])),
                                max(abs(lo[2]), abs(hi[2]), abs(lo[3]), abs(hi[3])))
        t_lo, t_hi = clip(hi[0] - lo[2] + m, hi[1] - lo[3] + m, t_lo, t_hi)
        t_lo, t_hi = clip(hi[2] - lo[0] + m, hi[3] - lo[1] + m, t_lo, t_hi)
        if t_lo > t_hi:
            return t_lo, t_hi
    size = max(abs(x) for t in (p0, p1, q0, q1) for corner in t for x in corner)

    def edge(t, i, j):
        return [t[j][c] - t[i][c] for c in range(3)]

    axes = [(edge(p0, 0, 1), edge(p0, 0, 2)), (edge(q0, 0, 1), edge(q0, 0, 2))]
    axes += [(edge(p0, i, (i + 1) % 3), edge(q0, j, (j + 1) % 3)) for i in range(3) for j in range(3)]
    for (ux, uy, uz), (vx, vy, vz) in axes:
        nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        length = math.sqrt(nx * nx + ny * ny + nz * nz)
        if not length > 0.0 or not math.isfinite(length):
            continue
        m = margin * length * (1.0 + ulps) + ulps * size * (abs(nx) + abs(ny) + abs(nz)) + 1e-300
        d = [[nx * x + ny * y + nz * z for x, y, z in t] for t in (p0, p1, q0, q1)]
        t_lo, t_hi = clip(max(d[0]) - min(d[2]) + m, max(d[1]) - min(d[3]) + m, t_lo, t_hi)
        t_lo, t_hi = clip(max(d[2]) - min(d[0]) + m, max(d[3]) - min(d[1]) + m, t_lo, t_hi)
        if t_lo > t_hi:
            return t_lo, t_hi
    return t_lo, t_hi


def test_moving_window_is_its_formula_to_the_last_bit():
    """windows.swept_window equals _window_by_formula exactly (the order in which a
    search tries triangle pairs, and so the last bits of contact times, follow from
    these windows), on triangles near each other, apart, nearly parallel, degenerate,
    collinear and nearly coincident, at scales from 1e-6 to 1e6."""
    from collide.windows import swept_window
    rng = np.random.default_rng(23)
    outcomes = set()
    for k in range(1500):
        scale = 10.0 ** rng.integers(-6, 7)
        p0 = rng.normal(size=(3, 3))
        kind = k % 5
        if kind == 1:
            p0[2] = p0[1]  # two corners equal
        elif kind == 2:
            p0[2] = 2 * p0[1] - p0[0]  # collinear
        q0 = p0 + rng.normal(size=(3, 3)) * 10.0 ** rng.uniform(-9, 0) + rng.normal(size=3) * rng.uniform(0, 1.5)
        if kind == 3:
            q0[1] = q0[0]
        p1 = p0 + rng.normal(size=3) * 0.1 + rng.normal(size=(3, 3)) * 0.01
        q1 = q0 + rng.normal(size=3) * 0.1
        p0, p1, q0, q1 = (t * scale for t in (p0, p1, q0, q1))
        margin = abs(rng.normal()) * 0.01 * scale
        window = swept_window(p0, p1, q0, q1, margin)
        assert window == _window_by_formula(p0, p1, q0, q1, margin), k
        outcomes.add((window[0] > window[1], window == (0.0, 1.0)))
    assert len(outcomes) == 3  # empty, the whole step and a part of it all occur


def _edge_crossing(p, gap, rng):
    """A triangle (3, 3) with an edge crossing p's first edge (p[0], p[1]) at its middle,
    ``gap`` away along their common normal, and its third corner beyond it."""
    e = p[1] - p[0]
    f = np.cross(e, rng.normal(size=3))
    f /= np.linalg.norm(f)
    s = np.cross(e, f)
    s /= np.linalg.norm(s)
    if np.dot(p[2] - p[0], s) > 0:
        s = -s  # p's third corner on the other side
    middle = 0.5 * (p[0] + p[1]) + gap * s
    return np.array([middle - f, middle + f, middle + s + 0.3 * rng.normal(size=3)])


def test_edge_axes_separate_crossing_edges_that_boxes_and_normals_do_not():
    """Two triangles whose edges cross 0.1 apart, tilted to every coordinate axis and
    sliding: the boxes and both normals overlap all along, the cross product of the
    two edges keeps them apart."""
    from collide.windows import swept_window
    rng = np.random.default_rng(3)
    p0 = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 0.2], [0.9, 0.1, -0.8]])
    q0 = _edge_crossing(p0, 0.1, rng)
    assert _triangle_distance(p0, q0) > 0.099
    slide = 0.2 * (p0[1] - p0[0])
    p1, q1 = p0 + slide, q0 + slide
    for t in np.linspace(0, 1, 11):
        p, q = p0 + t * (p1 - p0), q0 + t * (q1 - q0)
        assert (p.max(axis=0) >= q.min(axis=0)).all() and (q.max(axis=0) >= p.min(axis=0)).all()
        for n in (np.cross(p0[1] - p0[0], p0[2] - p0[0]), np.cross(q0[1] - q0[0], q0[2] - q0[0])):
            assert (p @ n).max() >= (q @ n).min() and (q @ n).max() >= (p @ n).min()
    t_lo, t_hi = swept_window(p0, p1, q0, q1, 0.05)
    assert t_lo > t_hi


def test_normal_axes_separate_close_parallel_faces_that_boxes_do_not():
    """Two parallel triangles tilted to every coordinate axis, 0.1 apart and sliding
    along their plane: their boxes overlap all along, their normals keep them apart."""
    from collide.windows import swept_window
    p0 = np.array([[0.0, 0.0, 0.0], [1.0, -1.0, 0.0], [1.0, 0.0, -1.0]])
    normal = np.cross(p0[1] - p0[0], p0[2] - p0[0])
    normal /= np.linalg.norm(normal)
    q0 = p0 + 0.1 * normal
    slide = p0[1] - p0[0]
    p1, q1 = p0 + 0.2 * slide, q0 - 0.2 * slide
    for t in np.linspace(0, 1, 11):
        p, q = p0 + t * (p1 - p0), q0 + t * (q1 - q0)
        assert (p.max(axis=0) >= q.min(axis=0)).all() and (q.max(axis=0) >= p.min(axis=0)).all()
    t_lo, t_hi = swept_window(p0, p1, q0, q1, 0.05)
    assert t_lo > t_hi
    t_lo, t_hi = swept_window(p0, p1, q0, q1, 0.11)  # within the margin: the whole step
    assert (t_lo, t_hi) == (0.0, 1.0)


def _random_pose(rng, centre, spread, angle):
    """A rigid pose [R | p] (3, 4): a turn by up to ``angle`` radians about a random axis,
    placed at centre + up to spread in each coordinate."""
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    theta = rng.uniform(0.0, angle)
    pose = np.empty((3, 4))
    pose[:, :3] = np.eye(3) + np.sin(theta) * k + (1 - np.cos(theta)) * (k @ k)
    pose[:, 3] = centre + rng.uniform(-spread, spread, 3)
    return pose


def test_swept_node_box_is_the_chord_box_to_the_last_bit():
    """broad._swept_node_box and _moving_node_box (centre, half extents and |R| computed
    once per box) equal the chord box motion.chord_interval_of computes axis by axis and
    pose by pose, widened by d, and the placed boxes of motion.world_interval_of, bit for
    bit: random boxes, turns and scales."""
    from collide.broad import _moving_node_box, _swept_node_box
    from collide.motion import chord_interval_of, pose_tuple, rotation_magnitudes, world_interval_of
    rng = np.random.default_rng(31)
    for k in range(300):
        scale = 10.0 ** rng.integers(-4, 5)
        lo = rng.normal(size=3) * scale
        box = tuple(lo) + tuple(lo + rng.uniform(0, 1, 3) * scale)
        rp0 = pose_tuple(_random_pose(rng, np.zeros(3), scale, np.pi))
        rp1 = pose_tuple(_random_pose(rng, np.zeros(3), scale, np.pi))
        d = rng.uniform(0, 1e-6) * scale
        expected = [chord_interval_of(box, rp0, rp1, i) for i in range(3)]
        expected = tuple(e[0] - d for e in expected) + tuple(e[1] + d for e in expected)
        abs0, abs1 = rotation_magnitudes(rp0), rotation_magnitudes(rp1)
        assert _swept_node_box(box, rp0, rp1, abs0, abs1, d) == expected
        moving = _moving_node_box(box, rp0, rp1, abs0, abs1)
        for c in range(3):
            assert moving[4 * c:4 * c + 2] == world_interval_of(box, rp0, c)
            assert moving[4 * c + 2:4 * c + 4] == world_interval_of(box, rp1, c)
            assert moving[12 + c] == max(abs(x) for x in moving[4 * c:4 * c + 4])


@pytest.mark.parametrize("seed", range(4))
def test_swept_descent_reuses_node_boxes_without_changing_what_it_finds(seed):
    """broad.swept_leaves, which carries the box of each node not yet opened down the
    stack, finds the same leaf pairs in the same order after testing the same node pairs
    as the plain tandem descent that recomputes both boxes for every pair
    (broad.overlapping_leaves under RULE_SWEPT): FCL's robot turning and sliding
    through its environment, screw and linear-vertex motion."""
    from conftest import DATA

    from collide.broad import RULE_SWEPT, overlapping_leaves, swept_leaves
    from collide.discrete import object_margins, pair_scratch, start_descent
    from collide.load import load_mesh
    from collide.motion import INTERPOLATIONS, MOTION_WIDTH, step_motions
    from collide.packed import pack_scene
    from collide.rows import COUNT_NODE_PAIRS, COUNT_WIDTH

    rng = np.random.default_rng(seed)
    env, rob = load_mesh(DATA / "env.obj"), load_mesh(DATA / "rob.obj")
    ps, _ = pack_scene([env, rob], np.array([0, 1]))
    centre = env.vertices.mean(axis=0)
    spread = 0.25 * np.ptp(env.vertices, axis=0)
    poses = np.array([[_random_pose(rng, 0.0, 0.0, 0.2), _random_pose(rng, centre, spread, np.pi)]
                      for _ in range(2)])
    poses[1, 1] = _random_pose(rng, poses[0, 1, :, 3], 0.05 * spread, 1.0)
    for interpolation in ("screw", "linear-vertex"):
        margin = np.empty(2)
        motion = np.empty((2, MOTION_WIDTH))
        object_margins(ps, poses[0], poses[1], margin)
        step_motions(INTERPOLATIONS[interpolation], poses[0], poses[1], margin, motion)
        found = []
        for descend in ("plain", "held"):
            scratch, stack = pair_scratch(), np.empty((4, 2), np.int64)
            top = start_descent(ps, poses[0], poses[1], motion, 0, 1, scratch, stack)
            counts = np.zeros(COUNT_WIDTH, np.int64)
            out = np.empty((4, 2), np.int64)
            if descend == "plain":
                _, _, out, k = overlapping_leaves(ps.node_lo, ps.node_hi, ps.node_first, ps.node_count, ps.leaf_box,
                                                  *ps.leaf_box_shift[ps.object_mesh], scratch.pose, scratch.motion,
                                                  RULE_SWEPT, 1e-9, stack, top, out, np.iinfo(np.int64).max, counts,
                                                  scratch.toward, False)
            else:
                _, _, out, k = swept_leaves(ps.node_lo, ps.node_hi, ps.node_first, ps.node_count, ps.leaf_box,
                                            *ps.leaf_box_shift[ps.object_mesh], scratch.pose, scratch.motion, False,
                                            1e-9, stack, top, out, counts)
            found.append((out[:k].copy(), counts.copy()))
        (plain, plain_counts), (held, held_counts) = found
        assert plain.shape[0] > 10 and plain_counts[COUNT_NODE_PAIRS] > 100
        np.testing.assert_array_equal(held, plain)
        np.testing.assert_array_equal(held_counts, plain_counts)


#: (turn in radians, slide as a share of the environment's size) of the environment, then of
#: the robot, over the step: both turning, one of them only, or neither
_STEP_MOTIONS = [((0.6, 0.02), (1.2, 0.1)), ((0.8, 0.0), (0.0, 0.01)), ((0.0, 0.01), (1.2, 0.0)),
                 ((0.3, 0.05), (0.3, 0.05)), ((0.0, 0.0), (0.0, 0.1))]


@pytest.mark.parametrize("seed", range(10))
def test_rigid_swept_descent_keeps_every_leaf_pair_that_overlaps_along_the_screws(seed):
    """broad.RULE_SWEPT_RIGID (each node's box placed in the other object's frame at both
    ends of the step, widened by rigid_frame_deviation; leaf pairs also checked along
    their normals) against sampling: at 81 moments of the step, both objects placed by
    their screw motions (motion.pose_at), every leaf pair with two triangles that meet
    there (exact predicate, brute force over the leaf pairs whose boxes overlap there:
    the frame test's RULE_POSE descent) is among the rigid descent's leaf pairs, and
    every leaf pair whose boxes overlap there among RULE_SWEPT's. FCL's robot and
    environment, turning (up to 1.2 radians) and sliding, both, one or neither of them
    (_STEP_MOTIONS); the robot starts inside the environment."""
    from conftest import DATA, meshes_touch

    from collide.broad import RULE_POSE, RULE_SWEPT, RULE_SWEPT_RIGID
    from collide.discrete import object_margins, pair_leaves, pair_scratch
    from collide.load import load_mesh
    from collide.motion import INTERPOLATIONS, MOTION_WIDTH, pose_at, step_motions
    from collide.packed import pack_scene, world_vertices
    from collide.rows import COUNT_WIDTH

    rng = np.random.default_rng(100 + seed)
    env, rob = load_mesh(DATA / "env.obj"), load_mesh(DATA / "rob.obj")
    ps, _ = pack_scene([env, rob], np.array([0, 1]))
    centre = env.vertices.mean(axis=0)
    spread = 0.2 * np.ptp(env.vertices, axis=0)
    poses = np.empty((2, 2, 3, 4))
    poses[0, 0] = _random_pose(rng, 0.0, 0.0, 0.3)
    poses[0, 1] = _random_pose(rng, centre, spread, np.pi)
    for o, (angle, shift) in enumerate(_STEP_MOTIONS[seed % len(_STEP_MOTIONS)]):
        turn = _random_pose(rng, 0.0, 0.0, angle) if angle else np.eye(3, 4)
        poses[1, o, :, :3] = turn[:, :3] @ poses[0, o, :, :3]
        poses[1, o, :, 3] = poses[0, o, :, 3] + rng.normal(scale=shift, size=3) * spread
    margin = np.empty(2)
    motion = np.empty((2, MOTION_WIDTH))
    object_margins(ps, poses[0], poses[1], margin)
    step_motions(INTERPOLATIONS["screw"], poses[0], poses[1], margin, motion)
    pair_margin = margin.sum() + 1e-9
    still = np.zeros((2, MOTION_WIDTH))

    def leaf_pairs(rp0, rp1, rows, rule):
        stack, leaves = np.empty((4, 2), np.int64), np.empty((4, 2), np.int64)
        _, leaves, n = pair_leaves(ps, rp0, rp1, rows, 0, 1, rule, pair_margin, pair_scratch(), stack, leaves,
                                   np.zeros(COUNT_WIDTH, np.int64))
        return set(map(tuple, leaves[:n].tolist()))

    rigid = leaf_pairs(poses[0], poses[1], motion, RULE_SWEPT_RIGID)
    world = leaf_pairs(poses[0], poses[1], motion, RULE_SWEPT)
    sampled = set()
    def leaf_faces(o, leaf):  # object o has mesh o
        return ps.faces[ps.face_start[o] + ps.prim_ids[ps.node_first[leaf]:ps.node_first[leaf] + ps.node_count[leaf]]]

    at = np.empty((2, 3, 4))
    touching = set()
    for t in np.linspace(0.0, 1.0, 81):
        for o in range(2):
            pose_at(motion[o], poses[0, o], poses[1, o], t, at[o])
        overlapping = leaf_pairs(at, at, still, RULE_POSE)
        sampled |= overlapping
        placed = [world_vertices(ps.vertices[ps.vert_start[o]:ps.vert_start[o + 1]], at[o]) for o in range(2)]
        touching |= {(la, lb) for la, lb in overlapping - touching
                     if meshes_touch(placed[0], leaf_faces(0, la), placed[1], leaf_faces(1, lb))}
    assert len(sampled) > 10 and touching  # the checks below are not empty
    assert touching <= rigid, sorted(touching - rigid)[:5]
    assert sampled <= world


@pytest.mark.parametrize("interpolation", ["screw", "linear-vertex"])
@pytest.mark.parametrize("seed", range(3))
def test_frame_tests_inside_the_swept_kernel_find_the_discrete_contacts(monkeypatch, seed, interpolation):
    """A continuous scan runs its frame tests inside the swept kernel (pipeline._run_steps):
    a pair's frame test at a step's last frame is skipped when the swept test finds the
    pair apart over the step (no leaf pair, or no triangle pair whose moving boxes come
    near), and otherwise runs on the swept leaf pairs. It must find
    exactly the (frame, pair) contacts of the discrete scan's own descents, and the same
    swept contacts as the scan that takes the frame contacts from the discrete scan
    (the --triangle-pairs path): FCL's robot, three copies turning and sliding through
    two overlapping static copies of its environment, 40 frames in blocks of 7 and chunks
    of 1, 4 and 64 steps, under both interpolations."""
    from conftest import DATA

    from collide import pipeline
    from collide.filters import build_filters
    from collide.load import PoseArray, load_mesh
    from collide.packed import pack_scene
    from collide.rows import HIT_A, HIT_B, HIT_FRAME, SWEPT_A, SWEPT_B, SWEPT_STEP

    rng = np.random.default_rng(seed)
    env, rob = load_mesh(DATA / "env.obj"), load_mesh(DATA / "rob.obj")
    ps, _ = pack_scene([env, rob], np.array([0, 0, 1, 1, 1]))
    centre = env.vertices.mean(axis=0)
    spread = 0.5 * np.ptp(env.vertices, axis=0)
    n_frames = 40
    poses = np.empty((n_frames, 5, 3, 4))
    poses[:, 0] = np.eye(3, 4)
    poses[:, 1] = _random_pose(rng, 0.05 * spread, 0.0, 0.3)
    for o in (2, 3, 4):
        poses[0, o] = _random_pose(rng, centre, spread, np.pi)
        for f in range(1, n_frames):
            turn = _random_pose(rng, 0.0, 0.0, 0.3)
            poses[f, o, :, :3] = turn[:, :3] @ poses[f - 1, o, :, :3]
            poses[f, o, :, 3] = poses[f - 1, o, :, 3] + rng.normal(scale=0.06, size=3) * spread
    static = np.array([True, True, False, False, False])
    filters = build_filters(["env", "env2", "rob", "rob2", "rob3"])
    dist_tol = config.DIST_TOL_REL * float(np.linalg.norm(np.ptp(env.vertices, axis=0)))

    def scan(continuous, pair_sink):
        source = PoseArray(poses)
        source.block = 7
        hits, ids, fractions, _ = pipeline._scan_blocks(ps, source, static, filters, pair_sink, continuous,
                                                        interpolation, config.TIME_TOL, dist_tol, 1, None)
        frame_pairs = sorted(map(tuple, hits[:, [HIT_FRAME, HIT_A, HIT_B]].tolist()))
        order = np.lexsort((ids[:, SWEPT_B], ids[:, SWEPT_A], ids[:, SWEPT_STEP]))
        return frame_pairs, ids[order][:, [SWEPT_STEP, SWEPT_A, SWEPT_B]], fractions[order]

    discrete, _, _ = scan(False, None)
    _, known_ids, known_fractions = scan(True, pipeline.TrianglePairs())
    whole = (known_fractions[:, 0] == 0.0) & (known_fractions[:, 1] == 1.0)
    assert len(discrete) > 100 and whole.sum() > 50 and (~whole).sum() > 10  # steps searched at one end or both
    touching = set(discrete)
    entering = [(f, a, b) for f, a, b in discrete if f > 0 and (f - 1, a, b) not in touching]
    assert len(entering) >= 5  # contacts found by the frame tests of pairs apart at the step's start
    for size in (1, 4, 64):
        with monkeypatch.context() as patch:
            patch.setattr(pipeline, "_chunk_size", lambda *args, size=size: size)
            frame_pairs, ids, fractions = scan(True, None)
        assert frame_pairs == discrete
        np.testing.assert_array_equal(ids, known_ids)
        np.testing.assert_array_equal(fractions, known_fractions)


def test_stable_order_is_numpys_stable_argsort():
    """The short-array insertion path and the merge sort path give numpy's stable order,
    ties (many, with -0.0 == 0.0) in index order."""
    from collide.narrow import stable_order
    rng = np.random.default_rng(4)
    for n in [0, 1, 2, 3, 5, 16, 17, 40]:
        for _ in range(20):
            floats = rng.choice([0.0, -0.0, 0.25, 0.5, 1.0, -1.0], size=n)
            ints = rng.integers(0, 4, size=n)
            for keys in (floats, ints):
                assert np.array_equal(stable_order(keys), np.argsort(keys, kind="stable")), keys


def test_leaf_pairs_leave_their_heap_in_numpys_stable_order():
    """The one-sided search takes its leaf pairs from a narrow.Pending heap keyed (key,
    index, 0): they come out in numpy's stable order, ties (many, with -0.0 == 0.0 and
    inf) in index order, whatever the number it takes; built in one pass
    (narrow.pending_of_keys) or pushed one by one."""
    from collide.narrow import new_pending, pending_of_keys, pending_pop, pending_push
    rng = np.random.default_rng(5)
    for n in [1, 2, 3, 7, 16, 17, 100, 1000]:
        for _ in range(10):
            keys = rng.choice([0.0, -0.0, 0.25, 0.5, 1.0, -1.0, np.inf], size=n)
            keys[rng.random(n) < 0.5] = rng.random()  # some distinct keys too
            heap = new_pending()
            for i in range(n):
                heap = pending_push(heap, keys[i], np.int64(i), np.int64(0))
            handed = [pending_pop(heap)[1] for i in range(n)]
            assert handed == list(np.argsort(keys, kind="stable")), keys
            built = pending_of_keys(keys, np.int64(n))  # the same rows, heap-ordered in one pass
            assert [pending_pop(built)[1] for i in range(n)] == handed, keys


def test_leaf_boxes_hold_their_triangles():
    """packed.oriented_leaf_boxes: orthonormal axes, the first along the leaf's summed
    normal, every corner of every triangle of the leaf inside the box and its range along
    the normal, that range tight (FCL's robot
    and environment, a sphere with degenerate triangles added: zero-area leaves get x, y
    and z)."""
    import trimesh
    from conftest import DATA

    from collide.load import load_mesh
    from collide.packed import LEAF_AXES, LEAF_CENTRE, LEAF_HALF, LEAF_NORMAL_HI, LEAF_NORMAL_LO, pack_scene
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=3.0)
    vertices = np.vstack([sphere.vertices, [[5.0, 5.0, 5.0], [5.0, 5.0, 5.0], [6.0, 6.0, 6.0]]])
    faces = np.vstack([sphere.faces, [[len(vertices) - 3, len(vertices) - 2, len(vertices) - 1]] * 5])
    meshes = [load_mesh(DATA / "env.obj"), load_mesh(DATA / "rob.obj"), trimesh.Trimesh(vertices, faces, process=False)]
    ps, _ = pack_scene(meshes, np.arange(3))
    checked = 0
    for m in range(3):
        nodes = range(ps.root[m], ps.root[m + 1] if m + 1 < 3 else ps.node_count.shape[0])
        for node in nodes:
            if ps.node_count[node] == 0:
                continue
            box = ps.leaf_box[node + ps.leaf_box_shift[m]]
            axes = box[LEAF_AXES:LEAF_AXES + 9].reshape(3, 3)
            np.testing.assert_allclose(axes @ axes.T, np.eye(3), atol=1e-12)
            tris = ps.prim_ids[ps.node_first[node]:ps.node_first[node] + ps.node_count[node]]
            corners = ps.vertices[ps.vert_start[m] + ps.faces[ps.face_start[m] + tris]]
            normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]).sum(axis=0)
            if np.linalg.norm(normal) > 0:
                assert np.dot(normal, axes[0]) > 0.999999 * np.linalg.norm(normal)
            offsets = (corners.reshape(-1, 3) - box[LEAF_CENTRE:LEAF_CENTRE + 3]) @ axes.T
            assert (np.abs(offsets) <= box[LEAF_HALF:LEAF_HALF + 3]).all(), node
            along = corners.reshape(-1, 3) @ axes[0]
            assert box[LEAF_NORMAL_LO] <= along.min() and along.max() <= box[LEAF_NORMAL_HI], node
            assert box[LEAF_NORMAL_HI] - box[LEAF_NORMAL_LO] <= np.ptp(along) + 1e-6 * (1 + np.abs(along).max())
            checked += 1
    assert checked > 1000


@pytest.mark.parametrize("seed", range(3))
def test_leaf_pairs_apart_along_their_normals_stay_apart(seed):
    """The rigid swept descent drops a leaf pair that its oriented boxes keep apart along
    either leaf's normal over the whole step (broad.leaves_apart_along_normals): FCL's
    robot turning and sliding near its environment. Every leaf pair it drops, and only
    those, would be kept without the leaf boxes; and each dropped pair is apart at 33
    moments of the step by python-fcl's exact distance between its triangles, placed by
    the screw motion itself (motion.pose_at). Many are dropped."""
    fcl = pytest.importorskip("fcl")
    from conftest import DATA

    from collide.broad import swept_leaves
    from collide.discrete import object_margins, pair_scratch, start_descent
    from collide.load import load_mesh
    from collide.motion import INTERPOLATIONS, MOTION_WIDTH, pose_at, step_motions
    from collide.packed import NO_LEAF_BOXES, pack_scene
    from collide.rows import COUNT_WIDTH

    rng = np.random.default_rng(seed)
    env, rob = load_mesh(DATA / "env.obj"), load_mesh(DATA / "rob.obj")
    ps, _ = pack_scene([env, rob], np.array([0, 1]))
    centre = env.vertices.mean(axis=0)
    spread = 0.25 * np.ptp(env.vertices, axis=0)
    dropped_total = kept_total = 0
    for _ in range(6):
        poses = np.array([[_random_pose(rng, 0.0, 0.0, 0.2), _random_pose(rng, centre, spread, np.pi)]
                          for _ in range(2)])
        poses[1, 1] = _random_pose(rng, poses[0, 1, :, 3], 0.02 * spread, 0.1)
        poses[1, 0] = _random_pose(rng, poses[0, 0, :, 3], 0.005 * spread, 0.02)
        margin = np.empty(2)
        motion = np.empty((2, MOTION_WIDTH))
        object_margins(ps, poses[0], poses[1], margin)
        step_motions(INTERPOLATIONS["screw"], poses[0], poses[1], margin, motion)
        found = []
        for shifts in (ps.leaf_box_shift[ps.object_mesh], (NO_LEAF_BOXES, NO_LEAF_BOXES)):
            scratch, stack = pair_scratch(), np.empty((4, 2), np.int64)
            top = start_descent(ps, poses[0], poses[1], motion, 0, 1, scratch, stack)
            out = np.empty((4, 2), np.int64)
            _, _, out, k = swept_leaves(ps.node_lo, ps.node_hi, ps.node_first, ps.node_count, ps.leaf_box, *shifts,
                                        scratch.pose, scratch.motion, True, margin[0] + margin[1] + 1e-9, stack, top,
                                        out, np.zeros(COUNT_WIDTH, np.int64))
            found.append({tuple(row) for row in out[:k]})
        kept, without = found
        assert kept <= without
        dropped = sorted(without - kept)
        dropped_total += len(dropped)
        kept_total += len(kept)
        for la, lb in dropped[:40]:
            corners = []  # each leaf's triangles' corners, (3 n, 3), body frame (object o has mesh o)
            for o, leaf in ((0, la), (1, lb)):
                tris = ps.prim_ids[ps.node_first[leaf]:ps.node_first[leaf] + ps.node_count[leaf]]
                corners.append(ps.vertices[ps.vert_start[o] + ps.faces[ps.face_start[o] + tris]].reshape(-1, 3))
            for t in np.linspace(0.0, 1.0, 33):
                objects = []
                for o, body in enumerate(corners):
                    pose = np.empty((3, 4))
                    pose_at(motion[o], poses[0, o], poses[1, o], t, pose)
                    model = fcl.BVHModel()
                    model.beginModel(len(body), len(body) // 3)
                    model.addSubModel(body @ pose[:, :3].T + pose[:, 3], np.arange(len(body)).reshape(-1, 3))
                    model.endModel()
                    objects.append(fcl.CollisionObject(model, fcl.Transform()))
                distance = fcl.distance(objects[0], objects[1], fcl.DistanceRequest(), fcl.DistanceResult())
                assert distance > 0.0, (la, lb, t)
    assert dropped_total > max(1000, 0.02 * (dropped_total + kept_total)), (dropped_total, kept_total)


@pytest.mark.parametrize("interpolation", ["screw", "linear-vertex"])
def test_leaf_boxes_change_no_contact(tmp_path, monkeypatch, interpolation):
    """The same contacts, bit for bit, with the leaf boxes' normal checks in the swept
    descent and without them (config.LEAF_BOX_TRIANGLES = 0: no mesh gets leaf boxes):
    the lid pressed into the wavy plate and lifted (contacts beginning and ending over a
    large patch) and FCL's robot passing through its environment; the checks drop leaf
    pairs (in the frame tests, and under screw motion in the swept descent too)."""
    from conftest import DATA
    meshes, traj = _chattering_plates(tmp_path, 5, 0.5 if interpolation == "screw" else 0.0)
    robot = tmp_path / "robot"
    robot.mkdir()
    for name in ("env.obj", "rob.obj"):
        (robot / name).write_bytes((DATA / name).read_bytes())
    rng = np.random.default_rng(3)
    n = 6
    matrix = np.tile(np.eye(4), (n, 1, 1, 1))
    for k in range(n):
        matrix[k, 0, :3, :3] = rotation_about([0.0, 0.0, 1.0], 0.05 * k)
        matrix[k, 0, :3, 3] = [-200.0 + 80.0 * k, 100.0, 0.0] + rng.normal(scale=5.0, size=3)
    robot_traj = write_trajectory(tmp_path / "robot.h5", 0.1 * np.arange(n), ["rob"], matrix=matrix)
    leaf_pairs = np.zeros(2, np.int64)
    for folder, trajectory in ((meshes, traj), (robot, robot_traj)):
        with_boxes = collide.scan(folder, trajectory, mode="continuous", interpolation=interpolation)
        with monkeypatch.context() as patch:
            patch.setattr(config, "LEAF_BOX_TRIANGLES", 0)
            without = collide.scan(folder, trajectory, mode="continuous", interpolation=interpolation)
        assert with_boxes.contacts["t_begin"].size > 0
        for name, column in without.contacts.items():
            np.testing.assert_array_equal(with_boxes.contacts[name], column, err_msg=name)
        leaf_pairs += [with_boxes.stats["work"]["leaf_pairs"], without.stats["work"]["leaf_pairs"]]
    assert leaf_pairs[0] < leaf_pairs[1], leaf_pairs
