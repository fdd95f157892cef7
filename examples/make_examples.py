"""Generate the bundled example scenes (deterministic; lengths in mm, times in s).

    python examples/make_examples.py

fixture/  parts moving through a fixture (the quick-start scene):
  frame     static square window (4 bars, 20 x 20 mm opening), about 3000 triangles
  pillar    static cylinder beside the window
  peg_a     cylinder r = 9 mm passing through the window's centre: 1 mm clearance, no contact
  peg_b     the same mesh (objects/mesh), later, 1.5 mm off centre: scrapes the window's side
  arm       capsule turning about z (0.75 degrees per frame) that sweeps into the pillar and out
tunnel/   a fast bullet through a thin wall between two frames (discrete mode misses it) and a
          ball passing 0.2 mm beside the wall's edge (a near miss).
turning/  an arm swinging 40 degrees per frame about a vertical hub clips a post between two
          frames: the post stands on the arc of the arm's tip but outside the straight paths
          of its vertices, so --interpolation screw (the default) catches it and
          linear-vertex does not.
"""
from pathlib import Path

import h5py
import numpy as np
import trimesh

HERE = Path(__file__).resolve().parent


def quaternion_z(angle):
    """wxyz quaternions (n, 4) of rotations by ``angle`` (n,) radians about z."""
    return np.stack([np.cos(angle / 2), 0 * angle, 0 * angle, np.sin(angle / 2)], axis=-1)


def write_trajectory(path, time, names, position, orientation, mesh=None):
    with h5py.File(path, "w") as f:
        f["time"] = time
        f["time"].attrs["unit"] = "s"
        f.create_dataset("objects/name", data=names, dtype=h5py.string_dtype())
        if mesh is not None:
            f.create_dataset("objects/mesh", data=mesh, dtype=h5py.string_dtype())
        f["poses/position"] = position
        f["poses/position"].attrs["unit"] = "mm"
        f["poses/orientation"] = orientation
        f["poses/orientation"].attrs["quaternion_order"] = "wxyz"


def subdivided_box(extents, centre, times=3):
    box = trimesh.creation.box(extents=extents)
    for _ in range(times):
        box = box.subdivide()
    box.apply_translation(centre)
    return box


def fixture_scene(folder):
    meshes = folder / "meshes"
    meshes.mkdir(parents=True, exist_ok=True)
    # a square window in the plane x = 0: opening |y|, |z| <= 10, bars 10 mm wide, 6 mm thick
    bars = [subdivided_box((6, 40, 10), (0, 0, 15)), subdivided_box((6, 40, 10), (0, 0, -15)),
            subdivided_box((6, 10, 20), (0, 15, 0)), subdivided_box((6, 10, 20), (0, -15, 0))]
    trimesh.util.concatenate(bars).export(meshes / "frame.stl")
    pillar = trimesh.creation.cylinder(radius=6, height=60, sections=96)
    pillar.apply_translation((40, 60, 0))
    pillar.export(meshes / "pillar.stl")
    peg = trimesh.creation.cylinder(radius=9, height=30, sections=256)
    peg.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (0, 1, 0)))  # axis along x
    peg.export(meshes / "peg.ply")
    arm = trimesh.creation.capsule(height=50, radius=4, count=(32, 32))
    arm.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (0, 1, 0)))
    arm.apply_translation((25, 0, 0))  # the arm reaches from its hub (body origin) to x = 79
    arm.export(meshes / "arm.stl")

    n = 240
    time = np.linspace(0.0, 4.0, n)
    s = np.linspace(0.0, 1.0, n)
    position = np.zeros((n, 3, 3))
    position[:, 0, 0] = -60 + 240 * s                  # peg_a: through the window's centre at s = 0.25
    position[:, 1, 0] = -180 + 240 * s                 # peg_b: through the window at s = 0.75,
    position[:, 1, 1] = 1.5                            # 1.5 mm off centre,
    position[:, 1, 2] = np.clip(60 - 150 * s, 0, None)  # after dropping into line far from the window
    position[:, 2] = (0, 60, 0)                                                 # arm hub
    orientation = np.zeros((n, 3, 4))
    orientation[:, :2, 0] = 1.0
    orientation[:, 2] = quaternion_z(np.radians(-60 + 1.5 * np.arange(n) / 2))   # arm turns 0.75 deg/frame
    write_trajectory(folder / "traj.h5", time, ["peg_a", "peg_b", "arm"], position, orientation,
                     mesh=["peg.ply", "peg.ply", "arm.stl"])


def tunnel_scene(folder):
    meshes = folder / "meshes"
    meshes.mkdir(parents=True, exist_ok=True)
    subdivided_box((0.5, 100, 100), (0, 0, 0), times=2).export(meshes / "wall.stl")
    trimesh.creation.icosphere(subdivisions=2, radius=2.0).export(meshes / "bullet.stl")
    trimesh.creation.icosphere(subdivisions=2, radius=2.0).export(meshes / "ball.stl")
    n = 20
    time = np.arange(n) * 0.01
    position = np.zeros((n, 2, 3))
    position[:, 0, 0] = -235 + 50 * np.arange(n)   # 50 mm per frame: from x = -10 to x = 40 in one step
    position[:, 1] = np.stack([-50 + 5 * np.arange(n), 0 * time + 52.2, 0 * time], axis=-1)
    orientation = np.zeros((n, 2, 4))
    orientation[..., 0] = 1.0
    write_trajectory(folder / "traj.h5", time, ["bullet", "ball"], position, orientation)


def turning_scene(folder):
    meshes = folder / "meshes"
    meshes.mkdir(parents=True, exist_ok=True)
    arm = trimesh.creation.capsule(height=380, radius=15, count=(24, 24))
    arm.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (0, 1, 0)))
    arm.apply_translation((205, 0, 0))  # from the hub (body origin) to its tip at x = 410 mm
    arm.export(meshes / "arm.stl")
    post = trimesh.creation.cylinder(radius=4, height=200, sections=32)
    post.apply_translation((402 * np.cos(np.radians(60)), 402 * np.sin(np.radians(60)), 0))
    post.export(meshes / "post.stl")
    n = 5
    time = np.arange(n) * 0.04                     # 25 frames per second
    angle = np.radians(40.0 * np.arange(n))        # 40 degrees per frame about the hub's z axis
    orientation = quaternion_z(angle)[:, None, :]
    write_trajectory(folder / "traj.h5", time, ["arm"], np.zeros((n, 1, 3)), orientation)


if __name__ == "__main__":
    fixture_scene(HERE / "fixture")
    tunnel_scene(HERE / "tunnel")
    turning_scene(HERE / "turning")
    for scene in ("fixture", "tunnel", "turning"):
        for path in sorted((HERE / scene / "meshes").iterdir()):
            mesh = trimesh.load(path, process=False, force="mesh")
            print(f"{scene}/meshes/{path.name}: {len(mesh.faces)} triangles")
