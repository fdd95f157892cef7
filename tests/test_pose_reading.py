"""Poses are read in chunks of frames, and only the frames a scan selects: the same poses
as an independent conversion (scipy's rotations), the same contacts as a trajectory cut to
those frames, and frames outside the selection are never read."""
import h5py
import numpy as np
import pytest
from conftest import REPO
from scipy.spatial.transform import Rotation

import collide
from collide import config
from collide.errors import InputError
from collide.load import load_trajectory

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
