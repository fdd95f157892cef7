"""Poses are read in chunks of frames, and only the frames a scan selects: the same poses
as an independent conversion (scipy's rotations), the same contacts as a trajectory cut to
those frames, and frames outside the selection are never read."""
import h5py
import numpy as np
import pytest
from conftest import REPO, identity_quaternions, write_box
from conftest import write_trajectory as write_traj_file
from scipy.spatial.transform import Rotation

import collide
from collide import config
from collide.errors import InputError
from collide.load import PoseFile, load_trajectory

FIXTURE = REPO / "examples" / "fixture"


def fixture_arrays():
    with h5py.File(FIXTURE / "traj.h5", "r") as f:
        return {name: f[name][()] for name in ("time", "objects/name", "objects/mesh", "poses/position",
                                               "poses/orientation")}


def write_trajectory(path, arrays, frames=slice(None)):
    """The fixture's datasets, cut to ``frames``, as a trajectory file."""
    with h5py.File(path, "w") as f:
        for name, data in arrays.items():
            f[name] = data[frames] if name in ("time", "poses/position", "poses/orientation") else data
        f["poses/orientation"].attrs["quaternion_order"] = "wxyz"
    return path


@pytest.mark.parametrize("chunk", [1, 7, 10**9])
@pytest.mark.parametrize("frames", [None, "3:40:4", "-5:"])
def test_chunked_reading_matches_an_independent_conversion(monkeypatch, chunk, frames):
    monkeypatch.setattr(config, "POSE_CHUNK", chunk)
    traj = load_trajectory(FIXTURE / "traj.h5", frames=frames)
    arrays = fixture_arrays()
    expected_index = np.arange(arrays["time"].size)[slice(*(int(p) if p else None for p in frames.split(":")))
                                                       if frames else slice(None)]
    np.testing.assert_array_equal(traj.frame_index, expected_index)
    q = arrays["poses/orientation"][expected_index]
    rotation = Rotation.from_quat(np.roll(q, -1, axis=-1).reshape(-1, 4)).as_matrix().reshape(q.shape[:-1] + (3, 3))
    np.testing.assert_allclose(traj.poses[..., :3], rotation, atol=1e-12)
    np.testing.assert_array_equal(traj.poses[..., 3], arrays["poses/position"][expected_index])


@pytest.mark.parametrize("mode", ["discrete", "continuous"])
def test_selected_frames_give_the_contacts_of_a_cut_trajectory(tmp_path, mode):
    arrays = fixture_arrays()
    cut = write_trajectory(tmp_path / "cut.h5", arrays, slice(10, 60, 2))
    reference = collide.scan(FIXTURE / "meshes", cut, mode=mode)
    selected = collide.scan(FIXTURE / "meshes", FIXTURE / "traj.h5", mode=mode, frames="10:60:2")
    np.testing.assert_array_equal(selected.frame_index, np.arange(10, 60, 2))
    np.testing.assert_array_equal(selected.frame_time, reference.frame_time)
    for name, column in reference.contacts.items():
        np.testing.assert_array_equal(selected.contacts[name], column, err_msg=name)


def test_frames_outside_the_selection_are_never_read(tmp_path):
    """NaN poses outside the selection do not matter; inside it they are named by their
    frame number in the file."""
    arrays = fixture_arrays()
    arrays["poses/position"][:5] = np.nan
    arrays["poses/position"][30, 1, 2] = np.nan
    traj = write_trajectory(tmp_path / "t.h5", arrays)
    result = collide.scan(FIXTURE / "meshes", traj, mode="discrete", frames="5:30")
    assert result.frame_index[0] == 5 and result.frame_index[-1] == 29
    with pytest.raises(InputError, match=r"poses/position.*non-finite value at index \(30, 1, 2\)"):
        collide.scan(FIXTURE / "meshes", traj, mode="discrete", frames="20:40")


def test_errors_name_file_frames_when_reading_in_chunks(tmp_path, monkeypatch):
    monkeypatch.setattr(config, "POSE_CHUNK", 8)
    arrays = fixture_arrays()
    arrays["poses/orientation"][33, 0] *= 2.0
    traj = write_trajectory(tmp_path / "t.h5", arrays)
    with pytest.raises(InputError, match="norm 2 at frame 33, object 0"):
        load_trajectory(traj)
    assert load_trajectory(traj, frames="0:33").poses.shape[0] == 33


# --- scans that read their poses block by block ------------------------------------------------

FIXTURE_OBJECTS = 5  # 3 in the trajectory, 2 static meshes


def count_reads(monkeypatch):
    """The selected-frame ranges a PoseFile reads, as a list that grows as it reads."""
    reads = []
    original = PoseFile.read_checked

    def read_checked(self, start, stop):
        reads.append((start, stop))
        return original(self, start, stop)
    monkeypatch.setattr(PoseFile, "read_checked", read_checked)
    return reads


@pytest.mark.parametrize("mode", ["discrete", "continuous"])
@pytest.mark.parametrize("block, frames, pairs", [(2, "50:110", False), (7, "3:230:3", False),
                                                  (5, "150:200", True)])
def test_contacts_do_not_depend_on_pose_blocks(monkeypatch, mode, block, frames, pairs):
    """A scan that holds a few frames' poses at a time, reading the next ones from the file
    as it goes, finds the contacts (times, triangles, points) and triangle pairs of a
    scan that holds every pose in memory."""
    reference = collide.scan(FIXTURE / "meshes", FIXTURE / "traj.h5", mode=mode, frames=frames,
                             triangle_pairs=pairs)
    assert reference.contacts["object_a"].size > 0
    monkeypatch.setattr(config, "POSE_BLOCK_BYTES", block * FIXTURE_OBJECTS * 12 * 8)
    reads = count_reads(monkeypatch)
    blocked = collide.scan(FIXTURE / "meshes", FIXTURE / "traj.h5", mode=mode, frames=frames, triangle_pairs=pairs)
    n_frames = reference.frame_index.size
    assert max(stop - start for start, stop in reads) <= block + 1  # a block and the next one's first frame
    assert len(reads) >= 2 * (n_frames // block)  # every block checked once, then scanned
    np.testing.assert_array_equal(blocked.frame_time, reference.frame_time)
    for name, column in reference.contacts.items():
        np.testing.assert_array_equal(blocked.contacts[name], column, err_msg=name)
    if pairs:
        assert reference.triangle_pairs["frame"].size > 0
        for name, column in reference.triangle_pairs.items():
            np.testing.assert_array_equal(blocked.triangle_pairs[name], column, err_msg=name)


def test_bad_poses_in_a_later_block_are_refused_before_the_scan(tmp_path, monkeypatch):
    """Read block by block, the poses are still all checked before any work starts: a bad
    quaternion in the last block is named by its file frame, and no output is written."""
    arrays = fixture_arrays()
    arrays["poses/orientation"][230, 2] *= 3.0
    traj = write_trajectory(tmp_path / "t.h5", arrays)
    monkeypatch.setattr(config, "POSE_BLOCK_BYTES", 4 * FIXTURE_OBJECTS * 12 * 8)
    reads = count_reads(monkeypatch)
    with pytest.raises(InputError, match="norm 3 at frame 230, object 2"):
        collide.scan(FIXTURE / "meshes", traj, output=tmp_path / "c.h5")
    assert reads[-1][1] > 230 and len(reads) == 58
    assert not (tmp_path / "c.h5").exists()


def _far_apart_scene(folder, n_frames):
    """Four boxes drifting side by side, never near each other, for n_frames frames."""
    meshes = folder / "meshes"
    meshes.mkdir(parents=True)
    names = [f"box{i}" for i in range(4)]
    for name in names:
        write_box(meshes / f"{name}.stl")
    position = np.zeros((n_frames, 4, 3))
    position[:, :, 0] = np.arange(4) * 10.0
    position[:, :, 1] = np.linspace(0.0, 5.0, n_frames)[:, None]
    traj = write_traj_file(folder / "t.h5", np.arange(n_frames) * 0.01, names, position,
                           identity_quaternions(n_frames, 4))
    return meshes, traj


@pytest.mark.parametrize("mode", ["discrete", "continuous"])
def test_memory_does_not_grow_with_the_number_of_frames(tmp_path, monkeypatch, mode):
    """With poses read a block at a time, ten times more frames cost only the per-frame
    output (frame times: 8 bytes a frame, plus the file's time column and the frame
    index), not the poses (96 bytes a frame for each of 4 objects): peak traced memory
    of the scan (tracemalloc: numpy arrays) for 2 000 and 20 000 frames."""
    import tracemalloc
    monkeypatch.setattr(config, "POSE_BLOCK_BYTES", 500 * 4 * 12 * 8)
    peaks = {}
    for n_frames in (2000, 20000):
        meshes, traj = _far_apart_scene(tmp_path / str(n_frames), n_frames)
        collide.scan(meshes, traj, mode=mode, frames="0:10")  # kernels and imports ready: not counted
        tracemalloc.start()
        result = collide.scan(meshes, traj, mode=mode, workers=1)
        peaks[n_frames] = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert result.contacts["object_a"].size == 0 and result.frame_index.size == n_frames
    grown = peaks[20000] - peaks[2000]
    poses = 18000 * 4 * 12 * 8
    assert grown < 64 * 18000 + 2**20, (peaks, poses)  # 64 bytes a frame for what the scan keeps per frame


def test_rotation_errors_match_numpys_gram_matrix_and_determinant():
    """load.rotation_errors (what refuses non-rigid poses/matrix entries) against einsum's
    R^T R and linalg.det, on rotations, rotations nudged off orthonormal by up to 1e-3,
    reflections and scaled matrices."""
    from collide.load import rotation_errors
    rng = np.random.default_rng(3)
    rotations = Rotation.random(400, random_state=4).as_matrix()
    matrices = np.concatenate([rotations,
                               rotations + rng.normal(scale=1e-3, size=rotations.shape) * rng.random((400, 1, 1)),
                               rotations * np.array([-1.0, 1.0, 1.0]),
                               rotations * rng.uniform(0.5, 2.0, size=(400, 1, 1))]).reshape(4, 400, 3, 3)
    padded = np.zeros((4, 400, 4, 4))  # as poses/matrix holds them
    padded[..., :3, :3] = matrices
    error, det = rotation_errors(padded)
    gram = np.einsum("...ki,...kj->...ij", matrices, matrices)
    assert np.allclose(error, np.abs(gram - np.eye(3)).max(axis=(-2, -1)), rtol=0, atol=1e-15)
    assert np.allclose(det, np.linalg.det(matrices), rtol=0, atol=1e-14)
    assert (error[0] < 1e-14).all() and (error[1] > 0).all() and (det[2] < 0).all()  # reflections: orthonormal


def test_scene_size_is_the_diagonal_of_every_bounding_sphere_at_every_frame(monkeypatch):
    """pipeline.scene_size (what dist_tol scales with), read in blocks of frames, against
    the box of every object's bounding sphere at every frame computed in one go."""
    from collide.packed import pack_scene
    from collide.pipeline import scene_size
    monkeypatch.setattr(config, "POSE_BLOCK_BYTES", 4096)  # blocks of a few frames
    scene = collide.load.load_scene(FIXTURE / "meshes", FIXTURE / "traj.h5")
    ps, _ = pack_scene(scene.meshes, scene.object_mesh)
    assert scene.poses.block < scene.poses.n_frames  # several blocks
    centre, radius = ps.centre[ps.object_mesh], ps.sphere_radius[ps.object_mesh][None, :, None]
    poses = scene.poses.read(0, scene.poses.n_frames)
    world = np.einsum("tnij,nj->tni", poses[..., :3], centre) + poses[..., 3]
    expected = np.linalg.norm((world + radius).max(axis=(0, 1)) - (world - radius).min(axis=(0, 1)))
    assert scene_size(ps, scene.poses) == pytest.approx(expected, rel=1e-15)
