"""--scheduler: the same scan as tasks on a Dask distributed cluster gives the same result."""
import importlib
import pickle
from unittest import mock

import numpy as np
import pytest
from conftest import REPO, run_cli

import collide


@pytest.mark.parametrize("triangle_pairs", [True, False])
def test_scan_on_a_local_dask_cluster_matches_the_local_scan(triangle_pairs):
    """Both continuous paths: frame tests then swept tests (--triangle-pairs), and frame
    tests run inside the swept kernel (the default)."""
    local, remote = _local_and_on_cluster("tunnel", processes=False, triangle_pairs=triangle_pairs)
    assert remote.contacts["t_begin"].size == 1
    _assert_same_contacts(local, remote)


def _local_and_on_cluster(example, processes, **options):
    """collide.scan of an example here, and on a local Dask cluster of two single-thread
    workers (threads of this process, or worker processes)."""
    distributed = pytest.importorskip("distributed")
    meshes, traj = REPO / "examples" / example / "meshes", REPO / "examples" / example / "traj.h5"
    local = collide.scan(meshes, traj, **options)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=processes,
                                  dashboard_address=None) as cluster:
        remote = collide.scan(meshes, traj, scheduler=cluster.scheduler_address, **options)
    return local, remote


def _assert_same_contacts(local, remote):
    for name in local.contacts:
        assert np.array_equal(local.contacts[name], remote.contacts[name], equal_nan=True), name


@pytest.mark.slow  # Dask keeps retrying for its 10 s connect timeout
def test_unreachable_scheduler_is_a_clear_error(two_boxes, tmp_path):
    pytest.importorskip("distributed")
    meshes, traj = two_boxes
    proc = run_cli("scan", meshes, traj, "-o", tmp_path / "c.h5", "--scheduler", "tcp://127.0.0.1:9")
    assert proc.returncode == 2 and "Dask scheduler" in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "c.h5").exists()


def test_tasks_carry_kernels_by_name_and_workers_run_the_module_kernel():
    """A numba dispatcher pickled as such unpickles as a copy without its compiled cache
    (every worker process compiled the frame tests afresh, about 30 s); tasks carry a
    reference that resolves to the module's own dispatcher, and calls it."""
    from collide.discrete import scan_frames
    from collide.pipeline import KernelByName

    ref = pickle.loads(pickle.dumps(KernelByName.of(scan_frames)))
    assert ref == KernelByName("collide.discrete", "scan_frames")
    assert getattr(importlib.import_module(ref.module), ref.name) is scan_frames
    seen = []
    with mock.patch("collide.discrete.scan_frames", lambda *args: seen.append(args) or "hits"):
        assert ref(1, 2, 3) == "hits" and seen == [(1, 2, 3)]


@pytest.mark.slow  # starts two worker processes
@pytest.mark.parametrize("mode", ["discrete", "continuous"])
def test_scan_on_worker_processes_matches_the_local_scan(mode):
    """Worker processes receive the kernels through pickling (threads in this process do
    not), in both modes' chunk kernels: the fixture example, which both modes see touch."""
    local, remote = _local_and_on_cluster("fixture", processes=True, mode=mode)
    assert remote.contacts["t_begin"].size == local.contacts["t_begin"].size >= 1
    _assert_same_contacts(local, remote)
