"""Random rigid poses drawn like FCL's own mesh-mesh test, and python-fcl models (shared by tests and benchmarks)."""
import numpy as np


def euler_xyz(angles):
    """Rotation matrices (n, 3, 3) = Rz(c) @ Ry(b) @ Rx(a) for angles (n, 3) = (a, b, c)."""
    a, b, c = angles.T
    one, zero = np.ones_like(a), np.zeros_like(a)
    rx = np.stack([np.stack([one, zero, zero], -1), np.stack([zero, np.cos(a), -np.sin(a)], -1),
                   np.stack([zero, np.sin(a), np.cos(a)], -1)], 1)
    ry = np.stack([np.stack([np.cos(b), zero, np.sin(b)], -1), np.stack([zero, one, zero], -1),
                   np.stack([-np.sin(b), zero, np.cos(b)], -1)], 1)
    rz = np.stack([np.stack([np.cos(c), -np.sin(c), zero], -1), np.stack([np.sin(c), np.cos(c), zero], -1),
                   np.stack([zero, zero, one], -1)], 1)
    return rz @ ry @ rx


def fcl_poses(n, seed):
    """(rotations (n, 3, 3), translations (n, 3)): translation uniform in
    [-3000, 3000]^2 x [0, 3000], three uniform Euler angles."""
    rng = np.random.default_rng(seed)
    rotation = euler_xyz(rng.uniform(-np.pi, np.pi, (n, 3)))
    translation = rng.uniform([-3000, -3000, 0], [3000, 3000, 3000], (n, 3))
    return rotation, translation


def fcl_model(fcl, mesh):
    """A python-fcl BVHModel of a collide Mesh (``fcl`` is the imported module)."""
    model = fcl.BVHModel()
    model.beginModel(len(mesh.vertices), len(mesh.faces))
    model.addSubModel(mesh.vertices, mesh.faces)
    model.endModel()
    return model
