"""The mesh cache returns exactly what the uncached loader and builder return, skips
them when warm, and never trusts (or fails on) a bad entry or cache folder."""
import json
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import threading

import numpy as np
import pytest
import trimesh
from conftest import DATA, REPO

import collide
from collide import config
from collide import meshcache as mc
from collide.bvh import BVH, build_mesh_bvh
from collide.errors import InputError
from collide.load import load_mesh


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """An empty cache folder (COLLIDE_CACHE_DIR) under tmp_path."""
    folder = tmp_path / "cache"
    monkeypatch.setenv(mc.CACHE_ENV, str(folder))
    return folder


@pytest.fixture
def rob(tmp_path):
    """A copy of tests/data/rob.obj (216 triangles) in a meshes folder."""
    folder = tmp_path / "meshes"
    folder.mkdir()
    return shutil.copy(DATA / "rob.obj", folder / "rob.obj")


def same_arrays(a, b):
    """Bit for bit: dtype, shape and bytes (so -0.0 differs from 0.0)."""
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def same_mesh(cached, reference):
    return (cached.name == reference.name and cached.path == reference.path
            and same_arrays(cached.vertices, reference.vertices) and same_arrays(cached.faces, reference.faces))


def same_bvh(cached, reference):
    return isinstance(cached, BVH) and all(same_arrays(a, b) for a, b in zip(cached, reference))


def entries(folder, kind=""):
    return sorted(p.name for p in folder.glob(f"{kind}*.npz"))


def forbid(monkeypatch, target):
    """Make ``target`` ("module.attr") raise if called."""
    def refuse(*args, **kwargs):
        raise AssertionError(f"{target} called on a warm cache")
    monkeypatch.setattr(target, refuse)


# --- warm loads skip the parser and the builder ---------------------------------------------------

def test_second_load_is_read_from_the_cache_bit_for_bit(cache, rob, monkeypatch):
    reference = load_mesh(rob)
    stats = mc.CacheStats()
    assert same_mesh(mc.load_mesh_cached(rob, mc.file_sha256(rob), stats=stats), reference)
    assert entries(cache) == entries(cache, "mesh-") and len(entries(cache)) == 1
    forbid(monkeypatch, "trimesh.load")
    forbid(monkeypatch, "collide.meshcache.load_mesh")
    warm = mc.load_mesh_cached(rob, mc.file_sha256(rob), stats=stats)
    assert same_mesh(warm, reference)
    assert warm.vertices.flags.c_contiguous and warm.faces.flags.c_contiguous
    assert warm.vertices.flags.writeable
    assert stats.as_dict() == {"mesh_hits": 1, "mesh_misses": 1, "bvh_hits": 0, "bvh_misses": 0,
                               "rejected": 0, "stored": 1, "evicted": 0}


def test_hash_is_computed_when_not_given(cache, rob, monkeypatch):
    reference = load_mesh(rob)
    mc.load_mesh_cached(rob)
    forbid(monkeypatch, "trimesh.load")
    assert same_mesh(mc.load_mesh_cached(rob), reference)


def test_same_bytes_elsewhere_share_the_entry_under_their_own_name(cache, rob, tmp_path, monkeypatch):
    mc.load_mesh_cached(rob)
    other = tmp_path / "elsewhere" / "arm.obj"
    other.parent.mkdir()
    shutil.copy(rob, other)
    reference = load_mesh(other)
    forbid(monkeypatch, "trimesh.load")
    assert same_mesh(mc.load_mesh_cached(other), reference)
    assert len(entries(cache)) == 1


@pytest.mark.parametrize("split", config.SPLIT_RULES)
def test_second_bvh_is_read_from_the_cache_bit_for_bit(cache, rob, split, monkeypatch):
    mesh = load_mesh(rob)
    reference = build_mesh_bvh(mesh.vertices, mesh.faces, split, 3)
    stats = mc.CacheStats()
    assert same_bvh(mc.mesh_bvh_cached(mesh, split, 3, stats=stats), reference)
    forbid(monkeypatch, "collide.meshcache.build_mesh_bvh")
    assert same_bvh(mc.mesh_bvh_cached(mesh, split, 3, stats=stats), reference)
    assert (stats.bvh_hits, stats.bvh_misses, stats.rejected) == (1, 1, 0)


def test_default_leaf_size_is_the_configured_one(cache, rob, monkeypatch):
    mesh = load_mesh(rob)
    mc.build_mesh_bvh_cached(mesh.vertices, mesh.faces, "sah", None)
    forbid(monkeypatch, "collide.meshcache.build_mesh_bvh")
    reference = build_mesh_bvh(mesh.vertices, mesh.faces, "sah", config.DEFAULT_LEAF_SIZE)
    assert same_bvh(mc.build_mesh_bvh_cached(mesh.vertices, mesh.faces, "sah", config.DEFAULT_LEAF_SIZE),
                    reference)


def test_bvh_options_get_their_own_entries_and_share_the_mesh(cache, rob, monkeypatch):
    options = [("sah", 4), ("sah", 2), ("median", 4), ("mean", 1), ("lbvh", 4)]
    for split, leaf_size in options:
        mesh = mc.load_mesh_cached(rob)
        mc.mesh_bvh_cached(mesh, split, leaf_size)
    assert len(entries(cache, "mesh-")) == 1
    assert len(entries(cache, "bvh-")) == len(options)
    forbid(monkeypatch, "collide.meshcache.build_mesh_bvh")
    forbid(monkeypatch, "trimesh.load")
    mesh = mc.load_mesh_cached(rob)
    for split, leaf_size in options:
        assert same_bvh(mc.mesh_bvh_cached(mesh, split, leaf_size),
                        build_mesh_bvh(mesh.vertices, mesh.faces, split, leaf_size))


def test_bvh_of_other_arrays_is_not_reused(cache, rob):
    mesh = load_mesh(rob)
    mc.mesh_bvh_cached(mesh)
    moved = mesh.vertices.copy()
    moved[0, 0] = np.nextafter(moved[0, 0], np.inf)
    stats = mc.CacheStats()
    assert same_bvh(mc.build_mesh_bvh_cached(moved, mesh.faces, stats=stats),
                    build_mesh_bvh(moved, mesh.faces))
    assert stats.bvh_misses == 1 and len(entries(cache, "bvh-")) == 2


def test_same_bytes_with_another_suffix_are_another_entry(cache, rob):
    mc.load_mesh_cached(rob)
    as_ply = rob.with_suffix(".ply")
    shutil.copy(rob, as_ply)  # OBJ text is not a PLY file: the loader must see it
    with pytest.raises(InputError) as cached_error:
        mc.load_mesh_cached(as_ply)
    with pytest.raises(InputError) as reference_error:
        load_mesh(as_ply)
    assert str(cached_error.value) == str(reference_error.value)
    assert mc.mesh_key(".obj", "0" * 64) != mc.mesh_key(".stl", "0" * 64)
    assert mc.mesh_key(".OBJ", "0" * 64) == mc.mesh_key(".obj", "0" * 64)  # load_mesh ignores case


def test_a_modified_file_misses(cache, rob, monkeypatch):
    mc.load_mesh_cached(rob)
    rob.write_bytes(rob.read_bytes().replace(b"v -500 ", b"v -501 ", 1))
    reference = load_mesh(rob)
    stats = mc.CacheStats()
    assert same_mesh(mc.load_mesh_cached(rob, stats=stats), reference)
    assert stats.mesh_misses == 1 and len(entries(cache, "mesh-")) == 2


def test_a_wrong_digest_is_never_stored(cache, rob):
    reference = load_mesh(rob)
    assert same_mesh(mc.load_mesh_cached(rob, "ab" * 32), reference)
    assert entries(cache) == []
    with pytest.raises(ValueError):
        mc.load_mesh_cached(rob, "not a digest")


def test_errors_are_the_loaders_and_are_not_cached(cache, tmp_path):
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\n")
    with pytest.raises(InputError) as error:
        mc.load_mesh_cached(bad)
    assert "no triangles" in str(error.value)
    with pytest.raises(InputError):
        mc.load_mesh_cached(tmp_path / "missing.obj")
    assert entries(cache) == []


def test_files_that_reference_other_files_are_not_cached(cache, tmp_path):
    path = tmp_path / "box.gltf"
    trimesh.creation.box().export(path)  # geometry in a separate buffer
    reference = load_mesh(path)
    for _ in range(2):
        assert same_mesh(mc.load_mesh_cached(path), reference)
    assert entries(cache, "mesh-") == []


def test_use_cache_false_reads_and_writes_nothing(cache, rob):
    reference = load_mesh(rob)
    stats = mc.CacheStats()
    mesh = mc.load_mesh_cached(rob, use_cache=False, stats=stats)
    bvh = mc.mesh_bvh_cached(mesh, use_cache=False, stats=stats)
    assert same_mesh(mesh, reference) and same_bvh(bvh, build_mesh_bvh(reference.vertices, reference.faces))
    assert not cache.exists()
    assert (stats.mesh_misses, stats.bvh_misses, stats.stored) == (1, 1, 0)


def test_mesh_cache_object_records_digests_for_provenance(cache, rob, monkeypatch):
    from collide.pipeline import _sha256
    for enabled in (False, True, True):
        loader = mc.MeshCache(enabled=enabled)
        mesh = loader.load_mesh(rob)
        loader.build_mesh_bvh(mesh.vertices, mesh.faces, "sah", None)
        assert loader.digests == {rob: _sha256(rob)}
    assert loader.stats.mesh_hits == 1 and loader.stats.bvh_hits == 1
    with pytest.raises(InputError):
        mc.MeshCache().load_mesh(rob.parent / "missing.obj")


# --- bad entries are rebuilt silently ------------------------------------------------------------

def write_entry(path, key, **arrays):
    """An entry with a correct header for ``key`` and these arrays."""
    header = np.frombuffer(json.dumps({"format": mc.CACHE_FORMAT, "key": key}).encode(), np.uint8)
    with open(path, "wb") as f:
        np.savez(f, header=header, **arrays)


def mesh_entry(folder, path):
    key = mc.mesh_key(path.suffix, mc.file_sha256(path))
    return mc._entry_path(folder, key), key


def corrupt_mesh_entries():
    """name -> function(entry path, key, reference mesh, other valid entry path) that spoils it."""
    def junk(entry, key, ref, other):
        entry.write_bytes(os.urandom(3000))

    def truncated(entry, key, ref, other):
        entry.write_bytes(entry.read_bytes()[: entry.stat().st_size // 2])

    def empty(entry, key, ref, other):
        entry.write_bytes(b"")

    def flipped_byte(entry, key, ref, other):  # inside the vertex data: the zip CRC-32 catches it
        data = bytearray(entry.read_bytes())
        at = data.find(ref.vertices.tobytes()[:64]) + 100
        data[at] ^= 0x01
        entry.write_bytes(bytes(data))

    def foreign(entry, key, ref, other):  # another mesh's valid entry under this name
        shutil.copy(other, entry)

    def other_format(entry, key, ref, other):
        header = json.dumps({"format": mc.CACHE_FORMAT + 1, "key": key}).encode()
        with open(entry, "wb") as f:
            np.savez(f, header=np.frombuffer(header, np.uint8), vertices=ref.vertices, faces=ref.faces)

    def faces_out_of_range(entry, key, ref, other):
        faces = ref.faces.copy()
        faces[-1, 2] = ref.vertices.shape[0]
        write_entry(entry, key, vertices=ref.vertices, faces=faces)

    def negative_face(entry, key, ref, other):
        faces = ref.faces.copy()
        faces[0, 0] = -1
        write_entry(entry, key, vertices=ref.vertices, faces=faces)

    def float32_vertices(entry, key, ref, other):
        write_entry(entry, key, vertices=ref.vertices.astype(np.float32), faces=ref.faces)

    def int32_faces(entry, key, ref, other):
        write_entry(entry, key, vertices=ref.vertices, faces=ref.faces.astype(np.int32))

    def big_endian(entry, key, ref, other):
        write_entry(entry, key, vertices=ref.vertices.astype(">f8"), faces=ref.faces)

    def wrong_shape(entry, key, ref, other):
        write_entry(entry, key, vertices=ref.vertices[:, :2].copy(), faces=ref.faces)

    def no_faces(entry, key, ref, other):
        write_entry(entry, key, vertices=ref.vertices, faces=np.zeros((0, 3), np.int64))

    def fortran_order(entry, key, ref, other):
        write_entry(entry, key, vertices=np.asfortranarray(ref.vertices), faces=ref.faces)

    def nan_vertex(entry, key, ref, other):
        vertices = ref.vertices.copy()
        vertices[3, 1] = np.nan
        write_entry(entry, key, vertices=vertices, faces=ref.faces)

    def far_vertex(entry, key, ref, other):
        vertices = ref.vertices.copy()
        vertices[3, 1] = 1e200
        write_entry(entry, key, vertices=vertices, faces=ref.faces)

    def missing_member(entry, key, ref, other):
        write_entry(entry, key, vertices=ref.vertices)

    def object_array(entry, key, ref, other):
        write_entry(entry, key, vertices=ref.vertices, faces=np.array([object()] * 3, dtype=object))

    def compressed(entry, key, ref, other):
        header = json.dumps({"format": mc.CACHE_FORMAT, "key": key}).encode()
        with open(entry, "wb") as f:
            np.savez_compressed(f, header=np.frombuffer(header, np.uint8), vertices=ref.vertices,
                                faces=ref.faces)

    def garbage_header(entry, key, ref, other):
        with open(entry, "wb") as f:
            np.savez(f, header=np.frombuffer(b"\xff{not json", np.uint8), vertices=ref.vertices,
                     faces=ref.faces)

    def a_folder(entry, key, ref, other):
        entry.unlink()
        entry.mkdir()

    return {f.__name__: f for f in (junk, truncated, empty, flipped_byte, foreign, other_format,
                                    faces_out_of_range, negative_face, float32_vertices, int32_faces,
                                    big_endian, wrong_shape, no_faces, fortran_order, nan_vertex,
                                    far_vertex, missing_member, object_array, compressed, garbage_header,
                                    a_folder)}


@pytest.mark.parametrize("spoil", sorted(corrupt_mesh_entries()))
def test_bad_mesh_entries_are_rebuilt_silently(cache, rob, tmp_path, spoil, caplog):
    other = tmp_path / "meshes" / "env.obj"
    shutil.copy(DATA / "env.obj", other)
    mc.load_mesh_cached(other)
    other_entry, _ = mesh_entry(cache, other)
    reference = load_mesh(rob)
    mc.load_mesh_cached(rob)
    entry, key = mesh_entry(cache, rob)
    corrupt_mesh_entries()[spoil](entry, key, reference, other_entry)
    stats = mc.CacheStats()
    with caplog.at_level(logging.INFO, logger="collide"):
        assert same_mesh(mc.load_mesh_cached(rob, stats=stats), reference)
    assert [r for r in caplog.records if r.levelno >= logging.INFO] == []
    assert (stats.mesh_hits, stats.mesh_misses, stats.rejected) == (0, 1, 1)
    if spoil != "a_folder":  # an entry in the way that cannot be replaced stays a miss
        assert stats.stored == 1
        again = mc.CacheStats()
        assert same_mesh(mc.load_mesh_cached(rob, stats=again), reference)
        assert again.mesh_hits == 1


def corrupt_bvh_entries():
    """name -> function(bvh arrays dict) -> spoiled arrays dict (a valid tree of 216 triangles)."""
    def fewer_prim_ids(a):
        a["prim_ids"] = a["prim_ids"][:-1]

    def duplicate_prim_id(a):
        a["prim_ids"][0] = a["prim_ids"][1]

    def prim_id_out_of_range(a):
        a["prim_ids"][0] = 10**6

    def leaf_past_the_end(a):
        leaf = np.flatnonzero(a["count"] > 0)[-1]
        a["first"][leaf] = a["prim_ids"].shape[0]

    def overlapping_leaves(a):
        leaf = np.flatnonzero(a["count"] > 0)[3]
        a["first"][leaf] -= 1

    def huge_first(a):
        leaf = np.flatnonzero(a["count"] > 0)[0]
        a["first"][leaf] = np.iinfo(np.int64).max

    def negative_count(a):
        a["count"][np.flatnonzero(a["count"] > 0)[0]] = -1

    def leaf_too_big(a):
        leaf = np.flatnonzero(a["count"] > 0)[0]
        a["count"][leaf] = 99

    def child_before_parent(a):
        inner = np.flatnonzero(a["count"] == 0)[1]
        a["first"][inner] = 0

    def child_past_the_end(a):
        inner = np.flatnonzero(a["count"] == 0)[-1]
        a["first"][inner] = a["count"].shape[0] - 1

    def shared_child(a):
        inner = np.flatnonzero(a["count"] == 0)
        a["first"][inner[2]] = a["first"][inner[1]]

    def extra_node(a):
        for k in ("lo", "hi", "first", "count"):
            a[k] = np.concatenate([a[k], a[k][-1:]])

    def fewer_nodes(a):
        for k in ("lo", "hi", "first", "count"):
            a[k] = a[k][:-1]

    def nan_box(a):
        a["lo"][5, 1] = np.nan

    def infinite_box(a):
        a["hi"][0, 2] = np.inf

    def shrunk_leaf_box(a):
        leaf = np.flatnonzero(a["count"] > 0)[2]
        a["lo"][leaf] = np.nextafter(a["lo"][leaf], np.inf)

    def grown_inner_box(a):
        a["hi"][0, 0] += 1.0

    def swapped_leaves(a):  # both leaves keep their boxes but hold each other's triangles
        l0, l1 = np.flatnonzero(a["count"] > 0)[:2]
        a["first"][[l0, l1]] = a["first"][[l1, l0]]
        a["count"][[l0, l1]] = a["count"][[l1, l0]]

    def siblings_out_of_smallest_id_order(a):  # a valid tree, but the second child holds the smaller ids
        left = a["first"][0]
        for k in ("lo", "hi", "first", "count"):
            a[k][[left, left + 1]] = a[k][[left + 1, left]]

    def leaf_not_ascending(a):
        leaf = np.flatnonzero(a["count"] > 1)[0]
        start = a["first"][leaf]
        a["prim_ids"][start:start + 2] = a["prim_ids"][start:start + 2][::-1].copy()

    def float32_boxes(a):
        a["lo"] = a["lo"].astype(np.float32)

    def int32_ids(a):
        a["prim_ids"] = a["prim_ids"].astype(np.int32)

    def two_dim_count(a):
        a["count"] = a["count"][:, None]

    return {f.__name__: f for f in (fewer_prim_ids, duplicate_prim_id, prim_id_out_of_range,
                                    leaf_past_the_end, overlapping_leaves, huge_first, negative_count,
                                    leaf_too_big, child_before_parent, child_past_the_end, shared_child,
                                    extra_node, fewer_nodes, nan_box, infinite_box, shrunk_leaf_box,
                                    grown_inner_box, swapped_leaves, siblings_out_of_smallest_id_order,
                                    leaf_not_ascending, float32_boxes, int32_ids, two_dim_count)}


@pytest.mark.parametrize("spoil", sorted(corrupt_bvh_entries()))
def test_bad_bvh_entries_are_rebuilt_silently(cache, rob, spoil, caplog):
    mesh = load_mesh(rob)
    reference = build_mesh_bvh(mesh.vertices, mesh.faces, "sah", 4)
    key = mc.bvh_key(mesh.vertices, mesh.faces, "sah", 4)
    entry = mc._entry_path(cache, key)
    mc.mesh_bvh_cached(mesh, "sah", 4)
    assert entry.exists()
    arrays = {k: v.copy() for k, v in reference._asdict().items()}
    corrupt_bvh_entries()[spoil](arrays)
    write_entry(entry, key, **arrays)
    stats = mc.CacheStats()
    with caplog.at_level(logging.INFO, logger="collide"):
        assert same_bvh(mc.mesh_bvh_cached(mesh, "sah", 4, stats=stats), reference)
    assert [r for r in caplog.records if r.levelno >= logging.INFO] == []
    assert (stats.bvh_hits, stats.bvh_misses, stats.rejected, stats.stored) == (0, 1, 1, 1)
    assert same_bvh(mc.mesh_bvh_cached(mesh, "sah", 4, stats=stats), reference)
    assert stats.bvh_hits == 1


def test_bvh_checks_accept_every_builder_output():
    """No false alarms: the checks pass on real trees of every rule and leaf size."""
    for name in ("rob.obj", "env.obj"):
        mesh = load_mesh(DATA / name)
        for split in config.SPLIT_RULES:
            for leaf_size in (1, 2, 4, 7):
                bvh = build_mesh_bvh(mesh.vertices, mesh.faces, split, leaf_size)
                mc.check_bvh_arrays(bvh._asdict(), mesh.vertices, mesh.faces, leaf_size)
    one = np.array([[0, 1, 2]])
    vertices = np.eye(3)
    mc.check_bvh_arrays(build_mesh_bvh(vertices, one, "sah", 1)._asdict(), vertices, one, 1)


# --- cache locations that cannot be used ----------------------------------------------------------

def test_a_cache_path_under_a_file_turns_caching_off_with_one_info_line(tmp_path, rob, monkeypatch, caplog):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    monkeypatch.setenv(mc.CACHE_ENV, str(blocker / "cache"))
    reference = load_mesh(rob)
    with caplog.at_level(logging.INFO, logger="collide"):
        for _ in range(3):
            mesh = mc.load_mesh_cached(rob)
            assert same_mesh(mesh, reference)
            assert same_bvh(mc.mesh_bvh_cached(mesh), build_mesh_bvh(mesh.vertices, mesh.faces))
    messages = [r.getMessage() for r in caplog.records]
    assert len(messages) == 1 and "caching is off" in messages[0] and caplog.records[0].levelno == logging.INFO


def test_a_cache_path_that_is_a_file_turns_caching_off(tmp_path, rob, monkeypatch, caplog):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    monkeypatch.setenv(mc.CACHE_ENV, str(blocker))
    with caplog.at_level(logging.INFO, logger="collide"):
        assert same_mesh(mc.load_mesh_cached(rob), load_mesh(rob))
        assert same_mesh(mc.load_mesh_cached(rob), load_mesh(rob))
    assert len(caplog.records) == 1
    assert blocker.read_text() == "not a folder"


def test_an_unwritable_cache_is_still_read(cache, rob, monkeypatch, caplog):
    mc.load_mesh_cached(rob)  # one entry, written while it could be

    def read_only(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr("collide.meshcache.tempfile.mkstemp", read_only)
    mesh = load_mesh(rob)
    stats = mc.CacheStats()
    with caplog.at_level(logging.INFO, logger="collide"):
        assert same_mesh(mc.load_mesh_cached(rob, stats=stats), mesh)  # hit
        for split in ("median", "mean"):  # misses that cannot be stored
            assert same_bvh(mc.mesh_bvh_cached(mesh, split, stats=stats),
                            build_mesh_bvh(mesh.vertices, mesh.faces, split))
    assert (stats.mesh_hits, stats.bvh_misses, stats.stored) == (1, 2, 0)
    assert len(caplog.records) == 1 and "permission denied" in caplog.records[0].getMessage()
    assert [p.name for p in cache.iterdir() if not p.name.endswith(".npz")] == []


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0, reason="root writes anywhere")
def test_a_read_only_folder_works(tmp_path, rob, monkeypatch):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o500)
    monkeypatch.setenv(mc.CACHE_ENV, str(folder / "cache"))
    try:
        assert same_mesh(mc.load_mesh_cached(rob), load_mesh(rob))
    finally:
        folder.chmod(0o700)


# --- concurrency ----------------------------------------------------------------------------------

def test_concurrent_writers_and_readers_of_one_key(cache, rob):
    mesh = load_mesh(rob)
    cache.mkdir()
    key = mc.mesh_key(".obj", mc.file_sha256(rob))
    entry = mc._entry_path(cache, key)
    arrays = {"vertices": mesh.vertices, "faces": mesh.faces}
    start, done = threading.Barrier(5), threading.Event()
    seen, stats = [], mc.CacheStats()

    def write():
        start.wait()
        for _ in range(20):
            mc._store(cache, entry, key, arrays, None)

    def read():
        start.wait()
        while not done.is_set() or not seen or not seen[-1]:
            found = mc._lookup(entry, key, mc._MESH_MEMBERS, mc.check_mesh_arrays, stats)
            seen.append(found is not None and same_arrays(found["faces"], mesh.faces))

    writers = [threading.Thread(target=write) for _ in range(4)]
    reader = threading.Thread(target=read)
    for t in writers + [reader]:
        t.start()
    for t in writers:
        t.join()
    done.set()
    reader.join()
    assert stats.rejected == 0 and all(seen[seen.index(True):])
    assert sorted(p.name for p in cache.iterdir()) == [entry.name]
    assert same_mesh(mc.load_mesh_cached(rob), mesh)


WRITER = """
import sys
from pathlib import Path
from collide import meshcache as mc
from collide.load import load_mesh
path, folder = Path(sys.argv[1]), Path(sys.argv[2])
mesh = load_mesh(path)
key = mc.mesh_key(path.suffix, mc.file_sha256(path))
entry = mc._entry_path(folder, key)
print("ready", flush=True)
sys.stdin.readline()
for _ in range(40):
    mc._store(folder, entry, key, {"vertices": mesh.vertices, "faces": mesh.faces}, None)
"""


def test_concurrent_writer_processes_leave_a_readable_entry(cache, tmp_path):
    path = shutil.copy(DATA / "env.obj", tmp_path / "env.obj")
    cache.mkdir()
    env = dict(os.environ, PYTHONPATH=str(REPO))
    writers = [subprocess.Popen([sys.executable, "-c", WRITER, str(path), str(cache)], env=env,
                                stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True) for _ in range(2)]
    for w in writers:
        assert w.stdout.readline().strip() == "ready"
    for w in writers:  # start both at once
        w.stdin.write("go\n")
        w.stdin.flush()
    reference = load_mesh(path)
    key = mc.mesh_key(".obj", mc.file_sha256(path))
    stats = mc.CacheStats()
    while any(w.poll() is None for w in writers):
        found = mc._lookup(mc._entry_path(cache, key), key, mc._MESH_MEMBERS, mc.check_mesh_arrays, stats)
        assert found is None or same_arrays(found["vertices"], reference.vertices)
    assert [w.wait() for w in writers] == [0, 0]
    assert stats.rejected == 0
    assert len(list(cache.iterdir())) == 1
    hits = mc.CacheStats()
    assert same_mesh(mc.load_mesh_cached(path, stats=hits), reference) and hits.mesh_hits == 1


# --- size policy and housekeeping -----------------------------------------------------------------

def test_least_recently_used_entries_are_evicted(cache, tmp_path, monkeypatch):
    paths = []
    for k in range(4):
        paths.append(tmp_path / f"m{k}.obj")
        trimesh.creation.box(extents=(1.0 + k, 1.0, 1.0)).export(paths[-1])
    stats = mc.CacheStats()
    for k, path in enumerate(paths):
        mc.load_mesh_cached(path, stats=stats)
        entry = mesh_entry(cache, path)[0]
        os.utime(entry, (1e9 + k, 1e9 + k))  # distinct ages, oldest first
        if k == 0:
            monkeypatch.setattr(config, "CACHE_MAX_BYTES", int(2.5 * entry.stat().st_size))
    count, total = mc.cache_size(cache)
    assert count == 2 and total <= config.CACHE_MAX_BYTES and stats.evicted == 2
    assert [mesh_entry(cache, p)[0].exists() for p in paths] == [False, False, True, True]


def test_a_hit_marks_an_entry_as_recently_used(cache, rob):
    mc.load_mesh_cached(rob)
    entry = mesh_entry(cache, rob)[0]
    os.utime(entry, (1e9, 1e9))
    mc.load_mesh_cached(rob)
    assert entry.stat().st_mtime > 1e9 + 1


def test_entries_above_the_entry_limit_are_not_stored(cache, rob, monkeypatch):
    monkeypatch.setattr(config, "CACHE_MAX_ENTRY_BYTES", 100)
    reference = load_mesh(rob)
    stats = mc.CacheStats()
    assert same_mesh(mc.load_mesh_cached(rob, stats=stats), reference)
    assert stats.stored == 0 and entries(cache) == []


def test_size_clear_and_stale_temporary_files(cache, rob):
    mesh = mc.load_mesh_cached(rob)
    mc.mesh_bvh_cached(mesh)
    count, total = mc.cache_size()
    assert count == 2 and total == sum(p.stat().st_size for p in cache.glob("*.npz"))
    digest = "0" * 64
    stale, fresh = cache / f".bvh-{digest}.abc_12.tmp", cache / f".mesh-{digest}.xyz.tmp"
    others = [cache / "notes.txt", cache / ".other.abc.tmp", cache / f"mesh-{digest}.npz.bak",
              cache / "mesh-mine.npz"]
    fd, killed = tempfile.mkstemp(prefix=f".mesh-{digest}.", suffix=".tmp", dir=cache)  # as _store names it
    os.close(fd)
    os.utime(killed, (1e9, 1e9))
    for p in [stale, fresh] + others:
        p.write_text("x")
        os.utime(p, (1e9, 1e9))
    os.utime(fresh)
    assert mc.clear_cache() == (2, total)
    assert sorted(p.name for p in cache.iterdir()) == sorted(p.name for p in [fresh] + others)
    assert mc.cache_size() == (0, 0)


# --- location -------------------------------------------------------------------------------------

def test_cache_dir_follows_the_environment_and_the_platform(tmp_path, monkeypatch):
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setenv(mc.CACHE_ENV, str(tmp_path / "mine"))
    assert mc.cache_dir() == tmp_path / "mine"
    monkeypatch.setenv(mc.CACHE_ENV, "")
    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert mc.cache_dir() == tmp_path / "xdg" / "collide"
    monkeypatch.setenv("XDG_CACHE_HOME", "relative/ignored")
    assert mc.cache_dir() == tmp_path / "home" / ".cache" / "collide"
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert mc.cache_dir() == tmp_path / "home" / ".cache" / "collide"
    monkeypatch.setattr(sys, "platform", "darwin")
    assert mc.cache_dir() == tmp_path / "home" / "Library" / "Caches" / "collide"
    monkeypatch.setattr(sys, "platform", "win32")
    monkeypatch.setenv("LOCALAPPDATA", str(tmp_path / "local"))
    assert mc.cache_dir() == tmp_path / "local" / "collide" / "Cache"


def test_second_scan_reuses_parsed_meshes_and_bvhs(tmp_path, monkeypatch):
    """Through the command line: a warm scan parses nothing and builds no BVH (the
    summary's cache line), gives the same contacts and provenance hashes, and --no-cache
    bypasses the cache."""
    from conftest import run_cli
    monkeypatch.setenv("COLLIDE_CACHE_DIR", str(tmp_path / "cache"))
    fixture = REPO / "examples" / "fixture"
    summaries, files = [], []
    for k, extra in enumerate(([], [], ["--no-cache"])):
        out = tmp_path / f"c{k}.h5"
        proc = run_cli("scan", fixture / "meshes", fixture / "traj.h5", "-o", out, "--mode", "discrete",
                       "--format", "json", *extra)
        assert proc.returncode == 0, proc.stderr
        summaries.append(json.loads(proc.stdout)["cache"])
        files.append(collide.read_contacts(out))
    cold, warm, off = summaries
    assert cold["enabled"] and cold["mesh_hits"] == 0 and cold["bvh_hits"] == 0
    assert warm["mesh_hits"] == 4 and warm["mesh_misses"] == 0 and warm["bvh_hits"] == 4
    assert off == {**off, "enabled": False, "mesh_hits": 0, "bvh_hits": 0}
    for other in files[1:]:
        for name, column in files[0].contacts.items():
            np.testing.assert_array_equal(other.contacts[name], column, err_msg=name)
        assert other.provenance["inputs"]["meshes"] == files[0].provenance["inputs"]["meshes"]
