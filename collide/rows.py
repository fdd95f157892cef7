"""Layouts of the rows the scan kernels hand back to Python, by column name.

- Frame hits, int64 (H, HIT_WIDTH): one row per object pair in contact at a frame
  (discrete.scan_frames, and swept.scan_intervals when it runs the frame tests).
- Triangle pairs, int64 (P, PAIR_WIDTH): one row per intersecting triangle pair at a
  frame (discrete.scan_frames, with --triangle-pairs).
- Swept contacts, one row per object pair and motion step in which they touch
  (swept.scan_intervals), as two arrays of equal length: ids int64 (R, SWEPT_WIDTH)
  and times float64 (R, TIMES_WIDTH), fractions of the step.

Object indices index the scene's objects; triangle indices are the mesh file's faces.
"""

# frame hits
HIT_FRAME = 0      #: analysed frame index
HIT_A = 1          #: object_a (< object_b)
HIT_B = 2          #: object_b
HIT_PAIRS = 3      #: intersecting triangle pairs found (1 when the search stopped at the first)
HIT_TRI_A = 4      #: a touching triangle pair: the smallest (or the first found)
HIT_TRI_B = 5
HIT_SMALLEST = 6   #: 1 when (tri_a, tri_b) is known to be the smallest, 0 when it may be the first found
HIT_WIDTH = 7

# triangle pairs
PAIR_FRAME = 0
PAIR_A = 1
PAIR_B = 2
PAIR_TRI_A = 3
PAIR_TRI_B = 4
PAIR_WIDTH = 5

# swept contacts: ids
SWEPT_STEP = 0     #: step k: from analysed frame k to k + 1
SWEPT_A = 1
SWEPT_B = 2
SWEPT_TRI_A = 3    #: the smallest triangle pair touching at the first contact
SWEPT_TRI_B = 4
SWEPT_WIDTH = 5
# swept contacts: times
T_BEGIN = 0        #: first contact, fraction of the step (conservative: never late)
T_END = 1          #: last contact, fraction of the step (never early)
TIMES_WIDTH = 2

# work counters: int64 (COUNT_WIDTH,), summed over kernel calls (the scan summary's "work")
COUNT_OBJECT_PAIRS = 0   #: object pairs whose BVHs were descended (after the cheap culls)
COUNT_NODE_PAIRS = 1     #: BVH node pairs tested in those descents
COUNT_LEAF_PAIRS = 2     #: overlapping leaf pairs found
COUNT_TRIANGLE_PAIRS = 3  #: triangle pairs tested (box, exact predicate or swept box)
COUNT_CCD_PAIRS = 4      #: triangle-pair continuous searches (15 primitive queries each at most)
COUNT_CCD_QUERIES = 5    #: primitive queries not excluded at once (they search boxes)
COUNT_BOX_CHECKS = 6     #: boxes those searches checked
COUNT_SUBSTEPS = 7       #: sub-steps of fast-turning object pairs searched
COUNT_SPLITS = 8         #: triangle-pair sub-step splits of the screw refinement
COUNT_WIDTH = 9
COUNT_NAMES = ("object_pairs", "node_pairs", "leaf_pairs", "triangle_pairs", "ccd_pairs", "ccd_queries",
               "box_checks", "substeps", "splits")
