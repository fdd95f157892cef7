"""Shared helpers: writing small scenes and running the real CLI in a subprocess."""
import contextlib
import io
import logging
import os
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
import trimesh
from numba import njit

TESTS = Path(__file__).resolve().parent
DATA = TESTS / "data"
REPO = TESTS.parent
SHARED_DATA = REPO.parent / "shared" / "data"


def _shared_kernel_cache():
    """The tests (and the command lines they start) use the user's kernel cache, so that
    kernels compile once for every test run and installed copy, not in the private mesh
    cache folder set below."""
    if not os.environ.get("COLLIDE_KERNEL_CACHE_DIR"):
        from collide.jit import cache_root
        os.environ["COLLIDE_KERNEL_CACHE_DIR"] = str(cache_root())


_shared_kernel_cache()


def _one_blas_thread():
    """pytest-xdist runs one test process per core: each gets one BLAS thread (a variable
    the workers inherit). With a thread per core in every process, scipy's logm in the
    screw-motion references ran 6-15 times slower (the slow random-scene checks of screw
    motion: 310 s instead of 20 s on two cores)."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


_one_blas_thread()

# collide's kernels are created on import: only now that their cache folder is pinned
from collide.predicates import triangles_intersect  # noqa: E402


def pytest_configure(config):
    """On a cold kernel cache, compile every kernel first, in parallel processes (what
    `collide warmup` does), once, before any test (and before pytest-xdist's workers
    start), rather than in each test process as tests need them."""
    if hasattr(config, "workerinput"):
        return  # a pytest-xdist worker: the controller has done it
    from collide import warmup
    if not (warmup.is_warm("discrete") and warmup.is_warm("continuous")):
        warmup.warm_up(("discrete", "continuous"), extra=("lbvh",))  # lbvh: the tests build with every rule


@pytest.fixture(autouse=True, scope="session")
def _private_mesh_cache(tmp_path_factory):
    """The tests' mesh cache lives in a temporary folder, never in the user's cache
    (subprocesses inherit the variable)."""
    previous = os.environ.get("COLLIDE_CACHE_DIR")
    os.environ["COLLIDE_CACHE_DIR"] = str(tmp_path_factory.mktemp("mesh-cache"))
    yield
    if previous is None:
        os.environ.pop("COLLIDE_CACHE_DIR", None)
    else:
        os.environ["COLLIDE_CACHE_DIR"] = previous


def write_trajectory(path, time, names, position=None, orientation=None, order="wxyz",
                     matrix=None, mesh=None):
    """Write a SPEC §2.2 trajectory; pass position+orientation or matrix."""
    with h5py.File(path, "w") as f:
        f["time"] = np.asarray(time, dtype=np.float64)
        f["time"].attrs["unit"] = "s"
        f.create_dataset("objects/name", data=np.array(names, dtype=object), dtype=h5py.string_dtype())
        if mesh is not None:
            f.create_dataset("objects/mesh", data=np.array(mesh, dtype=object), dtype=h5py.string_dtype())
        if matrix is not None:
            f["poses/matrix"] = np.asarray(matrix, dtype=np.float64)
        else:
            f["poses/position"] = np.asarray(position, dtype=np.float64)
            f["poses/orientation"] = np.asarray(orientation, dtype=np.float64)
            if order is not None:
                f["poses/orientation"].attrs["quaternion_order"] = order
    return path


def identity_quaternions(n_frames, n_objects, order="wxyz"):
    q = np.zeros((n_frames, n_objects, 4))
    q[..., 0 if order == "wxyz" else 3] = 1.0
    return q


@njit(cache=True)
def meshes_touch(va, fa, vb, fb):
    """Whether any triangle of (va, fa) meets any of (vb, fb) (closed triangles, exact
    predicate; brute force over all pairs): float64 (V, 3) vertices, int64 (F, 3) faces."""
    for i in range(fa.shape[0]):
        for j in range(fb.shape[0]):
            if triangles_intersect(va[fa[i]], vb[fb[j]]):
                return True
    return False


def rotation_about(axis, angle):
    """Rotation matrix (3, 3) by ``angle`` radians about ``axis`` (Rodrigues' formula)."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def rigid_transform(r, p):
    """The 4 x 4 matrix of rotation r (3, 3) followed by translation p (3,)."""
    m = np.eye(4)
    m[:3, :3] = r
    m[:3, 3] = p
    return m


def quaternion_rotation(q):
    """Rotation matrix (3, 3) of the unit quaternion q = (w, x, y, z)."""
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def write_box(path, extents=(1.0, 1.0, 1.0), centre=(0.0, 0.0, 0.0)):
    """An axis-aligned box mesh (12 triangles) with exact dyadic coordinates."""
    box = trimesh.creation.box(extents=extents)
    box.apply_translation(centre)
    box.export(path)
    return path


def run_cli(*args, cwd=None, env=None, process=False):
    """Run ``collide`` with these arguments; returns CompletedProcess (text).

    By default the command line's own entry point (``collide_cli.main.main``, what the
    ``collide`` program runs) is called in this test process, with stdout and stderr
    captured: the same code, without paying a new interpreter's imports and kernel
    loading for every call. ``process=True`` (implied by ``cwd`` or ``env``) runs it as
    a real process, for what only a process shows (signals, exit by the interpreter,
    environment read at start-up)."""
    if process or cwd is not None or env:
        full_env = dict(os.environ, **(env or {}))
        return subprocess.run([sys.executable, "-m", "collide_cli.main", *map(str, args)],
                              cwd=cwd, env=full_env, capture_output=True, text=True, timeout=600)
    return run_in_process(*args)


def run_in_process(*args):
    """``collide ARGS`` through collide_cli.main.main in this process (see run_cli)."""
    from collide_cli.main import main
    argv = [str(a) for a in args]
    out, err = io.StringIO(), io.StringIO()
    code = 0
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), _logging_restored():
        try:
            main(argv)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    return subprocess.CompletedProcess(["collide", *argv], code, out.getvalue(), err.getvalue())


@contextlib.contextmanager
def _logging_restored():
    """Put the "collide" and root loggers back as they were: the command line sets up its
    own handler and stops collide's records from reaching the root logger, which a later
    test of the same process (pytest's caplog listens there) would otherwise miss."""
    logger, root = logging.getLogger("collide"), logging.getLogger()
    saved = (logger.handlers[:], logger.propagate, logger.level, root.handlers[:], root.level)
    try:
        yield
    finally:
        logger.handlers[:], logger.propagate, logger.level = saved[0], saved[1], saved[2]
        root.handlers[:], root.level = saved[3], saved[4]


def default_sigint():
    """preexec_fn of a command a test interrupts with SIGINT: Ctrl-C reaches it even where
    the test run was started with SIGINT ignored (a background job of a non-interactive
    shell), which the child would inherit, and which collide rightly keeps ignoring."""
    import signal
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def signal_when_scanning(proc, folder, signum, timeout=120):
    """Send ``signum`` to the scan ``proc`` once it writes its output's temporary file in
    ``folder`` (inputs loaded, kernels ready: the scan itself has begun). False if the
    process ended first."""
    import time
    deadline = time.monotonic() + timeout
    while not any(p.name.startswith(".") for p in folder.iterdir()):
        if proc.poll() is not None or time.monotonic() > deadline:
            return False
        time.sleep(0.01)
    proc.send_signal(signum)
    return True


@pytest.fixture
def two_boxes(tmp_path):
    """Meshes folder with a static unit box 'fixed' at the origin and a unit box 'mover'
    translated along x from -3 to +3 in 13 frames (step 0.5): the boxes touch for
    |x| <= 1 (faces touching at |x| == 1), i.e. frames 4..8."""
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    write_box(meshes / "fixed.stl")
    write_box(meshes / "mover.obj")
    n = 13
    position = np.zeros((n, 1, 3))
    position[:, 0, 0] = np.linspace(-3.0, 3.0, n)
    traj = write_trajectory(tmp_path / "traj.h5", np.arange(n) * 0.1, ["mover"], position,
                            identity_quaternions(n, 1))
    return meshes, traj
