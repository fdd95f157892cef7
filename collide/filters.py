"""Which object pairs a scan checks: pair filters from name globs.

Users say which pairs to skip (``--ignore A:B``, and the trajectory's own
``filters/ignore`` list: an allowed-collision matrix that travels with the motion)
and, optionally, which pairs alone to check (``--only A:B``). A pattern pair is two
``fnmatch`` globs on object names, unordered: ``A:B`` matches the pair (a, b) when a
matches A and b matches B, or the other way round.

A filter is data for the kernels, not code: for each of K pattern pairs, a bit per
object saying whether its name matches the first glob and a bit whether it matches
the second, packed into uint64 words (``PairFilter``). The kernels check a pair with a
few AND operations (``pair_selected``) before any bounding-volume work, so a filtered
pair costs nothing. Pairs of objects that never move (static objects) are tested
once, not at every frame: the scan adds them to the filter of the per-frame pass as
one more ignored pattern pair, and checks them alone in a one-off pass.
"""
import fnmatch
import re
from typing import NamedTuple

import numpy as np

from .errors import InputError, UsageError
from .jit import njit_borrowing


class PairFilter(NamedTuple):
    """Pair filter of N objects (see module docstring); words W = ceil(K / 64)."""
    ignore_a: np.ndarray  #: uint64 (N, W): bit k of object o: o matches glob A of ignored pattern k
    ignore_b: np.ndarray  #: uint64 (N, W): ... glob B of ignored pattern k
    only_a: np.ndarray    #: uint64 (N, W'): the same for the --only patterns
    only_b: np.ndarray    #: uint64 (N, W')
    has_only: bool        #: True when --only patterns were given: pairs must match one


@njit_borrowing
def _matches(side_a, side_b, a, b):
    for w in range(side_a.shape[1]):
        if (side_a[a, w] & side_b[b, w]) | (side_a[b, w] & side_b[a, w]):
            return True
    return False


@njit_borrowing
def pair_selected(pairs, a, b):
    """Objects a and b are to be checked against each other under the PairFilter."""
    if _matches(pairs.ignore_a, pairs.ignore_b, a, b):
        return False
    return not pairs.has_only or _matches(pairs.only_a, pairs.only_b, a, b)


# --- building filters (Python) ------------------------------------------------------------------

def _split_outside_brackets(text):
    """Positions of ':' not inside an fnmatch [...] set."""
    colons = []
    depth = 0
    for i, ch in enumerate(text):
        if ch == "[":
            depth += 1
        elif ch == "]" and depth:
            depth -= 1
        elif ch == ":" and not depth:
            colons.append(i)
    return colons


def parse_pattern_pair(text, option):
    """'A:B' -> ('A', 'B'); a name containing ':' writes it as '[:]'. UsageError otherwise."""
    if isinstance(text, (tuple, list)) and len(text) == 2:
        return str(text[0]), str(text[1])
    colons = _split_outside_brackets(str(text))
    if len(colons) != 1 or colons[0] in (0, len(text) - 1):
        raise UsageError(f"{option} {text!r}: expected two name globs A:B (e.g. 'link_*:link_*' or "
                         "'floor:*'; write a ':' inside a name as [:])")
    i = colons[0]
    return text[:i], text[i + 1:]


def _pattern_bits(names, patterns, unmatched):
    """bool (N, K) per side: which names match glob A and glob B of each pattern pair;
    unmatched(pattern, glob) is called for a glob that matches no name."""
    side_a = np.zeros((len(names), len(patterns)), bool)
    side_b = np.zeros((len(names), len(patterns)), bool)
    for k, (glob_a, glob_b) in enumerate(patterns):
        for side, glob in ((side_a, glob_a), (side_b, glob_b)):
            regex = re.compile(fnmatch.translate(glob))
            side[:, k] = [regex.match(n) is not None for n in names]
            if not side[:, k].any():
                unmatched((glob_a, glob_b), glob)
    return side_a, side_b


def _pack(bits):
    """bool (N, K) -> uint64 (N, ceil(K / 64)), bit k % 64 of word k // 64: the bits packed
    into little-endian bytes, eight to a word (a scan's first use of numpy's shifts on
    uint64 costs 50 µs more than these calls)."""
    n, k = bits.shape
    n_words = (k + 63) // 64
    if k == 0:  # no patterns
        return np.zeros((n, 0), np.uint64)
    packed = np.zeros((n, 8 * n_words), np.uint8)
    packed[:, :(k + 7) // 8] = np.packbits(bits, axis=1, bitorder="little")
    return packed.view("<u8").astype(np.uint64)


class Filters(NamedTuple):
    """A scan's filter patterns (lists of (glob_a, glob_b)) and their bits per object."""
    ignore: list          #: pattern pairs never checked (trajectory's, then the command line's)
    only: list            #: pattern pairs alone checked (empty: all)
    ignore_bits: tuple    #: (bool (N, K), bool (N, K)): who matches each side
    only_bits: tuple      #: (bool (N, K'), bool (N, K'))

    def kernel_filter(self, extra_ignore=None, only_within=None):
        """The PairFilter of these patterns, optionally also ignoring pairs within the bool
        (N,) set extra_ignore, or restricted to pairs within the bool (N,) set only_within."""
        ignore_a, ignore_b = self.ignore_bits
        if extra_ignore is not None:
            ignore_a = np.concatenate([ignore_a, extra_ignore[:, None]], axis=1)
            ignore_b = np.concatenate([ignore_b, extra_ignore[:, None]], axis=1)
        only_a, only_b = self.only_bits
        has_only = bool(self.only)
        if only_within is not None:
            if has_only:
                only_a = only_a & only_within[:, None]
                only_b = only_b & only_within[:, None]
            else:
                only_a = only_b = only_within[:, None]
            has_only = True
        return PairFilter(_pack(ignore_a), _pack(ignore_b), _pack(only_a), _pack(only_b), has_only)

    def selected(self, a, b):
        """Python version of pair_selected for objects a, b (for reports and tests)."""
        (ia, ib), (oa, ob) = self.ignore_bits, self.only_bits
        if ((ia[a] & ib[b]) | (ia[b] & ib[a])).any():
            return False
        return not self.only or bool(((oa[a] & ob[b]) | (oa[b] & ob[a])).any())


def build_filters(names, ignore=(), only=(), trajectory_ignore=(), trajectory_path=None):
    """Filters for the objects ``names`` from command-line patterns (``ignore``, ``only``:
    'A:B' strings or (A, B) pairs) and the trajectory's filters/ignore pairs. A glob that
    matches no object is an error: UsageError for the command line, InputError naming
    the trajectory's dataset for its own list."""
    known = ", ".join(names[:8]) + (", ..." if len(names) > 8 else "")

    def from_trajectory(pattern, glob):
        raise InputError(trajectory_path, f"pattern {glob!r} (of {pattern[0]}:{pattern[1]}) matches no object",
                         f"globs matching object names ({known})", dataset="filters/ignore")

    def from_option(option):
        def fail(pattern, glob):
            raise UsageError(f"{option} {pattern[0]}:{pattern[1]}: {glob!r} matches no object; "
                             f"expected globs matching object names ({known})")
        return fail

    traj = [parse_pattern_pair(p, "filters/ignore") for p in trajectory_ignore]
    cli_ignore = [parse_pattern_pair(p, "--ignore") for p in ignore]
    cli_only = [parse_pattern_pair(p, "--only") for p in only]
    traj_bits = _pattern_bits(names, traj, from_trajectory)
    ignore_bits = _pattern_bits(names, cli_ignore, from_option("--ignore"))
    only_bits = _pattern_bits(names, cli_only, from_option("--only"))
    ignore_bits = (np.column_stack([traj_bits[0], ignore_bits[0]]).reshape(len(names), -1),
                   np.column_stack([traj_bits[1], ignore_bits[1]]).reshape(len(names), -1))
    return Filters(traj + cli_ignore, cli_only, ignore_bits, only_bits)


def describe(filters):
    """The filter patterns as a JSON-able dict (for provenance and diff)."""
    return {"ignore": sorted(sorted(p) for p in filters.ignore),
            "only": sorted(sorted(p) for p in filters.only)}
