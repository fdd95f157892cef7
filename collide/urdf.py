"""Robots from URDF: one mesh per link and a link-pose trajectory from joint positions.

``urdf_to_scene`` turns a robot description and a table of joint positions over time
into what ``collide scan`` reads: a folder of link meshes (binary PLY, link frame) and
an HDF5 trajectory whose objects are the links (``poses/matrix``, world poses with the
root link at the identity), plus ``filters/ignore`` listing the link pairs joined by a
joint.

Steps, each a function below:

1. ``load_robot``: parse the URDF with yourdfpy; check that the links form one tree and
   that every joint can be moved.
2. ``read_joints``: joint positions over time from CSV, HDF5 or an in-memory mapping.
3. ``link_meshes``: each link's geometry elements as one triangle mesh in the link frame.
4. ``link_poses``: yourdfpy's forward kinematics at every frame.
5. ``adjacent_pairs``: parent-child link pairs, skipping links without geometry.
6. write the meshes (temporary folder renamed into place) and the trajectory (atomic).

yourdfpy is an optional dependency (``pip install 'collide[urdf]'``), imported only
inside these functions.
"""
import csv
import logging
import math
import os
import re
import shutil
import tempfile
from contextlib import contextmanager
from functools import partial
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .errors import InputError, UsageError
from .files import open_hdf5
from .load import _numeric, _read_float, _read_strings, _Source, _strings, load_mesh
from .output import atomic_path, check_not_an_input, check_output_path

log = logging.getLogger("collide")

#: Joint types that JOINTS can move, and the ones that stay where their <origin> puts them.
MOVABLE_JOINTS = ("revolute", "continuous", "prismatic")
FIXED_JOINTS = ("fixed", "floating", "planar")

GEOMETRY_KINDS = ("collision", "visual")

#: Tessellation of URDF primitives. Vertices lie on the true surface, so the meshes
#: are inscribed: a sphere becomes an icosphere of 1280 triangles (subdivision 3), a
#: cylinder a 32-sided prism (128 triangles).
SPHERE_SUBDIVISIONS = 3
CYLINDER_SECTIONS = 32

MESH_SUFFIX = ".ply"

URDF_EXPECTED = "a URDF robot description (XML with one <robot> element)"
JOINTS_EXPECTED = ("an HDF5 file (time, joints/name, joints/position) or a CSV file with a "
                   "time column and one column per joint")
IN_MEMORY = "<joints>"


class JointTrajectory(NamedTuple):
    """Joint positions over time, as read from JOINTS."""
    source: str             #: file path, or "<joints>" for in-memory data
    time: np.ndarray        #: float64 (T,), strictly increasing
    names: list             #: J joint names
    position: np.ndarray    #: float64 (T, J): radians (revolute, continuous) or length (prismatic)
    time_unit: str          #: unit attribute of the source's time, or None
    name_dataset: str       #: where the names live in the source (for messages), or None


class UrdfScene(NamedTuple):
    """What ``urdf_to_scene`` wrote."""
    robot: str              #: the URDF's robot name
    objects: list           #: link names, in URDF order: trajectory objects and mesh files
    mesh_files: list        #: Path of each object's mesh (same order)
    frames: int             #: T
    ignore: list            #: (a, b) link-name pairs written to filters/ignore (unescaped)
    joints_at_zero: list    #: movable joints that JOINTS does not list (held at 0)
    fallback_links: list    #: links whose mesh comes from the other geometry kind


# --- entry point -----------------------------------------------------------------------------

def urdf_to_scene(urdf_path, joints, meshes_out, trajectory_out, geometry="collision",
                  ignore_adjacent=True, force=False):
    """Write a meshes folder and a trajectory for ``collide scan`` from a URDF robot.

    Parameters
    ----------
    urdf_path : path of the URDF file; mesh files it names are found relative to its folder.
    joints : path of a CSV or HDF5 file of joint positions (see ``read_joints``), or a
        mapping (dict, pandas DataFrame) {"time": (T,), joint name: (T,), ...}.
    meshes_out : folder to create with one binary PLY per link that has geometry.
        An existing non-empty folder is refused unless ``force`` (then files of the same
        name are replaced and other files are kept).
    trajectory_out : HDF5 trajectory to write (replaced only by a complete new file).
    geometry : "collision" or "visual": which elements make a link's mesh (a link
        without any of that kind uses the other kind).
    ignore_adjacent : write the parent-child link pairs to ``filters/ignore``.

    Returns
    -------
    UrdfScene
    """
    if geometry not in GEOMETRY_KINDS:
        raise UsageError(f"unknown geometry {geometry!r}; expected one of {', '.join(GEOMETRY_KINDS)}")
    _yourdfpy()
    inputs = [urdf_path] + ([joints] if isinstance(joints, (str, os.PathLike)) else [])
    check_output_path(trajectory_out, inputs)
    _check_meshes_folder(Path(meshes_out), force)

    robot = load_robot(urdf_path)
    motion = read_joints(joints)
    columns, ignored, at_zero = _movable_columns(robot, motion)
    meshes, fallback = link_meshes(robot, urdf_path, geometry)
    # nothing written may replace a file read, nor a mesh file the URDF names (either geometry kind)
    inputs += named_mesh_files(robot, urdf_path)
    check_output_path(trajectory_out, inputs)
    _warn_joints(motion.source, ignored, at_zero)
    links = list(meshes)
    poses = link_poses(robot, {motion.names[j]: motion.position[:, j] for j in columns},
                       motion.time.shape[0], links)
    ignore = adjacent_pairs(robot, links) if ignore_adjacent else None

    stems = mesh_file_stems(links)
    for stem, link in zip(stems, links):
        mesh_out = Path(meshes_out) / f"{stem}{MESH_SUFFIX}"
        check_not_an_input(mesh_out, inputs)
        if os.path.realpath(mesh_out) == os.path.realpath(trajectory_out):
            raise InputError(trajectory_out, f"is where link {link!r}'s mesh goes",
                             "a trajectory path outside --meshes-out or of another name")
    staged = _stage_meshes(Path(meshes_out), {stem: meshes[link] for stem, link in zip(stems, links)})
    try:
        with atomic_path(trajectory_out) as tmp:
            write_trajectory(tmp, motion, links, stems, poses, ignore,
                             {"robot": robot.name, "urdf": str(urdf_path), "geometry": geometry})
        _place_meshes(staged, Path(meshes_out))
    finally:
        shutil.rmtree(staged, ignore_errors=True)
    mesh_files = [Path(meshes_out) / f"{stem}{MESH_SUFFIX}" for stem in stems]
    return UrdfScene(robot.name, links, mesh_files, int(motion.time.shape[0]), ignore or [], at_zero,
                     fallback)


def _yourdfpy():
    try:
        import yourdfpy
    except ImportError:
        raise UsageError("collide urdf needs the yourdfpy package: pip install 'collide[urdf]'") from None
    return yourdfpy


@contextmanager
def _yourdfpy_quiet():
    """Silence yourdfpy's log while it runs: collide checks what it would warn about
    (unresolved mesh files, disconnected links, broken mimic joints) and raises instead."""
    logger = logging.getLogger("yourdfpy")
    level = logger.level
    logger.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        logger.setLevel(level)


# --- 1. the robot ------------------------------------------------------------------------------

def load_robot(urdf_path):
    """Parse and check a URDF file; returns the ``yourdfpy.Robot``.

    Raises InputError unless the file is well-formed XML whose links form one tree
    (one root, each link the child of at most one joint) and whose joints can be
    evaluated (known types, finite origins, non-zero axes, mimic joints following a
    movable joint). Joint axes are normalised in place: URDF axes are directions, and
    yourdfpy moves a prismatic joint by ``q * axis`` as written.
    """
    yourdfpy = _yourdfpy()
    path = Path(urdf_path)
    if not path.exists():
        raise InputError(path, "no such file", URDF_EXPECTED)
    if path.is_dir():
        raise InputError(path, "is a folder", URDF_EXPECTED)
    _check_xml(path)
    try:
        with _yourdfpy_quiet():
            model = yourdfpy.URDF.load(str(path), build_scene_graph=False, build_collision_scene_graph=False,
                                       load_meshes=False, load_collision_meshes=False)
    except KeyError as exc:
        raise InputError(path, f"an element lacks the attribute {exc.args[0]!r}", URDF_EXPECTED) from None
    except Exception as exc:  # yourdfpy raises whatever its parsing hits (ValueError, TypeError, ...)
        raise InputError(path, f"cannot read URDF ({_first_line(exc)})", URDF_EXPECTED) from None
    robot = model.robot
    _link_parents(robot, path)
    _check_joints(robot, path)
    return robot


def _first_line(exc):
    text = str(exc).strip().splitlines()
    return (text[0][:120] if text else type(exc).__name__)


def _check_xml(path):
    """Strict XML check first: yourdfpy falls back to a recovering parser that would
    silently accept a truncated file."""
    from lxml import etree  # a yourdfpy dependency
    try:
        root = etree.parse(str(path)).getroot()
    except OSError as exc:
        raise InputError(path, f"cannot read file ({_first_line(exc)})", URDF_EXPECTED) from None
    except etree.XMLSyntaxError as exc:
        raise InputError(path, f"not well-formed XML ({_first_line(exc)})", URDF_EXPECTED) from None
    if root.tag != "robot":
        raise InputError(path, f"root element is <{root.tag}>", URDF_EXPECTED)


def _link_parents(robot, path):
    """{child link: parent link} of the robot's joints; raises InputError unless the
    links form one tree."""
    names = [link.name for link in robot.links]
    if not names:
        raise InputError(path, "robot has no <link>", "at least one link")
    _require_unique(names, path, "link")
    _require_unique([j.name for j in robot.joints], path, "joint")
    known = set(names)
    parent = {}
    for joint in robot.joints:
        for end in (joint.parent, joint.child):
            if end not in known:
                raise InputError(path, f"joint {joint.name!r} names unknown link {end!r}",
                                 "joints between links defined in the file")
        if joint.child in parent:
            raise InputError(path, f"link {joint.child!r} is the child of two joints",
                             "a tree: each link the child of at most one joint")
        parent[joint.child] = joint.parent
    roots = [name for name in names if name not in parent]
    if len(roots) != 1:
        problem = (f"{len(roots)} root links ({', '.join(roots[:5])})" if roots
                   else "no root link (the joints form a loop)")
        raise InputError(path, problem, "one tree of links connected by joints")
    for name in names:
        link, steps = name, 0
        while link in parent:
            link, steps = parent[link], steps + 1
            if steps > len(names):
                raise InputError(path, f"the joints form a loop through link {name!r}",
                                 "one tree of links connected by joints")
    return parent


def _require_unique(names, path, what):
    seen = set()
    for name in names:
        if name in seen:
            raise InputError(path, f"two {what}s named {name!r}", f"unique {what} names")
        seen.add(name)


def _check_joints(robot, path):
    """Joint types, origins, axes and mimic leaders (see ``load_robot``)."""
    by_name = {j.name: j for j in robot.joints}
    for joint in robot.joints:
        where = f"joint {joint.name!r}"
        if joint.type not in MOVABLE_JOINTS + FIXED_JOINTS:
            raise InputError(path, f"{where} has type {joint.type!r}",
                             "one of " + ", ".join(MOVABLE_JOINTS + FIXED_JOINTS))
        if joint.origin is not None and not np.isfinite(joint.origin).all():
            raise InputError(path, f"{where} has a non-finite <origin>", "finite xyz and rpy")
        if joint.type in MOVABLE_JOINTS:
            axis = np.asarray(joint.axis, dtype=np.float64)
            length = np.linalg.norm(axis) if axis.shape == (3,) else 0.0
            if not (np.isfinite(length) and length > 0):
                raise InputError(path, f"{where} has axis {joint.axis.tolist()}", "a non-zero <axis xyz>")
            joint.axis = axis / length
        if joint.mimic is not None:
            leader = by_name.get(joint.mimic.joint)
            if leader is None or leader.type not in MOVABLE_JOINTS or leader.mimic is not None:
                raise InputError(path, f"{where} mimics {joint.mimic.joint!r}",
                                 "a mimic joint following a revolute, continuous or prismatic "
                                 "joint that is not itself a mimic joint")
            if not (math.isfinite(joint.mimic.multiplier) and math.isfinite(joint.mimic.offset)):
                raise InputError(path, f"{where} has a non-finite mimic multiplier or offset",
                                 "finite numbers")
    held = [j.name for j in robot.joints if j.type in ("floating", "planar")]
    if held:
        log.warning("%s: floating and planar joints stay at their <origin>: %s", path, ", ".join(held))


# --- 2. joint positions ---------------------------------------------------------------------------

def read_joints(joints):
    """Joint positions over time.

    ``joints`` is one of
      - an HDF5 file: ``time`` float (T,), ``joints/name`` str (J,), ``joints/position``
        float (T, J);
      - a CSV file (comma-separated, header row): a ``time`` column and one column per joint;
      - a mapping {"time": (T,), joint name: (T,), ...} (dict, pandas DataFrame).
    Times must be finite and strictly increasing (T >= 1); positions finite, in radians
    (revolute, continuous) or the URDF's length unit (prismatic). Returns JointTrajectory.
    """
    if isinstance(joints, (str, os.PathLike)):
        path = Path(joints)
        if not path.exists():
            raise InputError(path, "no such file", JOINTS_EXPECTED)
        if path.is_dir():
            raise InputError(path, "is a folder", JOINTS_EXPECTED)
        return _read_joints_hdf5(path) if _is_hdf5(path) else _read_joints_csv(path)
    if hasattr(joints, "keys"):
        return _joints_from_mapping(joints)
    raise UsageError(f"joints must be a file path or a mapping of columns, not {type(joints).__name__}")


def _is_hdf5(path):
    import h5py
    try:
        return h5py.is_hdf5(path)
    except OSError as exc:
        raise InputError(path, f"cannot read file ({exc.strerror})", JOINTS_EXPECTED) from None


def _read_joints_hdf5(path):
    h5 = open_hdf5(path, JOINTS_EXPECTED)
    with h5:
        src = _Source(h5, Path(path), False)
        expected = "frame times, float (T,)"
        time = _read_float(src, _numeric(src, "time", (None,), expected), "time", expected)
        expected = "joint names, str (J,)"
        names = _read_strings(src, _strings(src, "joints/name", expected), "joints/name", expected)
        expected = "joint positions, one row per time and one column per joints/name"
        position = _read_float(src, _numeric(src, "joints/position", (time.shape[0], len(names)), expected),
                               "joints/position", expected)
        unit = h5["time"].attrs.get("unit")
    unit = unit.decode() if isinstance(unit, bytes) else (None if unit is None else str(unit))
    _check_time(time, path, "time", lambda k: f"index {k}")
    _check_names(names, path, "joints/name")
    return JointTrajectory(str(path), time, names, position, unit, "joints/name")


def _read_joints_csv(path):
    """Read a CSV of floats: header row with ``time`` and joint names, one row per frame."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            reader = csv.reader(f)
            rows = [(reader.line_num, row) for row in reader if any(cell.strip() for cell in row)]
    except UnicodeDecodeError:
        raise InputError(path, "not UTF-8 text (and not HDF5)", JOINTS_EXPECTED) from None
    except csv.Error as exc:
        raise InputError(path, f"cannot read as CSV ({exc})", JOINTS_EXPECTED) from None
    except OSError as exc:
        raise InputError(path, f"cannot read file ({exc.strerror})", JOINTS_EXPECTED) from None
    if not rows:
        raise InputError(path, "empty file", JOINTS_EXPECTED)
    header = [cell.strip() for cell in rows[0][1]]
    if "time" not in header:
        raise InputError(path, f"no 'time' column (header: {', '.join(header)[:100]})", JOINTS_EXPECTED)
    if any(not name for name in header):
        raise InputError(path, "empty column name in the header", "a name for every column")
    _check_names(header, path, None)
    values = np.empty((len(rows) - 1, len(header)))
    for r, (line, row) in enumerate(rows[1:]):
        if len(row) != len(header):
            raise InputError(path, f"line {line} has {len(row)} values, the header {len(header)}",
                             "one value per column on every line")
        for c, cell in enumerate(row):
            values[r, c] = _csv_number(cell, path, header[c], line)
    if values.shape[0] == 0:
        raise InputError(path, "no rows after the header", "at least one frame")
    lines = [line for line, _ in rows[1:]]
    t = header.index("time")
    time = np.ascontiguousarray(values[:, t])
    _check_time(time, path, "time", lambda k: f"line {lines[k]}")
    names = header[:t] + header[t + 1:]
    position = np.ascontiguousarray(np.delete(values, t, axis=1))
    return JointTrajectory(str(path), time, names, position, None, None)


def _csv_number(cell, path, column, line):
    try:
        value = float(cell)
    except ValueError:
        raise InputError(path, f"line {line}: {cell.strip()!r} is not a number", "numbers",
                         dataset=column) from None
    if not math.isfinite(value):
        raise InputError(path, f"line {line}: {cell.strip()}", "finite numbers", dataset=column)
    return value


def _joints_from_mapping(mapping):
    """{"time": (T,), joint: (T,)} -> JointTrajectory; errors name the key."""
    keys = [str(k) for k in mapping.keys()]
    if "time" not in keys:
        raise InputError(IN_MEMORY, "no 'time' entry", "a mapping with 'time' and one entry per joint")
    columns = {}
    for key in keys:
        try:
            column = np.asarray(mapping[key], dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(IN_MEMORY, "not numbers", "float values", dataset=key) from None
        if column.ndim != 1:
            raise InputError(IN_MEMORY, f"has shape {column.shape}", "a 1-D column (T,)", dataset=key)
        if not np.isfinite(column).all():
            k = int(np.flatnonzero(~np.isfinite(column))[0])
            raise InputError(IN_MEMORY, f"non-finite value at index {k}", "finite numbers", dataset=key)
        columns[key] = column
    time = columns.pop("time")
    for key, column in columns.items():
        if column.shape != time.shape:
            raise InputError(IN_MEMORY, f"has {column.shape[0]} values, time {time.shape[0]}",
                             "one value per time", dataset=key)
    _check_time(time, IN_MEMORY, "time", lambda k: f"index {k}")
    names = list(columns)
    position = np.stack([columns[n] for n in names], axis=1) if names else np.zeros((time.shape[0], 0))
    return JointTrajectory(IN_MEMORY, time, names, position, None, None)


def _check_time(time, source, dataset, row):
    """Times float64 (T,) must be strictly increasing with T >= 1; ``row(k)`` names row k."""
    if time.shape[0] < 1:
        raise InputError(source, "no frames", "at least one time", dataset=dataset)
    steps = np.diff(time)
    if (steps <= 0).any():
        k = int(np.argmax(steps <= 0)) + 1
        before, after = float(time[k - 1]), float(time[k])
        raise InputError(source, f"not strictly increasing at {row(k)} ({before!r} then {after!r})",
                         "strictly increasing times", dataset=dataset)


def _check_names(names, source, dataset):
    seen = set()
    for name in names:
        if not name:
            raise InputError(source, "empty joint name", "non-empty names", dataset=dataset)
        if name in seen:
            raise InputError(source, f"joint {name!r} listed twice", "each joint once", dataset=dataset)
        seen.add(name)


def _movable_columns(robot, motion):
    """Match JOINTS columns to the robot's joints.

    Returns (indices of the columns that move joints, listed joints whose values are
    ignored (fixed and mimic joints: mimic joints follow their leader), movable joints
    not listed (held at 0)). Unknown joint names and joints that cannot take a value
    (floating, planar) are errors."""
    joints = {j.name: j for j in robot.joints}
    movable = [j.name for j in robot.joints if j.type in MOVABLE_JOINTS and j.mimic is None]
    unknown = [n for n in motion.names if n not in joints]
    if unknown:
        listed = ", ".join(movable[:12]) + (", ..." if len(movable) > 12 else "")
        raise InputError(motion.source, f"unknown joint{'s' * (len(unknown) > 1)} "
                         f"{', '.join(map(repr, unknown))} (robot {robot.name!r})",
                         f"joints of the robot ({listed or 'it has no movable joints'})",
                         dataset=motion.name_dataset)
    held = [n for n in motion.names if joints[n].type in ("floating", "planar")]
    if held:
        raise InputError(motion.source, f"joint {held[0]!r} is {joints[held[0]].type}",
                         "revolute, continuous or prismatic joints (floating and planar joints "
                         "stay at their origin)", dataset=motion.name_dataset)
    ignored = [n for n in motion.names if n not in movable]
    at_zero = [n for n in movable if n not in motion.names]
    return [motion.names.index(n) for n in movable if n in motion.names], ignored, at_zero


def _warn_joints(source, ignored, at_zero):
    """One warning per kind, after all input checks passed."""
    if ignored:
        log.warning("%s: values of fixed and mimic joints are ignored (mimic joints follow their "
                    "leader): %s", source, ", ".join(ignored))
    if at_zero:
        log.warning("%s: joints not listed stay at 0: %s", source, ", ".join(at_zero))


# --- 3. link meshes --------------------------------------------------------------------------------

def link_meshes(robot, urdf_path, geometry="collision"):
    """Each link's geometry as one triangle mesh in the link frame.

    A link's elements of the chosen kind ("collision" or "visual"; the other kind when the
    link has none) are merged in file order, each with its <origin> (and a mesh's
    ``scale``) applied. Links without geometry are left out.

    Returns ({link name: (vertices float64 (V, 3), faces int64 (F, 3))} in URDF link
    order, [links that used the other kind]).
    """
    import trimesh  # noqa: F401  (primitives below)
    path = Path(urdf_path)
    resolve = _file_resolver(path)
    chosen, other = (("collisions", "visuals") if geometry == "collision" else ("visuals", "collisions"))
    meshes, fallback = {}, []
    for link in robot.links:
        attribute = chosen if getattr(link, chosen) else other
        elements = getattr(link, attribute)
        if not elements:
            continue
        if attribute == other:
            fallback.append(link.name)
        kind = attribute[:-1]
        parts = [_element_mesh(e, resolve, path, f"link {link.name!r} <{kind}>") for e in elements]
        meshes[link.name] = _merge(parts)
    if not meshes:
        raise InputError(path, "no link has <collision> or <visual> geometry",
                         "at least one link with geometry")
    if fallback:
        other_kind = other[:-1]
        log.warning("%s: links without <%s> geometry use their <%s> geometry: %s", path, geometry,
                    other_kind, ", ".join(fallback))
    return meshes, fallback


def _file_resolver(urdf_path):
    """resolve(fname=...) -> the path of a file a URDF names (relative to its folder,
    package:// looked up there and in its parents)."""
    return partial(_yourdfpy().filename_handler_magic, dir=str(Path(urdf_path).absolute().parent))


def named_mesh_files(robot, urdf_path):
    """The existing files that the URDF's <mesh> elements name, of both geometry kinds."""
    resolve = _file_resolver(urdf_path)
    found = []
    for link in robot.links:
        for element in list(link.visuals) + list(link.collisions):
            mesh = element.geometry.mesh if element.geometry is not None else None
            if mesh is not None and mesh.filename:
                with _yourdfpy_quiet():
                    path = resolve(fname=mesh.filename)
                if os.path.isfile(path):
                    found.append(path)
    return found


def _element_mesh(element, resolve, urdf_path, where):
    """One <collision>/<visual> element -> (vertices float64 (V, 3), faces int64 (F, 3)) in the
    link frame."""
    import trimesh
    g = element.geometry
    if g.box is not None:
        size = _positive(g.box.size, (3,), urdf_path, f"{where} box size")
        mesh = trimesh.creation.box(extents=size)
    elif g.cylinder is not None:
        radius, length = _positive([g.cylinder.radius, g.cylinder.length], (2,), urdf_path,
                                   f"{where} cylinder radius and length")
        mesh = trimesh.creation.cylinder(radius=radius, height=length, sections=CYLINDER_SECTIONS)
    elif g.sphere is not None:
        (radius,) = _positive([g.sphere.radius], (1,), urdf_path, f"{where} sphere radius")
        mesh = trimesh.creation.icosphere(subdivisions=SPHERE_SUBDIVISIONS, radius=radius)
    elif g.mesh is not None:
        vertices, faces = _referenced_mesh(g.mesh, resolve, urdf_path, where)
        mesh = None
    else:
        raise InputError(urdf_path, f"{where} has an empty <geometry>", "a box, cylinder, sphere or mesh")
    if mesh is not None:
        vertices, faces = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)
    origin = np.eye(4) if element.origin is None else np.asarray(element.origin, np.float64)
    if not np.isfinite(origin).all():
        raise InputError(urdf_path, f"{where} has a non-finite <origin>", "finite xyz and rpy")
    return vertices @ origin[:3, :3].T + origin[:3, 3], faces


def _positive(values, shape, urdf_path, what):
    array = np.asarray(values, dtype=np.float64)
    if array.shape != shape or not (np.isfinite(array) & (array > 0)).all():
        raise InputError(urdf_path, f"{what}: {np.atleast_1d(array).tolist()}",
                         f"{shape[0]} positive finite number{'s' * (shape[0] > 1)}")
    return array


def _referenced_mesh(mesh, resolve, urdf_path, where):
    """Load a <mesh filename=... scale=...> element's file and scale it (origin not applied)."""
    if not mesh.filename:
        raise InputError(urdf_path, f"{where} <mesh> has no filename", "<mesh filename=\"...\">")
    with _yourdfpy_quiet():
        found = resolve(fname=mesh.filename)
    if not os.path.isfile(found):
        raise InputError(urdf_path, f"{where}: mesh file {mesh.filename!r} not found",
                         "the file at that path relative to the URDF's folder (package://NAME/ is "
                         "looked up in that folder and its parents)")
    loaded = load_mesh(found)
    scale = np.float64(1.0) if mesh.scale is None else np.asarray(mesh.scale, dtype=np.float64)
    if scale.shape not in ((), (1,), (3,)) or not np.isfinite(scale).all():
        raise InputError(urdf_path, f"{where} mesh scale {np.atleast_1d(scale).tolist()}",
                         "one or three finite numbers")
    return loaded.vertices * scale, loaded.faces


def _merge(parts):
    """Concatenate [(vertices (V_i, 3), faces (F_i, 3))] into one mesh, faces re-indexed."""
    offsets = np.cumsum([0] + [v.shape[0] for v, _ in parts[:-1]])
    vertices = np.concatenate([v for v, _ in parts])
    faces = np.concatenate([f + offset for (_, f), offset in zip(parts, offsets)])
    return np.ascontiguousarray(vertices), np.ascontiguousarray(faces, dtype=np.int64)


# --- 4. link poses ---------------------------------------------------------------------------------

def link_poses(robot, joint_values, n_frames, links):
    """World poses float64 (T, N, 4, 4) of ``links`` (root link at the identity).

    ``joint_values`` maps movable joint names to positions float (T,); other joints stay
    at 0 and mimic joints follow their leader. Forward kinematics is yourdfpy's, on a copy
    of the robot without geometry.
    """
    yourdfpy = _yourdfpy()
    bare = yourdfpy.Robot(name=robot.name, links=[yourdfpy.Link(name=link.name) for link in robot.links],
                          joints=robot.joints)
    with _yourdfpy_quiet():
        model = yourdfpy.URDF(robot=bare, build_scene_graph=True, load_meshes=False)
    names = list(joint_values)
    values = np.stack([np.asarray(joint_values[n], np.float64) for n in names], axis=1) if names \
        else np.zeros((n_frames, 0))
    poses = np.empty((n_frames, len(links), 4, 4))
    for t in range(n_frames):
        model.update_cfg({name: float(q) for name, q in zip(names, values[t])})
        for i, link in enumerate(links):
            poses[t, i] = model.get_transform(link)
    poses[..., 3, :] = (0.0, 0.0, 0.0, 1.0)
    return poses


# --- 5. adjacent links -------------------------------------------------------------------------------

def adjacent_pairs(robot, links):
    """Link pairs joined by a joint, among ``links`` (those with geometry): each link and its
    nearest ancestor in ``links``. Links without geometry are skipped over, so a link and its
    grandchild through a geometry-less link (e.g. a fixed flange frame) count as adjacent.
    Returns [(ancestor, link)] in the order of ``links``."""
    parent = {j.child: j.parent for j in robot.joints}
    with_geometry = set(links)
    pairs = []
    for link in links:
        ancestor = parent.get(link)
        while ancestor is not None and ancestor not in with_geometry:
            ancestor = parent.get(ancestor)
        if ancestor is not None:
            pairs.append((ancestor, link))
    return pairs


def glob_escape(name):
    """A glob pattern that matches exactly ``name``: ``*``, ``?`` and ``[`` become ``[*]``,
    ``[?]`` and ``[[]`` (fnmatch syntax)."""
    return re.sub(r"([*?[])", r"[\1]", name)


# --- 6. writing ---------------------------------------------------------------------------------------

def mesh_file_stems(links):
    """A file stem per link: the link name, or for names unsafe as file names (path
    separators, leading dots, other characters outside ``A-Za-z0-9._-``) a cleaned name;
    unique without regard to case."""
    stems, taken = [], set()
    for name in links:
        stem = re.sub(r"[^A-Za-z0-9._-]", "_", name).lstrip(".") or "link"
        candidate, k = stem, 1
        while candidate.lower() in taken:
            k += 1
            candidate = f"{stem}_{k}"
        taken.add(candidate.lower())
        stems.append(candidate)
    return stems


def write_ply(path, vertices, faces):
    """Binary little-endian PLY with float64 ("double") vertices (V, 3) and int32 triangles
    (F, 3), in the given order. (trimesh's PLY and STL writers round vertices to float32.)"""
    header = ("ply\nformat binary_little_endian 1.0\ncomment collide urdf: link frame\n"
              f"element vertex {vertices.shape[0]}\n"
              "property double x\nproperty double y\nproperty double z\n"
              f"element face {faces.shape[0]}\nproperty list uchar int vertex_indices\nend_header\n")
    rows = np.empty(faces.shape[0], dtype=[("count", "u1"), ("index", "<i4", (3,))])
    rows["count"] = 3
    rows["index"] = faces
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(np.ascontiguousarray(vertices, dtype="<f8").tobytes())
        f.write(rows.tobytes())


def write_trajectory(path, motion, links, stems, poses, ignore, attrs):
    """Write the trajectory HDF5: time, objects/name (+ objects/mesh when a stem differs from
    its link name), poses/matrix (T, N, 4, 4), filters/ignore str (K, 2) of glob-escaped link
    names unless ``ignore`` is None, and the string attributes ``attrs``."""
    import h5py
    strings = h5py.string_dtype()
    with h5py.File(path, "w") as h5:
        h5["time"] = motion.time
        if motion.time_unit is not None:
            h5["time"].attrs["unit"] = motion.time_unit
        h5.create_dataset("objects/name", data=np.array(links, dtype=object), dtype=strings)
        if stems != links:
            h5.create_dataset("objects/mesh", data=np.array(stems, dtype=object), dtype=strings)
        h5["poses/matrix"] = poses
        if ignore is not None:
            patterns = np.array([[glob_escape(a), glob_escape(b)] for a, b in ignore], dtype=object)
            h5.create_dataset("filters/ignore", data=patterns.reshape(-1, 2), dtype=strings)
        for key, value in attrs.items():
            h5.attrs[key] = value
        h5.attrs["source"] = "collide urdf"


def _check_meshes_folder(folder, force):
    """Raise InputError unless ``folder`` can become the meshes folder."""
    parent = folder.parent if str(folder.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(folder, "parent folder does not exist", "a folder path in an existing folder")
    if folder.exists() and not folder.is_dir():
        raise InputError(folder, "is a file", "a folder for the link meshes")
    if not os.access(parent, os.W_OK):
        raise InputError(folder, "parent folder is not writable", "a writable folder")
    if folder.is_dir() and any(folder.iterdir()) and not force:
        raise InputError(folder, "folder is not empty",
                         "a new or empty folder for the link meshes (--force writes into it, "
                         "replacing files of the same name)")


def _stage_meshes(folder, meshes):
    """Write {stem: (vertices, faces)} as PLY files into a new hidden folder next to
    ``folder``; returns its path (removed again if writing fails)."""
    parent = folder.parent if str(folder.parent) else Path(".")
    try:
        staged = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", suffix=".tmp", dir=parent))
    except OSError as exc:
        raise InputError(folder, f"cannot write next to it ({exc.strerror})", "a writable folder") from None
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(staged, 0o777 & ~umask)
        for stem, (vertices, faces) in meshes.items():
            write_ply(staged / f"{stem}{MESH_SUFFIX}", vertices, faces)
    except BaseException:
        shutil.rmtree(staged, ignore_errors=True)
        raise
    return staged


def _place_meshes(staged, folder):
    """Rename the staged folder to ``folder`` (an empty ``folder`` is replaced); into an
    existing non-empty folder, move the files one by one (same names replaced, other
    files kept, with a warning naming the other mesh files)."""
    names = sorted(p.name for p in staged.iterdir())
    try:
        if folder.is_dir() and not any(folder.iterdir()):
            folder.rmdir()
        if not folder.exists():
            os.rename(staged, folder)
        else:
            for name in names:
                os.replace(staged / name, folder / name)
            _warn_other_meshes(folder, set(names))
    except OSError as exc:
        raise InputError(folder, f"cannot place the meshes ({exc.strerror})", "a writable folder") from None


def _warn_other_meshes(folder, ours):
    from .load import _mesh_suffixes
    suffixes = _mesh_suffixes()
    others = sorted(p.name for p in folder.iterdir()
                    if p.is_file() and p.suffix.lower() in suffixes and p.name not in ours
                    and not p.name.startswith("."))
    if others:
        listed = ", ".join(others[:5]) + (", ..." if len(others) > 5 else "")
        log.warning("%s also holds %d other mesh files (%s): collide scan reads them as static "
                    "objects", folder, len(others), listed)
