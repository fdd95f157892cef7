"""Screw motion between frames (--interpolation screw, the default), against independent
references: the matrix exponential of the pose change (scipy), closed-form contact
angles of turning parts, and dense sampling of the motion with the exact predicate.

SPEC: t_begin <= exact first contact <= t_begin + tol and t_end >= exact last contact
>= t_end - tol, tol = time_tol * frame interval. Closed forms below are evaluated in
float64, hence a slack of 1e-12 of the frame interval on the conservative side.
"""
import logging

import numpy as np
import pytest
from conftest import meshes_touch, run_cli, write_box, write_trajectory
from conftest import rigid_transform as transform
from conftest import rotation_about as rot

import collide
from collide import config, motion
from collide.errors import InputError
from collide.load import load_mesh
from collide.predicates import triangles_intersect

scipy_linalg = pytest.importorskip("scipy.linalg")

SLACK = 1e-12


# --- references ---------------------------------------------------------------------------------

def screw_reference(t0, t1, t):
    """exp(t log(T1 T0^-1)) T0 by scipy's matrix logarithm and exponential (4, 4)."""
    twist = np.real(scipy_linalg.logm(t1 @ np.linalg.inv(t0)))
    return scipy_linalg.expm(t * twist) @ t0


def motion_row(t0, t1):
    row = np.zeros(motion.MOTION_WIDTH)
    assert motion.screw_motion(np.ascontiguousarray(t0[:3]), np.ascontiguousarray(t1[:3]), 0.0, row)
    return row


def apply(m, x):
    return x @ m[:3, :3].T + m[:3, 3]


def random_pose(rng, max_angle=np.radians(170)):
    return transform(rot(rng.normal(size=3), rng.uniform(0, max_angle)), rng.uniform(-5, 5, 3))


# --- the motion itself --------------------------------------------------------------------------

@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-4, 0.3, 1.5, 3.0, np.pi - 1e-6])
def test_screw_positions_match_the_matrix_exponential(angle):
    rng = np.random.default_rng(7)
    for _ in range(5):
        t0 = random_pose(rng)
        t1 = transform(rot(rng.normal(size=3), angle), rng.uniform(-3, 3, 3)) @ t0
        row = motion_row(t0, t1)
        assert row[motion.M_THETA] == pytest.approx(angle, abs=1e-9)
        body = rng.uniform(-2, 2, (6, 3))
        x0, x1 = apply(t0, body), apply(t1, body)
        out = np.empty_like(x0)
        for t in np.linspace(0, 1, 11):
            motion.points_at(row, x0, x1, t, out)
            expected = apply(screw_reference(t0, t1, t), body)
            # scipy's logm loses accuracy next to a half turn; collide's formula does not
            tol = 1e-7 if angle > 3.1 else 1e-10
            assert np.abs(out - expected).max() < tol * 10, (angle, t)
        motion.points_at(row, x0, x1, 1.0, out)
        assert np.array_equal(out, x1)          # frames are hit exactly


def test_screw_does_not_depend_on_the_body_origin():
    """Moving the body frame's origin (and the mesh with it) leaves world paths unchanged."""
    rng = np.random.default_rng(3)
    t0 = random_pose(rng)
    t1 = transform(rot([1, 2, 3], 1.2), [0.5, -1, 2]) @ t0
    shift = transform(np.eye(3), [7.0, -4.0, 2.5])      # body coordinates move by -shift
    body = rng.uniform(-1, 1, (5, 3))
    paths = []
    for a, b, pts in ((t0, t1, body), (t0 @ shift, t1 @ shift, body - shift[:3, 3])):
        row = motion_row(a, b)
        out = np.empty((5, 3))
        motion.points_at(row, apply(a, pts), apply(b, pts), 0.37, out)
        paths.append(out.copy())
    assert np.abs(paths[0] - paths[1]).max() < 1e-12


@pytest.mark.parametrize("angle", [0.01, 0.5, 1.4, 2.5])
def test_deviation_bound_holds_and_is_tight(angle):
    """Sampled distance between each point's path and its chord <= point_deviation, and
    the bound is not loose: within 10 % of the sagitta rho (1 - cos(theta / 2))."""
    rng = np.random.default_rng(11)
    for _ in range(4):
        t0 = random_pose(rng)
        t1 = transform(rot(rng.normal(size=3), angle), rng.uniform(-3, 3, 3)) @ t0
        row = motion_row(t0, t1)
        body = rng.uniform(-3, 3, (1, 3))
        x0, x1 = apply(t0, body), apply(t1, body)
        worst = 0.0
        out = np.empty_like(x0)
        for t in np.linspace(0, 1, 401):
            motion.points_at(row, x0, x1, t, out)
            worst = max(worst, float(np.linalg.norm(out - ((1 - t) * x0 + t * x1))))
        bound = motion.point_deviation(row, x0)
        assert worst <= bound
        if angle <= np.pi / 2:
            assert bound <= 1.1 * worst + 1e-12


def _pair_contact(rows, corners, limit, backwards):
    """motion.triangle_pair_contact of triangles p, q under motion rows (m_p, m_q), corners
    (p0, p1, q0, q1) (3, 3) each, with the default tolerances."""
    from collide.ccd import ccd_work
    m_p, m_q = rows
    p0, p1, q0, q1 = corners
    work = ccd_work()
    dev = motion.point_deviation(m_p, p0) + motion.point_deviation(m_q, q0)
    eta = m_p[motion.M_ETA] + m_q[motion.M_ETA]
    return motion.triangle_pair_contact(m_p, m_q, p0, p1, q0, q1, dev, eta, config.TIME_TOL, 1e-9, limit,
                                        backwards, work, work.counts)


@pytest.mark.parametrize("seed", range(3))
def test_contact_search_with_a_limit_keeps_every_sampled_contact(seed):
    """triangle_pair_contact searches only up to its limit (forwards) or from it on
    (backwards), on that part of the step alone, and culls sub-steps by their moving
    boxes and normals: against 401 samples of scipy's screw motion and the exact
    predicate, a forward answer is never after the first sampled contact and is found
    whenever one lies before the limit (backwards: never before the last, found whenever
    one lies after the limit), and an answer is a moment where the triangles are within
    a hair (python-fcl's distance)."""
    fcl = pytest.importorskip("fcl")
    rng = np.random.default_rng(100 + seed)
    body = {"p": rng.uniform(-0.8, 0.8, (3, 3)), "q": rng.uniform(-0.8, 0.8, (3, 3))}
    samples = np.linspace(0.0, 1.0, 401)
    checked = 0
    for _ in range(12):
        ends = {}
        for name in "pq":
            start = transform(rot(rng.normal(size=3), rng.uniform(0, np.pi)), rng.uniform(-0.4, 0.4, 3))
            ends[name] = (start, transform(rot(rng.normal(size=3), rng.uniform(0.05, 0.8)),
                                           rng.uniform(-0.4, 0.4, 3)) @ start)
        rows = tuple(motion_row(*ends[name]) for name in "pq")
        corners = tuple(np.ascontiguousarray(apply(ends[name][i], body[name])) for name in "pq" for i in (0, 1))

        twists = {name: np.real(scipy_linalg.logm(ends[name][1] @ np.linalg.inv(ends[name][0]))) for name in "pq"}

        def at(t):  # screw_reference, with each motion's logarithm taken once
            return tuple(apply(scipy_linalg.expm(t * twists[name]) @ ends[name][0], body[name]) for name in "pq")

        touching = samples[[bool(triangles_intersect(*at(t))) for t in samples]]
        for limit in (-np.inf, 0.25, 0.5, 0.75, np.inf):
            first = _pair_contact(rows, corners, limit, False)
            last = _pair_contact(rows, corners, limit, True)
            if touching.size:
                if touching[0] <= limit:
                    assert first <= touching[0] + SLACK, (limit, first, touching[0])
                if touching[-1] >= limit:
                    assert last >= touching[-1] - SLACK, (limit, last, touching[-1])
                assert first == np.inf or first <= touching[0] + SLACK
                assert last == -np.inf or last >= touching[-1] - SLACK
                checked += 1
            for t in (first, last):
                if np.isfinite(t):
                    tri_p, tri_q = at(min(max(t, 0.0), 1.0))
                    gap = fcl.distance(*(fcl.CollisionObject(_triangle_model(fcl, tri), fcl.Transform())
                                         for tri in (tri_p, tri_q)), fcl.DistanceRequest(), fcl.DistanceResult())
                    assert gap < 1e-6, (limit, t, gap)
    assert checked > 0  # the triangles are placed to touch in some of the motions


def _triangle_model(fcl, corners):
    model = fcl.BVHModel()
    model.beginModel(3, 1)
    model.addSubModel(np.asarray(corners, float), np.array([[0, 1, 2]]))
    model.endModel()
    return model


def test_half_turn_is_ambiguous():
    row = np.zeros(motion.MOTION_WIDTH)
    t0 = np.eye(4)
    t1 = transform(rot([0, 0, 1], np.pi), [1, 0, 0])
    assert not motion.screw_motion(t0[:3].copy(), t1[:3].copy(), 0.0, row)
    assert motion.screw_motion(t0[:3].copy(), transform(rot([0, 0, 1], np.pi - 1e-6), [1, 0, 0])[:3].copy(),
                               0.0, row)


# --- scenes with closed-form contact times -------------------------------------------------------

def rod_scene(tmp_path, angles, hub, offset, post_centre, post_half, post_z=(-0.5, 0.5), rod=(1.0, 0.02, 1.0),
              z_per_frame=0.0, blade=False, dt=1.0):
    """A rod (x_b in [0, L] (blade: [-L, L]), |y_b| <= w, |z_b| <= H) turning about the z axis
    through ``hub`` by ``angles`` (T,) radians, its mesh stored with its body origin moved by
    -offset, rising z_per_frame per frame; a static square post (half-size post_half in x and
    y, z in post_z) centred at hub + post_centre (x, y)."""
    length, w, height = rod
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    x_lo = -length if blade else 0.0
    write_box(meshes / "rod.stl", (length - x_lo, 2 * w, 2 * height),
              (0.5 * (length + x_lo) + offset[0], offset[1], offset[2]))
    centre = (hub[0] + post_centre[0], hub[1] + post_centre[1], hub[2] + 0.5 * (post_z[0] + post_z[1]))
    write_box(meshes / "post.stl", (2 * post_half, 2 * post_half, post_z[1] - post_z[0]), centre)
    n = len(angles)
    matrix = np.zeros((n, 1, 4, 4))
    for k, a in enumerate(angles):
        r = rot([0, 0, 1], a)
        rise = np.array([0.0, 0.0, z_per_frame * k])
        matrix[k, 0] = transform(r, np.asarray(hub) + rise - r @ np.asarray(offset))
    traj = write_trajectory(tmp_path / "traj.h5", np.arange(n) * dt, ["rod"], matrix=matrix)
    return meshes, traj


def contact_angles(meshes, hub, w):
    """First and last rod angle at which the rod's side faces (|y_b| <= w, a dyadic w) touch
    the square post (both prisms along z): a post corner at radius rho and polar angle beta
    about the hub meets the leading face y_b = w at beta - asin(w / rho) and leaves the
    trailing one at beta + asin(w / rho). Corners as stored in the mesh file (float32)."""
    corners = load_mesh(meshes / "post.stl").vertices[:, :2] - np.asarray(hub[:2])
    rho = np.hypot(corners[:, 0], corners[:, 1])
    beta = np.arctan2(corners[:, 1], corners[:, 0])
    return float((beta - np.arcsin(w / rho)).min()), float((beta + np.arcsin(w / rho)).max())


def check_interval(c, k, begin, end, dt, time_tol=config.TIME_TOL):
    tol = time_tol * dt
    assert c["t_begin"][k] <= begin + SLACK * dt and begin <= c["t_begin"][k] + tol + SLACK * dt, \
        (c["t_begin"][k], begin)
    assert c["t_end"][k] >= end - SLACK * dt and end >= c["t_end"][k] - tol - SLACK * dt, (c["t_end"][k], end)


@pytest.mark.parametrize("step_deg", [80.0, 150.0])
def test_rod_turning_about_its_end_hits_a_pin_beyond_the_chord(tmp_path, step_deg):
    """The pin lies on the rod's arc but outside the straight vertex paths: screw reports the
    closed-form time; linear-vertex (and discrete mode) reports nothing. The hub is off the
    origin and the body origin is not at the hub."""
    alpha = np.radians(step_deg)
    direction = 0.5 * alpha
    post = (0.9 * np.cos(direction), 0.9 * np.sin(direction))
    w = 1 / 64
    meshes, traj = rod_scene(tmp_path, [0.0, alpha], hub=(5.0, -3.0, 2.0), offset=(1.5, -0.25, 0.75),
                             post_centre=post, post_half=w, rod=(1.0, w, 1.0), dt=0.5)
    result = collide.scan(meshes, traj)
    assert result.interpolation == "screw"
    c = result.contacts
    assert c["t_begin"].size == 1 and c["kind"].tolist() == [1]
    first, last = contact_angles(meshes, (5.0, -3.0), w)
    check_interval(c, 0, 0.5 * first / alpha, 0.5 * last / alpha, dt=0.5)
    assert collide.scan(meshes, traj, interpolation="linear-vertex").contacts["t_begin"].size == 0
    assert collide.scan(meshes, traj, mode="discrete").contacts["t_begin"].size == 0


def test_spinning_blade_cuts_a_thin_post_twice(tmp_path):
    """A blade spinning about its centre 85 degrees per frame passes a thin post with one half
    (frames 1-2) and again with the other half (frames 3-4); no frame shows either."""
    alpha = np.radians(85.0)
    angles = alpha * np.arange(6)
    beta = np.radians(120.0)
    post = (0.8 * np.cos(beta), 0.8 * np.sin(beta))
    w = 1 / 128
    meshes, traj = rod_scene(tmp_path, angles, hub=(0.0, 0.0, 0.0), offset=(0.0, 0.0, 0.0), post_centre=post,
                             post_half=w, rod=(1.0, w, 1.0), blade=True)
    c = collide.scan(meshes, traj).contacts
    assert c["t_begin"].size == 2 and c["kind"].tolist() == [1, 1]
    first, last = contact_angles(meshes, (0.0, 0.0), w)
    for k, half_turns in enumerate((0, 1)):
        check_interval(c, k, (first + np.pi * half_turns) / alpha, (last + np.pi * half_turns) / alpha, dt=1.0)
    assert c["frame_begin"].tolist() == [1, 3]


def test_screw_along_its_axis(tmp_path):
    """Turning 60 degrees and rising 0.5 per frame (a helix): the thin rod (|z_b| <= 1/16)
    meets the post (z in [0.625, 0.75] above the hub) where its angular window [first, last]
    and its height window overlap; both prisms stand along the screw axis, so contact is
    exactly 'touching in plan and overlapping in height'."""
    alpha = np.radians(60.0)
    angles = alpha * np.arange(4)
    beta = np.radians(75.0)
    post = (0.7 * np.cos(beta), 0.7 * np.sin(beta))
    meshes, traj = rod_scene(tmp_path, angles, hub=(1.0, 2.0, 0.0), offset=(0.0, 0.0, 0.0), post_centre=post,
                             post_half=0.05, post_z=(0.625, 0.75), rod=(1.0, 1 / 64, 1 / 16), z_per_frame=0.5)
    c = collide.scan(meshes, traj).contacts
    first, last = contact_angles(meshes, (1.0, 2.0), 1 / 64)
    plan = (first / alpha, last / alpha)                      # in frames (dt = 1)
    height = ((0.625 - 1 / 16) / 0.5, (0.75 + 1 / 16) / 0.5)  # rod z = 0.5 t
    assert plan[0] < height[1] and height[0] < plan[1]          # the windows overlap
    assert c["t_begin"].size == 1
    check_interval(c, 0, max(plan[0], height[0]), min(plan[1], height[1]), dt=1.0)


@pytest.mark.parametrize("example", ["tunnel", "fixture-translation"])
def test_pure_translation_gives_identical_output(tmp_path, example):
    from conftest import REPO
    if example == "tunnel":
        meshes, traj = REPO / "examples" / "tunnel" / "meshes", REPO / "examples" / "tunnel" / "traj.h5"
    else:  # boxes sliding and crossing, no rotation
        meshes = tmp_path / "m"
        meshes.mkdir()
        write_box(meshes / "a.stl", (1, 1, 1))
        write_box(meshes / "b.stl", (0.5, 2, 0.25), (0.1, 0.2, 0.3))
        pos = np.zeros((7, 1, 3))
        pos[:, 0] = np.linspace([-3, 0.3, 0.1], [3, -0.2, 0.4], 7)
        matrix = np.tile(np.eye(4), (7, 1, 1, 1))
        matrix[:, 0, :3, 3] = pos[:, 0]
        traj = write_trajectory(tmp_path / "t.h5", np.arange(7.0), ["b"], matrix=matrix)
    screw = collide.scan(meshes, traj, interpolation="screw").contacts
    linear = collide.scan(meshes, traj, interpolation="linear-vertex").contacts
    assert screw["t_begin"].size > 0
    for name in screw:
        np.testing.assert_array_equal(screw[name], linear[name], err_msg=name)


# --- random motions against dense sampling -------------------------------------------------------

def sampled_contacts(mesh_a, mesh_b, poses_a, poses_b, samples):
    """Times (in frames) at which the meshes touch, sampled ``samples`` times per step under
    the screw motion as scipy's matrix exponential computes it."""
    hits = []
    for k in range(len(poses_a) - 1):
        for s in range(samples + 1):
            t = s / samples
            ta = screw_reference(poses_a[k], poses_a[k + 1], t)
            tb = screw_reference(poses_b[k], poses_b[k + 1], t)
            if meshes_touch(apply(ta, mesh_a.vertices), mesh_a.faces, apply(tb, mesh_b.vertices), mesh_b.faces):
                hits.append(k + t)
    return np.array(hits)


@pytest.mark.parametrize("seed", [0] + [pytest.param(s, marks=pytest.mark.slow) for s in range(1, 8)])
def test_random_turning_boxes_lose_no_sampled_contact(tmp_path, seed):
    """Two boxes turning up to 70 degrees per frame about random axes near each other:
    every sampled contact time of the screw motion lies in a reported interval, and each
    reported interval begins where the boxes are (nearly) touching."""
    fcl = pytest.importorskip("fcl")
    from fcl_poses import fcl_model

    from collide.load import load_mesh
    rng = np.random.default_rng(seed)
    meshes = tmp_path / "m"
    meshes.mkdir()
    write_box(meshes / "a.stl", (1.0, 0.3, 0.2))
    write_box(meshes / "b.stl", (0.8, 0.25, 0.4))
    n = 6
    poses = np.zeros((n, 2, 4, 4))
    for o in range(2):
        pose = transform(rot(rng.normal(size=3), rng.uniform(0, np.pi)), rng.uniform(-0.3, 0.3, 3))
        for k in range(n):
            poses[k, o] = pose
            pose = transform(rot(rng.normal(size=3), rng.uniform(0.3, np.radians(70))),
                             rng.uniform(-0.2, 0.2, 3)) @ pose
    traj = write_trajectory(tmp_path / "t.h5", np.arange(n, dtype=float), ["a", "b"], matrix=poses)
    c = collide.scan(meshes, traj).contacts
    mesh_a, mesh_b = load_mesh(meshes / "a.stl"), load_mesh(meshes / "b.stl")
    hits = sampled_contacts(mesh_a, mesh_b, poses[:, 0], poses[:, 1], samples=200)
    tol = config.TIME_TOL
    for t in hits:
        inside = (c["t_begin"] <= t + SLACK) & (t - SLACK <= c["t_end"])
        assert inside.any(), (t, c["t_begin"], c["t_end"])
    assert hits.size > 0       # the scene is built to touch: the check above is not empty
    # no invented contacts: at (or within tol after) each t_begin the boxes are within a hair
    model_a, model_b = fcl_model(fcl, mesh_a), fcl_model(fcl, mesh_b)
    for begin in c["t_begin"]:
        k = min(int(begin), n - 2)
        gaps = []
        for t in (begin - k, begin - k + tol):
            ta = screw_reference(poses[k, 0], poses[k + 1, 0], min(t, 1.0))
            tb = screw_reference(poses[k, 1], poses[k + 1, 1], min(t, 1.0))
            gaps.append(fcl.distance(fcl.CollisionObject(model_a, fcl.Transform(ta[:3, :3], ta[:3, 3])),
                                     fcl.CollisionObject(model_b, fcl.Transform(tb[:3, :3], tb[:3, 3])),
                                     fcl.DistanceRequest(), fcl.DistanceResult()))
        assert min(gaps) < 1e-5, (begin, gaps)   # the boxes move < 10 units per frame: 1e-6 of it


def _moved_poses(rng, centre, angle):
    """Poses (2, 3, 4) at both ends of a step: a random start near centre, then a turn of
    up to ``angle`` radians about a random axis and a small shift."""
    start = transform(rot(rng.normal(size=3), rng.uniform(0, np.pi)), centre + rng.uniform(-0.1, 0.1, 3))
    end = transform(rot(rng.normal(size=3), rng.uniform(0, angle)), rng.uniform(-0.15, 0.15, 3)) @ start
    return start, end


@pytest.mark.parametrize("seed", range(2))
def test_axis_test_never_parts_objects_that_touch(seed):
    """swept.apart_along_axes (the cull before a pair's swept descent) against dense
    sampling of the exact screw motion (scipy) with python-fcl's collision test: a box
    and an ellipsoid, turning up to 45 degrees per step, placed so that their bounding
    spheres overlap. No pair it calls apart touches at any of 201 moments; it does call
    apart many pairs that come close (it culls), and leaves every touching pair alone."""
    import trimesh

    from collide.discrete import object_margins
    from collide.load import Mesh
    from collide.motion import INTERPOLATIONS, MOTION_WIDTH, step_motions
    from collide.packed import pack_scene
    from collide.swept import apart_along_axes, boxed_meshes

    fcl = pytest.importorskip("fcl")
    from fcl_poses import fcl_model

    rng = np.random.default_rng(40 + seed)
    box = trimesh.creation.box(extents=(1.0, 0.3, 0.2))
    ball = trimesh.creation.icosphere(subdivisions=2)
    ball.apply_scale((0.45, 0.3, 0.2))
    meshes = [Mesh(name, None, np.asarray(m.vertices, float), np.asarray(m.faces, np.int64))
              for name, m in (("box", box), ("ball", ball))]
    ps, _ = pack_scene(meshes, np.array([0, 1]))
    models = [fcl_model(fcl, m) for m in meshes]
    reach = ps.sphere_radius.sum()
    samples = np.linspace(0.0, 1.0, 201)

    def touch_at(ends, t):  # screw_reference, each motion's logarithm taken once
        placed = [scipy_linalg.expm(t * twist) @ e[0] for twist, e in zip(twists, ends)]
        objects = [fcl.CollisionObject(m, fcl.Transform(p[:3, :3], p[:3, 3])) for m, p in zip(models, placed)]
        return fcl.collide(*objects, fcl.CollisionRequest(), fcl.CollisionResult()) > 0

    apart = touching = 0
    for _ in range(100):
        direction = rng.normal(size=3)
        offset = direction / np.linalg.norm(direction) * rng.uniform(0.3, 1.0) * reach
        ends = [_moved_poses(rng, np.zeros(3), np.radians(45)), _moved_poses(rng, offset, np.radians(45))]
        poses = np.ascontiguousarray(np.array([[e[i][:3] for e in ends] for i in (0, 1)]))
        margin = np.empty(2)
        rows = np.empty((2, MOTION_WIDTH))
        object_margins(ps, poses[0], poses[1], margin)
        step_motions(INTERPOLATIONS["screw"], poses[0], poses[1], margin, rows)
        said_apart = apart_along_axes(ps, boxed_meshes(ps), poses[0], poses[1], rows, margin, 1e-9, 0, 1)
        twists = [np.real(scipy_linalg.logm(e[1] @ np.linalg.inv(e[0]))) for e in ends]
        touches = any(touch_at(ends, t) for t in samples)
        assert not (said_apart and touches)
        apart += said_apart
        touching += touches
    assert apart >= 10 and touching >= 10, (apart, touching)  # both kinds occur: the check above is not empty



def _boxes_overlap(placed_a, placed_b, box_a, box_b):
    """Whether two boxes (lo, hi (2, 3) in their body frames) placed by 4x4 poses overlap,
    pose by pose (placed_a, placed_b: (S, 4, 4); returns bool (S,)): the separating axis
    test over their 15 axes (an exact reference, in numpy)."""
    centres, axes, halves = [], [], []
    for m, (lo, hi) in ((placed_a, box_a), (placed_b, box_b)):
        centres.append(m[:, :3, :3] @ (0.5 * (lo + hi)) + m[:, :3, 3])
        axes.append(m[:, :3, :3])
        halves.append(0.5 * (hi - lo))
    candidates = [axes[0][:, :, i] for i in range(3)] + [axes[1][:, :, i] for i in range(3)]
    candidates += [np.cross(axes[0][:, :, i], axes[1][:, :, j]) for i in range(3) for j in range(3)]
    apart = np.zeros(placed_a.shape[0], bool)
    for axis in candidates:
        length = np.linalg.norm(axis, axis=1)
        usable = length >= 1e-12  # parallel edges: the face axes decide
        axis = axis / np.where(usable, length, 1.0)[:, None]
        reach = sum(np.abs(np.einsum("sij,si->sj", axes[k], axis)) @ halves[k] for k in range(2))
        gap = np.abs(np.einsum("si,si->s", centres[1] - centres[0], axis))
        apart |= usable & (gap > reach)
    return ~apart


@pytest.mark.parametrize("angle", [0.0, 0.05, 0.8, 2.0])
def test_node_pair_window_holds_every_moment_the_boxes_meet(angle):
    """broad.rigid_pair_window (the key of the best-first search for when a contact ends
    or begins) against the exact screw motion (scipy) sampled at 401 moments: two boxes
    passing each other while each turns by up to ``angle`` radians; at every moment their
    placed boxes overlap (separating axis test), the moment lies in the window, and in
    the looser window seen from one side only (what inner node pairs get). The window
    is not just the whole step: in most cases where the boxes meet only part of
    the time it leaves out some of the moments they are apart."""
    from collide.broad import relative_pose, rigid_deviations, rigid_pair_window, rigid_placed_node
    from collide.motion import rotation_magnitudes

    rng = np.random.default_rng(17)
    samples = np.linspace(0.0, 1.0, 401)
    meeting = narrowed = 0
    for _ in range(40):
        lo = rng.uniform(-1.0, 0.0, (2, 3))
        hi = lo + rng.uniform(0.1, 1.0, (2, 3))
        a0 = random_pose(rng)
        shift = rng.normal(size=3)
        shift *= 3.0 / np.linalg.norm(shift)  # A passes B: B starts near A's midway point, turns in place
        a1 = transform(rot(rng.normal(size=3), rng.uniform(0, angle)) @ a0[:3, :3], a0[:3, 3] + shift)
        b0 = transform(rot(rng.normal(size=3), rng.uniform(0, np.pi)), a0[:3, 3] + 0.5 * shift
                       + rng.uniform(-0.5, 0.5, 3))
        b1 = transform(rot(rng.normal(size=3), rng.uniform(0, angle)) @ b0[:3, :3],
                       b0[:3, 3] + rng.uniform(-0.5, 0.5, 3))
        pose = np.ascontiguousarray(np.stack([a0[:3], a1[:3], b0[:3], b1[:3]]))
        rows = np.ascontiguousarray(np.stack([motion_row(a0, a1), motion_row(b0, b1)]))
        dev_a, dev_b = rigid_deviations(lo, hi, pose, rows, np.array([[0, 1]], np.int64), 1)
        placings = []
        for ends in (((pose[2], pose[0]), (pose[3], pose[1])), ((pose[0], pose[2]), (pose[1], pose[3]))):
            start, end = relative_pose(*ends[0]), relative_pose(*ends[1])
            placings.append((start, end, rotation_magnitudes(start), rotation_magnitudes(end)))
        nodes = rigid_placed_node(lo, hi, 0, placings[0]), rigid_placed_node(lo, hi, 1, placings[1])
        t_lo, t_hi = rigid_pair_window(*nodes, dev_a, dev_b)
        seen_from_b = rigid_pair_window(*nodes, dev_a, dev_b, False)  # one side only (inner nodes): looser
        assert seen_from_b[0] <= t_lo and t_hi <= seen_from_b[1] or t_lo > t_hi
        twists = [np.real(scipy_linalg.logm(e @ np.linalg.inv(s))) for s, e in ((a0, a1), (b0, b1))]
        placed_a, placed_b = (scipy_linalg.expm(samples[:, None, None] * twist) @ start
                              for twist, start in zip(twists, (a0, b0)))
        meets = _boxes_overlap(placed_a, placed_b, (lo[0], hi[0]), (lo[1], hi[1]))
        if meets.any():
            for lo_t, hi_t in ((t_lo, t_hi), seen_from_b):
                assert lo_t <= samples[meets].min() + 1e-9 and samples[meets].max() - 1e-9 <= hi_t, (lo_t, hi_t)
        if 0 < meets.sum() < samples.size:
            meeting += 1
            narrowed += t_lo > 0.0 or t_hi < 1.0
    assert meeting >= 10 and narrowed >= meeting // 2, (meeting, narrowed)

def test_axis_test_allows_for_the_arc():
    """A rod turning 90 degrees about its centre, a small block on the diagonal within the
    rod's reach: the rod's corners at both frames lie below the block along the centre
    line, but halfway through the turn the rod points at it. apart_along_axes must
    keep the pair (the arc's deviation bound), and does part it once the block is beyond
    the reach."""
    import trimesh

    from collide.discrete import object_margins
    from collide.load import Mesh
    from collide.motion import INTERPOLATIONS, MOTION_WIDTH, step_motions
    from collide.packed import pack_scene
    from collide.swept import apart_along_axes, boxed_meshes

    meshes = [Mesh(name, None, np.asarray(m.vertices, float), np.asarray(m.faces, np.int64))
              for name, m in (("rod", trimesh.creation.box(extents=(2.0, 0.1, 0.1))),
                              ("block", trimesh.creation.box(extents=(0.1, 0.1, 0.1))))]
    ps, _ = pack_scene(meshes, np.array([0, 1]))
    diagonal = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    for distance, expected in ((0.95, False), (1.2, True)):
        block = transform(np.eye(3), distance * diagonal)
        poses = np.ascontiguousarray(np.array([[np.eye(4)[:3], block[:3]],
                                               [transform(rot([0, 0, 1], np.pi / 2), [0, 0, 0])[:3], block[:3]]]))
        margin = np.empty(2)
        rows = np.empty((2, MOTION_WIDTH))
        object_margins(ps, poses[0], poses[1], margin)
        step_motions(INTERPOLATIONS["screw"], poses[0], poses[1], margin, rows)
        said_apart = apart_along_axes(ps, boxed_meshes(ps), poses[0], poses[1], rows, margin, 1e-9, 0, 1)
        assert said_apart == expected, distance


def test_boxed_meshes_are_those_whose_box_is_their_hull():
    """swept.boxed_meshes flags a mesh when its root box's extent along any direction is
    its vertices' (apart_along_axes then skips reading them): a subdivided box and an
    offset box are flagged, and along 200 random directions their vertices' extremes
    equal their box corners' (numpy); an ellipsoid and a box with one corner cut off
    are not."""
    import trimesh

    from collide.load import Mesh
    from collide.packed import pack_scene
    from collide.swept import boxed_meshes

    fine_box = trimesh.creation.box(extents=(1.0, 0.4, 0.3)).subdivide().subdivide()
    offset_box = trimesh.creation.box(extents=(0.2, 0.3, 0.5))
    offset_box.apply_translation((3.0, -1.0, 0.5))
    ball = trimesh.creation.icosphere(subdivisions=1)
    ball.apply_scale((0.5, 0.3, 0.2))
    cut = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    cut = cut.slice_plane((0.4, 0.4, 0.4), (-1.0, -1.0, -1.0), cap=True)
    meshes = [Mesh(str(k), None, np.asarray(m.vertices, float), np.asarray(m.faces, np.int64))
              for k, m in enumerate((fine_box, offset_box, ball, cut))]
    ps, _ = pack_scene(meshes, np.arange(4))
    assert boxed_meshes(ps).tolist() == [True, True, False, False]
    directions = np.random.default_rng(3).normal(size=(200, 3))
    for mesh in meshes[:2]:
        lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
        corners = np.array([[(hi if c >> i & 1 else lo)[i] for i in range(3)] for c in range(8)])
        np.testing.assert_allclose((mesh.vertices @ directions.T).max(axis=0), (corners @ directions.T).max(axis=0),
                                   rtol=0, atol=1e-12)


# --- warnings and errors ------------------------------------------------------------------------

def turning_rod(tmp_path, step_deg, n=3):
    meshes = tmp_path / "meshes"
    meshes.mkdir(exist_ok=True)
    write_box(meshes / "rod.stl", (2.0, 0.1, 0.1), (1.0, 0, 0))
    write_box(meshes / "far.stl", (0.1, 0.1, 0.1), (50, 50, 50))
    matrix = np.array([[transform(rot([0, 0, 1], np.radians(step_deg) * k), [0, 0, 0])] for k in range(n)])
    return meshes, write_trajectory(tmp_path / "t.h5", np.arange(n, dtype=float), ["rod"], matrix=matrix)


def test_half_turn_between_frames_is_a_clear_error(tmp_path):
    meshes, traj = turning_rod(tmp_path, 180.0)
    with pytest.raises(InputError, match=r"'rod' turns half a turn .* between frames 0 and 1"):
        collide.scan(meshes, traj)
    proc = run_cli("scan", meshes, traj, "-o", tmp_path / "c.h5")
    assert proc.returncode == 2 and len(proc.stderr.splitlines()) == 1, proc.stderr
    assert not (tmp_path / "c.h5").exists()
    collide.scan(meshes, traj, interpolation="linear-vertex")    # straight paths are defined
    collide.scan(meshes, traj, mode="discrete")                  # and so are frames


def test_large_turns_warn_in_screw_mode(tmp_path, caplog):
    meshes, traj = turning_rod(tmp_path, 120.0)
    with caplog.at_level(logging.WARNING, logger="collide"):
        collide.scan(meshes, traj)
    assert "'rod' turns by 120.0 degrees between frames 0 and 1" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="collide"):
        collide.scan(meshes, traj, warn_angle=150.0)
    assert "turns by" not in caplog.text


def test_linear_vertex_warns_in_length_units(tmp_path, caplog):
    """A 2-long rod turning 10 degrees per frame about its end: its tip's chord passes
    2 (1 - cos 5 deg) = 0.0076 inside its arc (bound: rho theta^2 / 8 with rho from the
    bounding sphere); 1 degree stays below 1e-3 of its size."""
    meshes, traj = turning_rod(tmp_path, 10.0)
    with caplog.at_level(logging.WARNING, logger="collide"):
        collide.scan(meshes, traj, interpolation="linear-vertex")
    assert "'rod': between frames 0 and 1" in caplog.text and "length units" in caplog.text
    value = float(caplog.text.split("up to ")[1].split()[0])
    assert 2 * (1 - np.cos(np.radians(5))) <= value <= 2.2 * 2 * (1 - np.cos(np.radians(5)))
    caplog.clear()
    small = tmp_path / "small"
    small.mkdir()
    meshes, traj = turning_rod(small, 1.0)
    with caplog.at_level(logging.WARNING, logger="collide"):
        collide.scan(meshes, traj, interpolation="linear-vertex")
    assert "depart" not in caplog.text
