"""A deterministic robot cell for benchmarks: a 7-joint arm on a table, posts, a floor.

``write_cell(folder)`` writes

- ``robot.urdf`` and ``meshes/<link>.ply``: a serial arm of 8 links (``base`` + ``link1`` ..
  ``link7``), about 1 m reach, revolute joints ``j1`` .. ``j7`` alternating roll (z) and
  pitch (y) axes like common 7-axis arms. Each link is made of boxes and cylinders
  (tessellated to a maximum edge length), and each link's geometry overlaps its parent's
  at their joint by 1 cm, as real joint housings do: adjacent links touch at every pose;
- ``obstacles/{table,floor,post_a,post_b,post_c}.ply``: static meshes in world
  coordinates. The table stands on the floor (legs' feet on the floor's top face), the
  posts and the robot's base stand on the table top (z = 0);
- ``joints.csv``: ``time`` and ``j1`` .. ``j7`` at 100 Hz, sums of sinusoids. The arm
  sweeps about its base (j1) three times, the middle sweep the widest, with its gripper low
  over the table; ``post_a`` is placed (by forward kinematics of the trajectory) just
  beyond the gripper's farthest turn, so that the gripper runs 2.5 cm into it there, and
  nowhere else does the arm touch anything it is not joined to (checked by collide and
  python-fcl in bench_robot.py). The wrist roll ``j7`` swings up to 8 degrees per frame,
  so the spinning gripper touches post_a on and off during that window.

It returns a ``Cell`` with the names, triangle counts and the *expected* contact frames
of link7 with post_a: the frames at which a vertex of the gripper lies inside post_a's
solid cylinder or a vertex of post_a inside one of the gripper's solid primitives (an
independent check, from this module's own kinematics: a contact that only crosses
edges is missed by it, so a collision checker may find a frame or two more at the
window's ends).
"""
import csv
from pathlib import Path
from typing import NamedTuple

import numpy as np

#: Link geometry, link frame (origin on the joint that moves the link, z along the link).
#: ("box", lo, hi) or ("cyl", axis, radius, start, stop): a cylinder about the z or y axis.
LINKS = {
    "base": [("cyl", "z", 0.090, 0.000, 0.160)],
    "link1": [("cyl", "z", 0.075, -0.010, 0.200)],
    "link2": [("cyl", "y", 0.080, -0.085, 0.085), ("cyl", "z", 0.070, 0.000, 0.200)],
    "link3": [("cyl", "z", 0.062, -0.010, 0.200)],
    "link4": [("cyl", "y", 0.068, -0.075, 0.075), ("cyl", "z", 0.060, 0.000, 0.200)],
    "link5": [("cyl", "z", 0.055, -0.010, 0.190)],
    "link6": [("cyl", "y", 0.060, -0.065, 0.065), ("cyl", "z", 0.050, 0.000, 0.100)],
    "link7": [("cyl", "z", 0.042, -0.010, 0.020),                       # flange
              ("box", (-0.050, -0.022, 0.020), (0.050, 0.022, 0.060)),   # palm
              ("box", (0.022, -0.010, 0.060), (0.040, 0.010, 0.140)),    # fingers
              ("box", (-0.040, -0.010, 0.060), (-0.022, 0.010, 0.140))],
}
LINK_NAMES = list(LINKS)

#: Joints j1..j7: (parent, child, offset along the parent's z, axis).
JOINTS = [("base", "link1", 0.16, "z"), ("link1", "link2", 0.20, "y"), ("link2", "link3", 0.20, "z"),
          ("link3", "link4", 0.20, "y"), ("link4", "link5", 0.20, "z"), ("link5", "link6", 0.19, "y"),
          ("link6", "link7", 0.10, "z")]
JOINT_NAMES = [f"j{i + 1}" for i in range(len(JOINTS))]

#: Joint positions (radians): per joint, a constant and (amplitude, frequency Hz, phase) terms.
MOTION = [
    (0.0, [(0.90, 0.25, 0.0), (0.35, 0.05, 0.0)]),   # j1 base yaw: three sweeps, the middle one widest
    (0.80, [(0.06, 0.23, 1.0)]),                     # j2 shoulder
    (0.0, [(0.08, 0.17, 0.0)]),                      # j3 upper arm roll
    (1.00, [(0.08, 0.31, 0.3)]),                     # j4 elbow
    (0.0, [(0.10, 0.13, 2.0)]),                      # j5 forearm roll
    (0.80, [(0.10, 0.41, 0.0)]),                     # j6 wrist pitch
    (0.0, [(1.30, 1.70, 0.0)]),                      # j7 wrist roll: up to 8 deg per frame at 100 Hz
]

TABLE_TOP = (-0.75, -1.0, 0.75, 1.0)   # x0, y0, x1, y1 of the table top (its top face is z = 0)
TABLE_HEIGHT, TOP_THICKNESS, LEG = 0.75, 0.04, 0.06
POST_RADIUS = 0.035
GRIPPER_HALF_WIDTH = 0.050   # the palm's half length
BITE = 0.025                 # how far the palm reaches into post_a at the farthest turn (m)
STATIC_PAIRS_THAT_TOUCH = [("table", "floor"), ("post_*", "table"), ("base", "table")]


class Cell(NamedTuple):
    """What write_cell wrote."""
    folder: Path
    urdf: Path
    joints_csv: Path
    obstacles: Path          #: folder of the static meshes (world coordinates)
    links: list              #: link names (URDF order)
    statics: list            #: obstacle names
    triangles: dict          #: name -> triangle count
    expected_hit: np.ndarray  #: frames at which link7 is expected to touch post_a
    max_step_deg: float      #: largest joint change between two frames (degrees)


# --- geometry --------------------------------------------------------------------------------

def _primitive_mesh(primitive, max_edge):
    """(vertices, faces) of a box or cylinder primitive, tessellated to edges <= max_edge."""
    import trimesh
    if primitive[0] == "box":
        mesh = trimesh.creation.box(bounds=[primitive[1], primitive[2]])
    else:
        _, axis, radius, start, stop = primitive
        direction = np.array([0.0, 1.0, 0.0]) if axis == "y" else np.array([0.0, 0.0, 1.0])
        sections = max(16, int(np.ceil(2 * np.pi * radius / max_edge)))
        mesh = trimesh.creation.cylinder(radius=radius, segment=[start * direction, stop * direction],
                                         sections=sections)
    vertices, faces = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, max_edge)
    return np.asarray(vertices, float), np.asarray(faces, np.int64)


def _merge(parts):
    """One (vertices, faces) of several, faces kept in order."""
    vertices, faces, offset = [], [], 0
    for v, f in parts:
        vertices.append(v)
        faces.append(f + offset)
        offset += len(v)
    return np.concatenate(vertices), np.concatenate(faces)


def _write_ply(path, vertices, faces):
    import trimesh
    trimesh.Trimesh(vertices, faces, process=False).export(path)


def _inside(primitive, points, tol=0.0):
    """Points (n, 3) inside a primitive's solid (shrunk by tol)."""
    if primitive[0] == "box":
        lo, hi = np.asarray(primitive[1]), np.asarray(primitive[2])
        return np.all((points >= lo + tol) & (points <= hi - tol), axis=1)
    _, axis, radius, start, stop = primitive
    a = 1 if axis == "y" else 2
    radial = np.delete(points, a, axis=1)
    return ((np.einsum("ij,ij->i", radial, radial) <= (radius - tol) ** 2)
            & (points[:, a] >= start + tol) & (points[:, a] <= stop - tol))


# --- kinematics ------------------------------------------------------------------------------

def joint_trajectory(frames, rate):
    """(time (T,), positions (T, 7)) of the sinusoidal motion MOTION."""
    t = np.arange(frames) / rate
    q = np.empty((frames, len(MOTION)))
    for j, (const, terms) in enumerate(MOTION):
        q[:, j] = const + sum(a * np.sin(2 * np.pi * f * t + p) for a, f, p in terms)
    return t, q


def _rotation(axis, angle):
    """Rotation matrices (T, 3, 3) about the z or y axis."""
    c, s = np.cos(angle), np.sin(angle)
    r = np.zeros(angle.shape + (3, 3))
    if axis == "z":
        r[:, 0, 0], r[:, 0, 1], r[:, 1, 0], r[:, 1, 1], r[:, 2, 2] = c, -s, s, c, 1
    else:
        r[:, 0, 0], r[:, 0, 2], r[:, 2, 0], r[:, 2, 2], r[:, 1, 1] = c, s, -s, c, 1
    return r


def forward_kinematics(q):
    """World poses (T, 8, 4, 4) of the links (LINK_NAMES order) at joint positions q (T, 7)."""
    poses = np.zeros((q.shape[0], len(LINK_NAMES), 4, 4))
    poses[:, :, 3, 3] = 1
    poses[:, 0, :3, :3] = np.eye(3)
    for j, (parent, child, offset, axis) in enumerate(JOINTS):
        p, c = LINK_NAMES.index(parent), LINK_NAMES.index(child)
        joint = np.zeros_like(poses[:, 0])
        joint[:, :3, :3] = _rotation(axis, q[:, j])
        joint[:, 2, 3] = offset
        joint[:, 3, 3] = 1
        poses[:, c] = poses[:, p] @ joint
    return poses


def _transform(pose, points):
    return points @ pose[:3, :3].T + pose[:3, 3]


# --- the cell --------------------------------------------------------------------------------

def _urdf_text():
    lines = ['<?xml version="1.0"?>', '<robot name="arm7">']
    for name in LINK_NAMES:
        lines.append(f'  <link name="{name}"><collision><geometry><mesh filename="meshes/{name}.ply"/>'
                     '</geometry></collision></link>')
    for jname, (parent, child, offset, axis) in zip(JOINT_NAMES, JOINTS):
        xyz = "0 1 0" if axis == "y" else "0 0 1"
        lines.append(f'  <joint name="{jname}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
                     f'<origin xyz="0 0 {offset}"/><axis xyz="{xyz}"/>'
                     '<limit lower="-3.1" upper="3.1" effort="100" velocity="20"/></joint>')
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


def _post_a_position(poses):
    """Where post_a stands: just beyond the farthest turn of the fingertips about the base
    axis (over the whole motion), so that the gripper's leading side bites BITE into it
    there (the wrist roll turns the gripper, so the bite varies). Returns (xy, tip z)."""
    gripper = poses[:, LINK_NAMES.index("link7")]
    tips = gripper[:, :3, :3] @ [0.0, 0.0, 0.12] + gripper[:, :3, 3]
    angle = np.unwrap(np.arctan2(tips[:, 1], tips[:, 0]))
    k = int(np.argmax(angle))
    radius = np.hypot(tips[k, 0], tips[k, 1])
    post_angle = angle[k] + (POST_RADIUS + GRIPPER_HALF_WIDTH - BITE) / radius
    return radius * np.array([np.cos(post_angle), np.sin(post_angle)]), tips[k, 2]


def obstacles(post_a_xy, post_a_height, max_edge):
    """{name: (vertices, faces)} of the static meshes, world coordinates."""
    x0, y0, x1, y1 = TABLE_TOP
    floor_z = -TABLE_HEIGHT
    table = [(("box", (x0, y0, -TOP_THICKNESS), (x1, y1, 0.0)), max_edge * 5)]
    for x in (x0, x1 - LEG):
        for y in (y0, y1 - LEG):
            table.append((("box", (x, y, floor_z), (x + LEG, y + LEG, -TOP_THICKNESS)), max_edge * 2.5))
    posts = {"post_a": (post_a_xy, post_a_height),       # hit by the gripper
             "post_b": ((0.50, -0.82), 0.80),            # in the sweep, out of reach
             "post_c": ((-0.55, 0.10), 0.80)}            # behind the robot
    out = {"table": _merge([_primitive_mesh(p, e) for p, e in table]),
           "floor": _primitive_mesh(("box", (-2.0, -2.0, floor_z - 0.05), (2.0, 2.0, floor_z)), max_edge * 12.5)}
    for name, (xy, height) in posts.items():
        v, f = _primitive_mesh(("cyl", "z", POST_RADIUS, 0.0, height), max_edge * 3)
        out[name] = (v + [xy[0], xy[1], 0.0], f)
    return out


def expected_hits(poses, post_vertices, post_xy, post_height, max_edge):
    """Frames at which a link7 vertex lies in post_a's solid or a post_a vertex in a
    link7 primitive (see the module docstring)."""
    post = ("cyl", "z", POST_RADIUS, 0.0, post_height)
    gripper = LINKS["link7"]
    link = LINK_NAMES.index("link7")
    corners = _merge([_primitive_mesh(p, max_edge) for p in gripper])[0]
    hits = []
    for k in range(poses.shape[0]):
        pose = poses[k, link]
        world = _transform(pose, corners) - [post_xy[0], post_xy[1], 0.0]
        local = (post_vertices - pose[:3, 3]) @ pose[:3, :3]
        if _inside(post, world).any() or any(_inside(p, local).any() for p in gripper):
            hits.append(k)
    return np.array(hits, np.int64)


def write_cell(folder, frames=1000, rate=100.0, max_edge=0.04):
    """Write the cell into folder (created); returns a Cell. max_edge (m) sets the
    tessellation of the links (0.04: about 14k triangles in all; the static meshes are
    coarser, in proportion)."""
    folder = Path(folder)
    (folder / "meshes").mkdir(parents=True, exist_ok=True)
    (folder / "obstacles").mkdir(exist_ok=True)
    triangles = {}
    for name, primitives in LINKS.items():
        v, f = _merge([_primitive_mesh(p, max_edge) for p in primitives])
        _write_ply(folder / "meshes" / f"{name}.ply", v, f)
        triangles[name] = len(f)
    (folder / "robot.urdf").write_text(_urdf_text())

    t, q = joint_trajectory(frames, rate)
    with open(folder / "joints.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["time"] + JOINT_NAMES)
        for k in range(frames):
            writer.writerow([repr(float(t[k]))] + [repr(float(x)) for x in q[k]])

    poses = forward_kinematics(q)
    post_xy, tip_z = _post_a_position(poses)
    post_height = tip_z + 0.05          # the fingers reach below its top, the wrist stays above
    statics = obstacles(post_xy, post_height, max_edge)
    for name, (v, f) in statics.items():
        _write_ply(folder / "obstacles" / f"{name}.ply", v, f)
        triangles[name] = len(f)
    hit = expected_hits(poses, statics["post_a"][0], post_xy, post_height, max_edge)
    return Cell(folder, folder / "robot.urdf", folder / "joints.csv", folder / "obstacles", list(LINK_NAMES),
                list(statics), triangles, hit, float(np.degrees(np.abs(np.diff(q, axis=0)).max())))


if __name__ == "__main__":
    import sys
    cell = write_cell(sys.argv[1] if len(sys.argv) > 1 else "cell_out")
    print(f"{sum(cell.triangles.values())} triangles: {cell.triangles}")
    print(f"expected link7/post_a frames: {cell.expected_hit.min() if cell.expected_hit.size else None}.."
          f"{cell.expected_hit.max() if cell.expected_hit.size else None} ({cell.expected_hit.size} frames); "
          f"largest joint step {cell.max_step_deg:.2f} deg/frame")
