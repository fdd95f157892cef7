"""--scheduler: the same scan as tasks on a Dask distributed cluster gives the same result."""
import numpy as np
import pytest
from conftest import REPO, run_cli

import collide


@pytest.mark.parametrize("triangle_pairs", [True, False])
def test_scan_on_a_local_dask_cluster_matches_the_local_scan(triangle_pairs):
    """Both continuous paths: frame tests then swept tests (--triangle-pairs), and frame
    tests run inside the swept kernel (the default)."""
    distributed = pytest.importorskip("distributed")
    meshes, traj = REPO / "examples" / "tunnel" / "meshes", REPO / "examples" / "tunnel" / "traj.h5"
    local = collide.scan(meshes, traj, triangle_pairs=triangle_pairs)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        remote = collide.scan(meshes, traj, triangle_pairs=triangle_pairs, scheduler=cluster.scheduler_address)
    assert remote.contacts["t_begin"].size == 1
    for name in local.contacts:
        assert np.array_equal(local.contacts[name], remote.contacts[name], equal_nan=True), name


@pytest.mark.slow  # Dask keeps retrying for its 10 s connect timeout
def test_unreachable_scheduler_is_a_clear_error(two_boxes, tmp_path):
    pytest.importorskip("distributed")
    meshes, traj = two_boxes
    proc = run_cli("scan", meshes, traj, "-o", tmp_path / "c.h5", "--scheduler", "tcp://127.0.0.1:9")
    assert proc.returncode == 2 and "Dask scheduler" in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "c.h5").exists()
