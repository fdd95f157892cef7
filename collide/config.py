"""Tolerances and defaults, in one place.

Every number here has a unit and a reason; change them here, never inline.
"""

# --- input validation -------------------------------------------------------
#: Quaternions whose norm is within this of 1 are normalised (with a warning);
#: others are input errors (SPEC §2.2). Unitless.
QUATERNION_NORM_TOL = 1e-3

#: Pose matrices must satisfy max|R^T R - I| <= this (SPEC §2.2). Unitless.
ROTATION_ORTHONORMAL_TOL = 1e-6

#: The last row of a pose matrix must be within this of (0, 0, 0, 1). Unitless.
MATRIX_LAST_ROW_TOL = 1e-9

# --- broad phase -------------------------------------------------------------
#: Bounding boxes are widened by this fraction of the largest coordinate
#: magnitude involved (plus BOX_MARGIN_ABS), so that float rounding in box
#: transforms can never make the broad phase drop a pair that the exact narrow
#: phase would report. 1e-12 is ~4500 ulps of double precision: far above the
#: rounding of a 3x3 rotation applied to a box, far below any real gap.
BOX_MARGIN_REL = 1e-12

#: Absolute floor for the box margin, in scene length units.
BOX_MARGIN_ABS = 1e-300

# --- continuous mode ----------------------------------------------------------
#: Default time tolerance of reported contact begin/end, as a fraction of the
#: frame interval (SPEC §3).
TIME_TOL = 1e-6

#: Distance below which surfaces count as touching in continuous mode, as a
#: fraction of the scene size (SPEC §3: pairs farther apart are never reported).
DIST_TOL_REL = 1e-9

#: Screw interpolation: scan warns when an object turns by more than this between
#: consecutive frames (the trajectory is then probably under-sampled: a turn of
#: more than 180 degrees looks like a smaller one the other way). Degrees.
SCREW_WARN_DEG = 90.0

#: Screw interpolation: a rotation between two frames whose sine is below this
#: (and cosine negative) is a half turn within the rounding of the pose data; its
#: axis, and so the motion, is ambiguous (an input error). Unitless.
SCREW_HALF_TURN_SIN = 1e-12

#: Screw interpolation: an object pair's step is cut into equal sub-steps until, on
#: each, the objects' paths stay within this fraction of the pair's size (the sum of
#: their bounding-sphere diameters) of their chords. Only affects speed: smaller means
#: more, tighter sub-steps. Unitless.
SUBSTEP_DEVIATION_REL = 1e-3

#: Continuous mode: an object pair touching at one frame of a step only (a contact that
#: ends or begins in it) whose swept BVH descent finds at least this many overlapping leaf
#: pairs has them read in the order they can meet, and its search stops at the first
#: (last) contact; fewer are searched all at once, which costs less per leaf pair. A
#: touching patch moving off or onto the other object reaches thousands (benchmarks/
#: bench_meshsize.py --lift 0.04: 1 700 per step); the searches at 1000 bodies
#: (bench_bodies.py) mostly 20-40. Only affects speed. Leaf pairs.
ONE_SIDED_LEAVES = 256

#: A search for when a contact ends (or begins) between two objects whose meshes both
#: have at least this many triangles, under screw motion, does not descend both BVHs
#: over the whole step (a patch lifting off or landing reaches every leaf pair it sweeps
#: over). Meshes with oriented leaf boxes (LEAF_BOX_TRIANGLES) first probe moments
#: inside the step with frame tests (a few cheap descents that stop at the first
#: touching pair) and then descend only over the part of the step after the last moment
#: found touching (before the first). Bigger meshes search best first: node pairs are
#: taken in the order their time windows reach toward the answer, and the search stops
#: once no window left can move the contact found. Either way the contact found is
#: certified like the whole search's (it may differ from it by at most the time
#: tolerance). Triangles.
PROBED_FACES = 4096

#: Each probe, and the frame test at a step's end of two such meshes apart at its start
#: (whether a contact begins in the step), gives up after this many leaf pairs without
#: a touching triangle pair (a probe that looks near a pair an earlier probe found, after
#: an eighth of them: swept.NEAR_PROBE_SHARE). A probe that gives up counts as if the
#: objects did not touch, and such a frame test leaves the pair to the search without
#: it (its frame test from the swept leaf pairs): the answer stays certified, and more of
#: the step is searched; the contact times may then differ by up to the time tolerance
#: (and the triangle pair named may differ), the same on every run. A contact near the
#: pair looked at first is usually found in the first few leaf pairs, while proving that
#: nothing touches would take all the leaf pairs near the patch. Leaf pairs (0: every
#: probe and such frame test gives up at once).
PROBE_LEAF_PAIRS = 64

#: Linear-vertex interpolation: scan warns where the straight vertex paths depart
#: from the rigid (screw) motion by more than this fraction of the object's size
#: (its bounding-sphere diameter). Unitless.
LINEAR_DEVIATION_WARN_REL = 1e-3

# --- BVH ----------------------------------------------------------------------
#: The BVH construction rules (collide.bvh; the choices of --split), the default first:
#: top-down binned surface area heuristic, median or mean centre; bottom-up Morton-code
#: LBVH (parallel, fastest to build, slower to query).
SPLIT_RULES = ("sah", "median", "mean", "lbvh")

#: The lbvh builder runs its parallel loops on one thread for fewer primitives than this:
#: each parallel loop costs from microseconds (idle cores) to ~10 ms (cores busy with
#: other work) to start and join its threads, a good part of a build this small on one
#: thread (~30 ms). Primitives.
LBVH_PARALLEL_MIN = 1 << 16

#: Default maximum number of triangles per BVH leaf.
DEFAULT_LEAF_SIZE = 4

#: Meshes of at most this many triangles get an oriented box per BVH leaf (packed.py),
#: which the frame tests, and the swept descent under screw motion, use to drop leaf pairs
#: apart along a leaf's normal (a nearly flat patch facing another across a gap): 44 %
#: fewer leaf pairs in the swept descents at 1000 bodies. Bigger meshes skip them: 144
#: bytes per BVH node and about 0.13 s per million triangles at every scan, for leaf pairs
#: that big, nearly touching patches rarely let go. Only affects speed and memory.
#: Triangles.
LEAF_BOX_TRIANGLES = 50_000

#: Number of bins per axis of the binned SAH builder.
SAH_BINS = 16

#: SAH cost of visiting a node relative to testing one primitive.
SAH_TRAVERSAL_COST = 1.0

# --- hostile input and resource limits ----------------------------------------
#: Largest magnitude of any world coordinate (length units): every mesh vertex,
#: every position, and |position| + |vertex| of every object at every frame must
#: stay at or below it. The exact predicates multiply three coordinate
#: differences (and their rounding errors), which overflows float64 beyond about
#: 1e100; continuous collision (collide.ccd) needs |x| < 1e150. Inputs beyond it
#: are refused rather than answered wrongly.
MAX_COORDINATE = 1e90

#: Default memory limit of a command (--max-memory), as a fraction of the
#: machine's physical memory. Unitless.
MAX_MEMORY_FRACTION = 0.5

#: With --triangle-pairs, frames are scanned (and their rows written) this many at
#: a time: the rows of at most 2 x workers such chunks are in memory. Frames.
PAIR_CHUNK_FRAMES = 8

#: Poses are read and converted this many (frame, object) poses at a time, so the
#: conversion's temporaries (about 60 float64 values per pose) stay a few tens of
#: MB whatever the trajectory's length. Count.
POSE_CHUNK = 65536

#: A scan holds the poses of this many bytes of frames at a time (a block: at least
#: 2 frames) and reads the next block from the trajectory file when it needs it, so
#: that its memory does not grow with the trajectory's length. Bytes.
POSE_BLOCK_BYTES = 64 * 2**20

#: Estimated peak bytes per selected (frame, object) pose while a trajectory is
#: read and scanned: the [R | p] array kept (12 float64), a second one when static
#: meshes are added, and the per-pose checks of the whole scene. Bytes.
POSE_BYTES = 256

#: Estimated bytes per string read from an HDF5 dataset (object names, mesh
#: names): the Python str object, its list slot and the HDF5 read buffer. Bytes.
STRING_BYTES = 256

#: Estimated bytes per numeric element read from a file: the read itself plus one
#: converted (float64 / int64) copy. Bytes.
NUMBER_BYTES = 16

#: Largest --leaf-size: a leaf never holds more than a mesh's triangles, and
#: triangle indices are int32 in the output; larger values change nothing.
MAX_LEAF_SIZE = 2**31 - 1

#: Largest --workers (threads): more threads than this only costs memory.
MAX_WORKERS = 1024

#: Largest scan --time-tol, as a fraction of the frame interval: a tolerance of a
#: whole frame interval already says nothing about when within the step a contact
#: begins.
MAX_TIME_TOL = 1.0

#: Default of collide plot --max-pairs: rows (object pairs) drawn at most; beyond it
#: the picture stops being readable.
PLOT_MAX_PAIRS = 200

#: collide plot draws times of magnitude up to this (time units); matplotlib's
#: axis arithmetic (margins, tick formatting) overflows near float64's maximum.
PLOT_MAX_TIME = 1e300

# --- mesh cache (collide.meshcache) ---------------------------------------------
#: Total size of the mesh cache's entries (parsed meshes and BVHs). After each new
#: entry, the least recently used entries are deleted until the total is at most
#: this. Bytes.
CACHE_MAX_BYTES = 1 << 30

#: Meshes or BVHs whose cache entry would be larger than this are not cached (they
#: would push out many smaller entries). Bytes.
CACHE_MAX_ENTRY_BYTES = 1 << 28
