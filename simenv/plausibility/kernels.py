"""Compiled (numba) kernels of the joint-level metrics.

:func:`score` is the one compiled entry: for each clip of a batch it gathers
the canonical keypoints once into float32 coordinate planes ``p`` (3, J, T)
(x, y, z; keypoints; frames; exact copies of the float32 clip, which every
metric converts to float64 as it reads them) that stay in cache, runs every
enabled metric on them (:func:`foot_skate`, :func:`ground_penetration`,
:func:`floating`, :func:`jitter`, :func:`velocity`: one function per metric
and clip, frame axis innermost and contiguous so LLVM vectorises the
elementwise loops; :func:`bone_length` reads the clip's source joints
instead, since its bones are the source skeleton's) and turns each
float64 timeline into the float32 result timeline and its violation runs,
all into the caller's arrays. :func:`simenv.plausibility.clips.score`
allocates them and turns them into results.

Numerics: every kernel does the same IEEE operations, in the same order, as
the numpy formulas in the metric docstrings of
:mod:`simenv.plausibility.metrics`
(numba adds no fast-math or FMA contraction unless asked, and none is
asked): norms are ``sqrt((x*x + y*y) + z*z)``; differences of differences
are taken as ``np.diff`` does; medians and percentiles interpolate exactly
as ``np.median`` / ``np.percentile`` (linear) on the selected order
statistics; means over frames use numpy's pairwise summation
(:func:`pairwise_sum`); the moving average is scipy's
``uniform_filter1d(mode="constant")`` running sum; ``np.interp`` is
reproduced branch for branch. Results are therefore bit-identical to the
numpy code, with one exception: the ballistic fit of :func:`floating` is the
closed-form least-squares line instead of LAPACK's SVD solver, which moves
the residual by at most a few 1e-13 relative (measured on the golden cases).

All compiled code of the joint-level metrics lives in this one file, a
metric's kernel included (its spec, in the metric's module of
:mod:`simenv.plausibility.metrics`, names its slot): numba's cache compares
only the source file of the function it caches, so a kernel edited in
another file would leave the cached :func:`score` running the old one. A
new kernel takes a slot number (and the count ``N_METRICS``), its
placeholder arguments in :data:`IDLE_ARGS` and one branch in :func:`score`.

Compilation: ``cache=True`` stores the machine code next to this module
(``__pycache__``), so only the first call on a machine compiles: about 50 s
of one core for each of the two forms of :func:`score`'s clips (one array,
a typed list), 0.4-0.6 s to load them from the cache (measured on the shared
2-core machine, see ``benchmarks/bench_score.py``).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _select(a: np.ndarray, n: int, k: int) -> float:
    """k-th smallest (0-based) of ``a[:n]`` by quickselect (median-of-three
    pivot, Hoare partition); reorders ``a[:n]`` so that ``a[:k]`` holds
    values <= the result."""
    lo, hi = 0, n - 1
    while lo < hi:
        mid = (lo + hi) >> 1
        if a[mid] < a[lo]:
            a[mid], a[lo] = a[lo], a[mid]
        if a[hi] < a[lo]:
            a[hi], a[lo] = a[lo], a[hi]
        if a[hi] < a[mid]:
            a[hi], a[mid] = a[mid], a[hi]
        pivot = a[mid]
        i, j = lo, hi
        while i <= j:
            while a[i] < pivot:
                i += 1
            while a[j] > pivot:
                j -= 1
            if i <= j:
                a[i], a[j] = a[j], a[i]
                i += 1
                j -= 1
        # Now a[lo:j+1] <= pivot <= a[i:hi+1] and a[j+1:i] == pivot.
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            return a[k]
    return a[k]


@njit(cache=True)
def _max_below(a: np.ndarray, k: int) -> float:
    """Largest of ``a[:k]`` (k >= 1): after :func:`_select` of ``k``, the
    (k-1)-th smallest."""
    m = a[0]
    for i in range(1, k):
        if a[i] > m:
            m = a[i]
    return m


#: Sample size of the bracketing step of :func:`_order_pair`.
_SAMPLE = 15
#: Below this many values :func:`_order_pair` finishes by ranking.
_SMALL = 32


@njit(cache=True)
def _rank_pair(a: np.ndarray, n: int, k: int) -> tuple[float, float]:
    """The (k-1)-th and k-th smallest (0-based, 1 <= k < n) of a short
    ``a[:n]`` (n <= ``_SMALL``), or two NaN when a value is NaN (the caller
    then uses quickselect, whose NaN behaviour the results keep).

    Ranks value i as ``#{j: a_j < a_i} + #{j < i: a_j == a_i}`` (ties in
    index order, so finite values get each rank once): n^2 branch-free
    comparisons that vectorise, against quickselect's ~n mispredicted
    branches, which cost more below a few dozen values. The values returned
    are the order statistics themselves, as quickselect's.
    """
    lower = np.nan
    upper = np.nan
    finite = True
    for i in range(n):
        v = a[i]
        finite &= v == v
        rank = 0
        for j in range(n):
            w = a[j]
            rank += (w < v) | ((w == v) & (j < i))
        if rank == k:
            upper = v
        elif rank == k - 1:
            lower = v
    if not finite:
        return np.nan, np.nan
    return lower, upper


@njit(cache=True)
def _order_pair(a: np.ndarray, n: int, k: int, tmp: np.ndarray) -> tuple[float, float]:
    """The (k-1)-th and k-th smallest (0-based, 1 <= k < n) of ``a[:n]``.

    Quickselect's data-dependent branches mispredict on about every other
    comparison (~15 ns per value here). Instead, as Floyd and Rivest, each
    step brackets the two order statistics between two values of a small
    sorted sample and compacts the values inside the bracket with a
    branch-free pass (~1 ns per value), which keeps about a third of them;
    when the bracket misses, a second pass keeps the side holding both.
    Ranges of at most ``_SMALL`` values are ranked (:func:`_rank_pair`);
    ranges that straddle a bracket edge or cannot shrink go to quickselect.
    ``a`` and ``tmp`` (at least n long) are overwritten.
    """
    src, dst = a, tmp
    m = n
    while m > _SMALL:
        # The sorted sample lives in dst until the pass below overwrites it
        # (no allocation: about 70 ns each, a tenth of a median of 240).
        sample = dst
        for i in range(_SAMPLE):
            v = src[((2 * i + 1) * m) // (2 * _SAMPLE)]
            j = i
            while j > 0 and sample[j - 1] > v:
                sample[j] = sample[j - 1]
                j -= 1
            sample[j] = v
        r = (k * _SAMPLE) // m
        lo = sample[max(r - 2, 0)]
        hi = sample[min(r + 2, _SAMPLE - 1)]
        below = 0
        inside = 0
        for i in range(m):
            v = src[i]
            dst[inside] = v
            below += v < lo
            inside += (v >= lo) & (v <= hi)
        if below < k < below + inside:
            if lo == hi:
                return lo, lo
            if inside == m:
                break
            k -= below
            m = inside
        elif k < below:
            # Missed low: both statistics are below the bracket.
            kept = 0
            for i in range(m):
                v = src[i]
                dst[kept] = v
                kept += v < lo
            m = kept
        elif k - 1 >= below + inside:
            # Missed high: both are above it.
            kept = 0
            for i in range(m):
                v = src[i]
                dst[kept] = v
                kept += v > hi
            k -= below + inside
            m = kept
        else:
            break
        src, dst = dst, src
    if m <= _SMALL:
        lower, upper = _rank_pair(src, m, k)
        if lower == lower and upper == upper:
            return lower, upper
    upper = _select(src, m, k)
    return _max_below(src, k), upper


@njit(cache=True)
def median(a: np.ndarray, n: int, tmp: np.ndarray) -> float:
    """``np.median(a[:n])``: the middle order statistic, or the mean of the
    two middle ones as ``(lo + hi) / 2``. ``a`` and ``tmp`` are scratch."""
    k = n // 2
    if n == 1:
        return a[0]
    lower, upper = _order_pair(a, n, k, tmp)
    if n % 2 == 1:
        return upper
    return (lower + upper) / 2.0


@njit(cache=True)
def percentile(a: np.ndarray, n: int, q: float, tmp: np.ndarray) -> float:
    """``np.percentile(a[:n], 100 * q)`` with numpy's default (linear)
    method and its exact interpolation formula. ``a`` and ``tmp`` are
    scratch."""
    virtual = (n - 1) * q
    if virtual >= n - 1:
        m = a[0]
        for i in range(1, n):
            if a[i] > m:
                m = a[i]
        return m
    prev = np.floor(virtual)
    gamma = virtual - prev
    lower, upper = _order_pair(a, n, int(prev) + 1, tmp)
    diff = upper - lower
    if gamma >= 0.5:
        return upper - diff * (1.0 - gamma)
    return lower + diff * gamma


@njit(cache=True)
def _block_sum(a: np.ndarray, lo: int, n: int) -> float:
    """numpy's pairwise-sum leaf (n <= 128): eight interleaved accumulators
    for n >= 8, then the remainder sequentially."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    while i < n - n % 8:
        r0 += a[lo + i]
        r1 += a[lo + i + 1]
        r2 += a[lo + i + 2]
        r3 += a[lo + i + 3]
        r4 += a[lo + i + 4]
        r5 += a[lo + i + 5]
        r6 += a[lo + i + 6]
        r7 += a[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@njit(cache=True)
def pairwise_sum(a: np.ndarray, lo: int, n: int) -> float:
    """Sum of the contiguous ``a[lo:lo + n]`` in numpy's pairwise order, so
    that a mean equals numpy's ``mean`` of the same C-ordered values bit for
    bit: ranges above 128 values are split at ``n // 2`` rounded down to a
    multiple of 8 and the halves' sums added; smaller ones are
    :func:`_block_sum` leaves.

    The recursion runs on an explicit stack: numba's cache does not reload
    self-recursive functions reliably (crashes on the cached code).
    """
    if n <= 128:
        return _block_sum(a, lo, n)
    # Node d of the current path: range start, length, 1 while its left
    # half is pending / 2 while its right half is, and its left half's sum.
    starts = np.empty(64, dtype=np.int64)
    sizes = np.empty(64, dtype=np.int64)
    phase = np.empty(64, dtype=np.int64)
    left = np.empty(64)
    depth = 0
    starts[0], sizes[0] = lo, n
    while True:
        m = sizes[depth]
        if m > 128:
            half = m // 2
            half -= half % 8
            phase[depth] = 1
            starts[depth + 1], sizes[depth + 1] = starts[depth], half
            depth += 1
            continue
        value = _block_sum(a, starts[depth], m)
        depth -= 1
        while depth >= 0:
            if phase[depth] == 1:
                left[depth] = value
                phase[depth] = 2
                half = sizes[depth] // 2
                half -= half % 8
                starts[depth + 1] = starts[depth] + half
                sizes[depth + 1] = sizes[depth] - half
                depth += 1
                break
            value = left[depth] + value
            depth -= 1
        if depth < 0:
            return value


@njit(cache=True)
def _keep_long_runs(mask: np.ndarray, min_len: int) -> None:
    """Clear, in place, the runs of True of the 1-D ``mask`` shorter than
    ``min_len``."""
    n = mask.shape[0]
    t = 0
    while t < n:
        if not mask[t]:
            t += 1
            continue
        start = t
        while t < n and mask[t]:
            t += 1
        if t - start < min_len:
            mask[start:t] = False


# -- the fused entry -----------------------------------------------------------

#: Metric slots of :func:`score`, in report order.
BONE, FOOT, GROUND, FLOAT, JITTER, VELOCITY = range(6)
#: Number of metric slots and of detail columns per metric.
N_METRICS, N_DETAILS = 6, 4


@njit(cache=True)
def _value_groups(values: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Group equal entries of ``values`` (N,): the (N,) group of each entry, the groups'
    values (first ``count`` entries, in order of first appearance) and ``count``. A
    linear scan: the per-bone tolerances and per-keypoint limits take a few values."""
    group = np.empty(values.shape[0], dtype=np.int64)
    group_values = np.empty(values.shape[0])
    count = 0
    for k in range(values.shape[0]):
        g = 0
        while g < count and group_values[g] != values[k]:
            g += 1
        if g == count:
            group_values[g] = values[k]
            count += 1
        group[k] = g
    return group, group_values, count


@njit(cache=True)
def _gather(clip: np.ndarray, idx: np.ndarray, p: np.ndarray, zmin: np.ndarray) -> float:
    """Canonical keypoints of one clip as float32 planes, in place.

    Float32 as the clip, so exact; half the bytes of float64 planes, which
    keeps a clip of about 1400 frames in a 512 KB L2 cache for the metrics
    that read the planes in turn (each converts to float64 to compute).

    Args:
        clip: (T, S, 3) float32 source-skeleton joints, metres.
        idx: (J,) source joint of each canonical keypoint.
        p: (3, J, T) float32 out: x, y, z planes. zmin: (T,) out: height of
            the lowest keypoint.

    Returns:
        The smallest height span (highest minus lowest keypoint) over
        frames, metres.
    """
    t_count = clip.shape[0]
    for j in range(idx.shape[0]):
        s = idx[j]
        # Frames innermost: strided loads but contiguous stores, ~3x faster
        # than the transposed order.
        for c in range(3):
            row = p[c, j]
            for t in range(t_count):
                row[t] = clip[t, s, c]
    zmax = p[2, 0].astype(np.float64)
    zmin[:] = zmax
    for j in range(1, idx.shape[0]):
        z = p[2, j]
        for t in range(t_count):
            zt = np.float64(z[t])
            zmin[t] = min(zmin[t], zt)
            zmax[t] = max(zmax[t], zt)
    return (zmax - zmin).min()


@njit(cache=True)
def _over(v: np.float32, thr32: np.float32, threshold: float, in_float32: bool) -> bool:
    """Whether the float32 timeline value ``v`` violates (see
    :func:`_violations`)."""
    return v > thr32 if in_float32 else np.float64(v) > threshold


@njit(cache=True)
def _violations(timeline: np.ndarray, threshold: float, in_float32: bool, out: np.ndarray,
                runs: np.ndarray, count: int) -> int:
    """Float32 timeline and its violation runs, in one pass.

    Args:
        timeline: (T,) float64 per-frame values.
        threshold: per-frame limit; a frame violates when its float32 value
            is above it (NaN never does), compared in float32 when
            ``in_float32`` (numpy's comparison of a float32 array with a
            Python float) and in float64 otherwise.
        out: (T,) float32 out: the timeline.
        runs: (R, 3) float64 rows (start frame, inclusive end frame, largest
            float32 value of the run), of which ``count`` are used; runs
            are appended in frame order while they fit.

    Returns:
        The new count, which goes on past R when the runs do not fit (the
        caller then scores again with room for them).
    """
    t_count = timeline.shape[0]
    thr32 = np.float32(threshold)
    hit = False
    for t in range(t_count):
        v = np.float32(timeline[t])
        out[t] = v
        hit |= v > thr32 if in_float32 else np.float64(v) > threshold
    if not hit:
        return count
    # Rare: the runs, comparing the float32 values again (no mask array).
    t = 0
    while t < t_count:
        if not _over(out[t], thr32, threshold, in_float32):
            t += 1
            continue
        start = t
        worst = out[t]
        while t < t_count and _over(out[t], thr32, threshold, in_float32):
            worst = max(worst, out[t])
            t += 1
        if count < runs.shape[0]:
            runs[count, 0] = start
            runs[count, 1] = t - 1
            runs[count, 2] = worst
        count += 1
    return count


@njit(cache=True)
def score(positions: np.ndarray, idx: np.ndarray, enabled: np.ndarray, args: tuple,
          frame_thresholds: np.ndarray, in_float32: np.ndarray, tl: np.ndarray,
          value: np.ndarray, details: np.ndarray, available: np.ndarray, span: np.ndarray,
          runs: np.ndarray, offsets: np.ndarray) -> int:
    """Every enabled joint-level metric of every clip, in one pass per clip.

    Each clip's canonical keypoints are gathered once into float32
    coordinate planes (exact: the clips are float32) that stay in cache
    while all metrics read them, each metric computing in float64, then each
    metric's float64 timeline is converted to the float32 result timeline
    together with its violation runs. The outputs are the caller's arrays:
    arrays made here would cost about 2.5 us each to hand back to Python,
    more than the kernels spend on a short clip.

    Args:
        positions: B clips of (T, S, 3) float32 source-skeleton joints,
            metres: a (B, T, S, 3) array or a typed list of (T, S, 3) arrays.
        idx: (J,) int64 source joint of each canonical keypoint.
        enabled: (6,) bool per metric slot (:data:`BONE` ... :data:`VELOCITY`).
        args: per slot, the arguments of its kernel after its inputs
            (:func:`bone_length` after its clip, the others after their planes
            or heights; ``()`` for :func:`ground_penetration`); unused when
            disabled, but always of the types of :data:`IDLE_ARGS`.
        frame_thresholds: (6,) per-frame limit of each metric's timeline;
            in_float32: (6,) bool, compare in float32 (see
            :func:`_violations`).
        tl: (6, B, T) float32 out: timelines (rows of disabled metrics are
            left unset). value: (6, B) out, zeros in. details: (6, B, 4) out,
            zeros in. available: (B,) bool out: clips with a bone checked.
            span: (B,) out: smallest height span over frames, metres.
            runs: (R, 3) out: violation runs (see :func:`_violations`), the
            first R. offsets: (B * 6 + 1,) int64 out: runs of clip b and
            metric m are ``runs[offsets[6 b + m]:offsets[6 b + m + 1]]``.

    Returns:
        The number of runs; above R, only the first R were written.
    """
    b_count, t_count = len(positions), positions[0].shape[0]
    j_count = idx.shape[0]
    count = 0
    offsets[0] = 0
    p = np.empty((3, j_count, t_count), dtype=np.float32)
    zmin = np.empty(t_count)
    line = np.empty(t_count)
    for b in range(b_count):
        span[b] = _gather(positions[b], idx, p, zmin)
        for m in range(N_METRICS):
            if enabled[m]:
                det = details[m, b]
                if m == BONE:
                    value[m, b], available[b] = bone_length(positions[b], *args[BONE], line,
                                                            det)
                elif m == FOOT:
                    value[m, b] = foot_skate(p, zmin, *args[FOOT], line, det)
                elif m == GROUND:
                    value[m, b] = ground_penetration(zmin, line, det)
                elif m == FLOAT:
                    value[m, b] = floating(p, zmin, *args[FLOAT], line, det)
                elif m == JITTER:
                    value[m, b] = jitter(p, *args[JITTER], line, det)
                else:
                    value[m, b] = velocity(p, *args[VELOCITY], line, det)
                count = _violations(line, frame_thresholds[m], in_float32[m], tl[m, b], runs,
                                    count)
            offsets[b * N_METRICS + m + 1] = count
    return count


# -- bone length ---------------------------------------------------------------


@njit(cache=True)
def bone_length(clip: np.ndarray, parent: np.ndarray, child: np.ndarray, tol: np.ndarray,
                min_length: float, q: float, tl: np.ndarray, details: np.ndarray
                ) -> tuple[float, bool]:
    """Bone-length consistency of one clip on its source skeleton's bones (see
    :func:`simenv.plausibility.metrics.bone_length.bone_length`).

    Reads the clip's own joints, not the canonical planes: a source bone may
    join joints that are no canonical keypoint (SMPL's collars, CMU's
    ``LHipJoint``).

    Args:
        clip: (T, S, 3) float32 source-skeleton joints, metres. parent,
            child: (K,) source joints of each bone.
        tol: (K,) relative tolerance per bone. min_length: metres, bones
            with a shorter median are skipped. q: percentile of the value
            as a fraction (0.95).
        tl: (T,) out: timeline. details: out: (max of the timeline, max
            relative deviation, bones checked).

    Returns:
        The value, and whether a bone was checked.
    """
    t_count = clip.shape[0]
    length = np.empty(t_count)
    buf = np.empty(t_count)
    tmp = np.empty(t_count)
    # Division by a positive tolerance is monotone (correct rounding keeps
    # order): the largest dev / tol among bones of one tolerance is their
    # largest dev over tol, one division per frame and tolerance instead of
    # one per bone, same values.
    group, group_tol, g_count = _value_groups(tol)
    # Skipped bones count deviation 0, which leaves every maximum (of
    # values >= 0) unchanged: start the maxima at 0.
    dev_group = np.zeros((g_count, t_count))
    checked = 0
    for k in range(parent.shape[0]):
        a, c = parent[k], child[k]
        longest = 0.0
        for t in range(t_count):
            dx = np.float64(clip[t, c, 0]) - np.float64(clip[t, a, 0])
            dy = np.float64(clip[t, c, 1]) - np.float64(clip[t, a, 1])
            dz = np.float64(clip[t, c, 2]) - np.float64(clip[t, a, 2])
            length[t] = np.sqrt((dx * dx + dy * dy) + dz * dz)
            longest = max(longest, length[t])
        # A collapsed bone (never min_length long) is skipped without its
        # median, which is at most its longest frame: same result.
        if not longest >= min_length:
            continue
        buf[:] = length
        m = median(buf, t_count, tmp)
        if not m >= min_length:
            continue
        checked += 1
        dev = dev_group[group[k]]
        for t in range(t_count):
            dev[t] = max(dev[t], abs(length[t] / m - 1.0))
    dev_max = np.zeros(t_count)
    tl[:] = 0.0
    for g in range(g_count):
        dev = dev_group[g]
        tk = group_tol[g]
        for t in range(t_count):
            dev_max[t] = max(dev_max[t], dev[t])
            tl[t] = max(tl[t], dev[t] / tk)
    buf[:] = tl
    details[0] = tl.max()
    details[1] = dev_max.max()
    details[2] = checked
    return percentile(buf, t_count, q, tmp), checked > 0


# -- jitter --------------------------------------------------------------------


@njit(cache=True)
def _interp(x_count: int, x_step: float, xp: np.ndarray, fp: np.ndarray, out: np.ndarray
            ) -> None:
    """``out[:] = np.interp(np.arange(x_count) / x_step, xp, fp, left=nan,
    right=nan)`` for increasing ``xp``, with numpy's branches (exact hits and
    the last sample return ``fp`` itself; otherwise ``slope * (x - xp[j]) +
    fp[j]`` with the slope from the bracketing samples)."""
    n = xp.shape[0]
    j = 0
    for i in range(x_count):
        x = i / x_step
        if x < xp[0] or x > xp[n - 1]:
            out[i] = np.nan
            continue
        while j < n - 1 and xp[j + 1] <= x:
            j += 1
        if j == n - 1 or xp[j] == x:
            out[i] = fp[j]
        else:
            slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
            out[i] = slope * (x - xp[j]) + fp[j]




@njit(cache=True)
def median_network(n: int) -> np.ndarray:
    """Compare-exchange pairs that bring the median of n values into place.

    Batcher's odd-even merge sort of the next power of two (m) sorts any
    input, so its comparators (i, j), i < j, each replacing
    ``(a_i, a_j)`` by ``(min, max)``, put the k-th smallest value at
    position k for every k. Treat positions >= n as +inf padding: a
    comparator touching one never exchanges, so it is dropped. Going back
    from the end, only comparators that touch a position the middle order
    statistics (n // 2, and n // 2 - 1 for even n) depend on are kept.

    Returns:
        (C, 2) int64 pairs in order (C = 91 for n = 21, against 420
        comparisons of ranking).
    """
    m = 1
    while m < n:
        m *= 2
    pairs = np.empty((max(m * m, 1), 2), dtype=np.int64)
    count = 0
    p = 1
    while p < m:
        k = p
        while k >= 1:
            for j in range(k % p, m - k, 2 * k):
                for i in range(k):
                    a, b = i + j, i + j + k
                    if a // (2 * p) == b // (2 * p) and b < n:
                        pairs[count, 0] = a
                        pairs[count, 1] = b
                        count += 1
            k //= 2
        p *= 2
    needed = np.zeros(max(n, 1), dtype=np.bool_)
    needed[n // 2] = True
    if n % 2 == 0 and n > 0:
        needed[n // 2 - 1] = True
    keep = np.zeros(count, dtype=np.bool_)
    for c in range(count - 1, -1, -1):
        a, b = pairs[c, 0], pairs[c, 1]
        if needed[a] or needed[b]:
            keep[c] = True
            needed[a] = True
            needed[b] = True
    return pairs[:count][keep]


@njit(cache=True)
def _column_medians(a: np.ndarray, network: np.ndarray, med: np.ndarray, top: np.ndarray
                    ) -> None:
    """Per column of ``a`` (n, W), the value of :func:`median` (out ``med``
    (W,)) and of ``.max()`` (out ``top`` (W,)); ``a`` is overwritten.

    The median comes from the pairs of :func:`median_network` (n), run on
    all columns at once so that every compare-exchange is a vector lane;
    each exchanges two values or leaves them, so it returns the order
    statistics themselves, as :func:`median`. A column holding a NaN goes
    through :func:`median` itself, before the network reorders it.
    """
    n, w_count = a.shape
    k = n // 2
    bad = np.zeros(w_count, dtype=np.bool_)
    top[:] = a[0]
    for i in range(n):
        ai = a[i]
        for w in range(w_count):
            bad[w] |= ai[w] != ai[w]
            top[w] = ai[w] if ai[w] > top[w] else top[w]
    if bad.any():
        buf = np.empty(n)
        tmp = np.empty(n)
        for w in np.flatnonzero(bad):
            buf[:] = a[:, w]
            top[w] = buf.max()
            med[w] = median(buf, n, tmp)
    for c in range(network.shape[0]):
        lo = a[network[c, 0]]
        hi = a[network[c, 1]]
        for w in range(w_count):
            u, v = lo[w], hi[w]
            swap = v < u
            lo[w] = v if swap else u
            hi[w] = u if swap else v
    for w in range(w_count):
        if bad[w]:
            continue
        if n == 1:
            med[w] = a[0, w]
        elif n % 2 == 1:
            med[w] = a[k, w]
        else:
            med[w] = (a[k - 1, w] + a[k, w]) / 2.0


@njit(cache=True)
def _keypoint_series(p: np.ndarray, j: int, resample: bool, src: np.ndarray,
                     weight: np.ndarray, series: np.ndarray) -> None:
    """series (3, N) <- keypoint ``j`` of the (3, J, T) planes ``p``, resampled
    as in :func:`jitter` when ``resample`` (else N = T and a plain copy)."""
    one = np.float32(1.0)
    for c in range(3):
        row = p[c, j]
        if resample:
            for k in range(series.shape[1]):
                wk = weight[k]
                series[c, k] = ((one - wk) * np.float32(row[src[k]])
                                + wk * np.float32(row[src[k] + 1]))
        else:
            series[c, :] = row


@njit(cache=True)
def _window_jerk(series: np.ndarray, w: int, dt: float, dt3: float, fa3: float, eps: float,
                 duration5: float, step: np.ndarray, jerk_sq: np.ndarray, cs_step: np.ndarray,
                 cs_jerk: np.ndarray, nj_row: np.ndarray, jerk_row: np.ndarray) -> None:
    """Normalized jerk of one keypoint's (3, N) ``series`` per window of ``w``
    frames into nj_row (N - w + 1,), and its |jerk| (m/s^3) per frame into
    jerk_row (N - 3,); step, jerk_sq, cs_step, cs_jerk are scratch (see
    :func:`jitter` for the other arguments)."""
    n = series.shape[1]
    x, y, z = series[0], series[1], series[2]
    # |v| dt and squared jerk dt per frame, with np.diff's differences
    # and the same divisions by dt, in loops free of loop-carried
    # dependencies (so the divisions and roots vectorise) ...
    for k in range(n - 1):
        vx, vy, vz = (x[k + 1] - x[k]) / dt, (y[k + 1] - y[k]) / dt, (z[k + 1] - z[k]) / dt
        step[k] = np.sqrt((vx * vx + vy * vy) + vz * vz) * dt
    for k in range(n - 3):
        d3x = (((x[k + 3] - x[k + 2]) - (x[k + 2] - x[k + 1]))
               - ((x[k + 2] - x[k + 1]) - (x[k + 1] - x[k])))
        d3y = (((y[k + 3] - y[k + 2]) - (y[k + 2] - y[k + 1]))
               - ((y[k + 2] - y[k + 1]) - (y[k + 1] - y[k])))
        d3z = (((z[k + 3] - z[k + 2]) - (z[k + 2] - z[k + 1]))
               - ((z[k + 2] - z[k + 1]) - (z[k + 1] - z[k])))
        jx, jy, jz = d3x / dt3, d3y / dt3, d3z / dt3
        jerk_sq[k] = ((jx * jx + jy * jy) + jz * jz) * dt
        jerk_row[k] = np.sqrt((d3x * d3x + d3y * d3y) + d3z * d3z) * fa3
    # ... then the running sums (sequential, as np.cumsum) ...
    cs_step[0] = 0.0
    for k in range(n - 1):
        cs_step[k + 1] = cs_step[k] + step[k]
    cs_jerk[0] = 0.0
    for k in range(n - 3):
        cs_jerk[k + 1] = cs_jerk[k] + jerk_sq[k]
    # ... and the window sums from them.
    for i in range(nj_row.shape[0]):
        path = max(cs_step[w - 1 + i] - cs_step[i], eps)
        nj_row[i] = duration5 * (cs_jerk[w - 3 + i] - cs_jerk[i]) / (path * path + eps)


@njit(cache=True)
def jitter(p: np.ndarray, resample: bool, src: np.ndarray, weight: np.ndarray, fps: float,
           fa: float, w: int, eps: float, limit: float, dt3: float, duration5: float,
           fa3: float, network: np.ndarray, timeline: np.ndarray, details: np.ndarray
           ) -> float:
    """Windowed normalized jerk of one clip (see
    :func:`simenv.plausibility.metrics.jitter.jitter` and
    :func:`~simenv.plausibility.metrics.jitter.windowed_normalized_jerk`).

    Args:
        p: (3, J, T) planes at ``fps``.
        resample: bring the clip to ``fa`` first: analysis frame k is
            ``(1 - weight[k]) * p[src[k]] + weight[k] * p[src[k] + 1]`` in
            float32, as :meth:`Motion.resample`. src: (N,) int64, weight:
            (N,) float32 (:func:`simenv.core.motion.resample_weights`); without
            resampling N = T and they are unused.
        fa: analysis frame rate. w: window, frames at ``fa`` (>= 4, <= N).
        eps: path-length floor. limit: normalized-jerk limit.
        dt3, duration5, fa3: ``(1 / fa) ** 3``, ``((w - 1) / fa) ** 5`` and
            ``fa ** 3`` as Python computes them (``pow``; numba would
            multiply, which rounds differently).
        network: :func:`median_network` of J, for the medians over
            keypoints.
        timeline: (T,) out: the median keypoint's NJ at each frame's window
            centre, NaN where none. details: out: (ProtoMotions' percent,
            mean |jerk| m/s^3, mean NJ).

    Returns:
        The value: percent of windows over the limit.
    """
    j_count, t_count = p.shape[1], p.shape[2]
    n = src.shape[0] if resample else t_count
    windows = n - w + 1
    dt = 1.0 / fa
    series = np.empty((3, n))
    step = np.empty(n - 1)
    jerk_sq = np.empty(n - 3)
    jerk_row = np.empty(n - 3)
    # Keypoint-major copy of nj for the medians over keypoints.
    njt = np.empty((j_count, windows))
    cs_step = np.empty(n)
    cs_jerk = np.empty(n - 2)
    nj = np.empty((windows, j_count))
    jerk_norm = np.empty((n - 3, j_count))
    typical = np.empty(windows)
    centres = np.empty(windows)
    for i in range(windows):
        centres[i] = (i + (w - 1) / 2.0) / fa
    for j in range(j_count):
        nj_row = njt[j]
        _keypoint_series(p, j, resample, src, weight, series)
        _window_jerk(series, w, dt, dt3, fa3, eps, duration5, step, jerk_sq, cs_step, cs_jerk,
                     nj_row, jerk_row)
        nj[:, j] = nj_row
        jerk_norm[:, j] = jerk_row
    top = np.empty(windows)
    _column_medians(njt, network, typical, top)
    high = 0
    high_any = 0
    for i in range(windows):
        high += typical[i] > limit
        high_any += top[i] > limit
    _interp(t_count, fps, centres, typical, timeline)
    details[0] = 100.0 * (high_any / windows)
    details[1] = pairwise_sum(jerk_norm.ravel(), 0, jerk_norm.size) / jerk_norm.size
    details[2] = pairwise_sum(nj.ravel(), 0, nj.size) / nj.size
    return 100.0 * (high / windows)


# -- velocity ------------------------------------------------------------------


@njit(cache=True)
def velocity(p: np.ndarray, limits: np.ndarray, fps: float, jump_limit: float,
             tl: np.ndarray, details: np.ndarray) -> float:
    """Speeds against their limits and teleports of one clip (see
    :func:`simenv.plausibility.metrics.velocity.velocity`); T >= 2.

    Args:
        p: (3, J, T) planes. limits: (J,) m/s. jump_limit: metres.
        tl: (T,) out: timeline (NaN on frame 0). details: out: (max speed
            m/s, max speed ratio, max jump m, teleport frames).

    Returns:
        The value: the timeline's maximum.
    """
    j_count, t_count = p.shape[1], p.shape[2]
    pairs = t_count - 1
    # Square roots, and products or quotients with a positive constant, are
    # monotone (correct rounding keeps order), so the largest speed among
    # keypoints of one limit is the root of their largest squared step and
    # the largest jump the root of the largest squared second difference:
    # one root per frame and limit instead of one per keypoint, same values.
    group, group_limit, g_count = _value_groups(limits)
    # Squares, speeds, ratios and jumps are >= 0: maxima start at 0.
    step_sq = np.zeros((g_count, pairs))
    jump_sq = np.zeros(max(t_count - 2, 0))
    for j in range(j_count):
        x, y, z = p[0, j], p[1, j], p[2, j]
        q = step_sq[group[j]]
        # One pass for steps (frame pairs t, t+1) and jumps (second
        # differences at t+1, np.diff of the steps), the last step apart.
        for t in range(pairs - 1):
            x0, y0, z0 = np.float64(x[t]), np.float64(y[t]), np.float64(z[t])
            x1, y1, z1 = np.float64(x[t + 1]), np.float64(y[t + 1]), np.float64(z[t + 1])
            dx, dy, dz = x1 - x0, y1 - y0, z1 - z0
            q[t] = max(q[t], (dx * dx + dy * dy) + dz * dz)
            ddx = (np.float64(x[t + 2]) - x1) - dx
            ddy = (np.float64(y[t + 2]) - y1) - dy
            ddz = (np.float64(z[t + 2]) - z1) - dz
            jump_sq[t] = max(jump_sq[t], (ddx * ddx + ddy * ddy) + ddz * ddz)
        t = pairs - 1
        dx = np.float64(x[t + 1]) - np.float64(x[t])
        dy = np.float64(y[t + 1]) - np.float64(y[t])
        dz = np.float64(z[t + 1]) - np.float64(z[t])
        q[t] = max(q[t], (dx * dx + dy * dy) + dz * dz)
    ratio = np.zeros(pairs)
    speed_max = np.zeros(pairs)
    for g in range(g_count):
        q = step_sq[g]
        lim = group_limit[g]
        for t in range(pairs):
            s = np.sqrt(q[t]) * fps
            speed_max[t] = max(speed_max[t], s)
            ratio[t] = max(ratio[t], s / lim)
    jump = np.sqrt(jump_sq)
    tl[0] = np.nan
    tl[1:] = ratio
    teleports = 0
    for t in range(t_count - 2):
        r = jump[t] / jump_limit
        teleports += r > 1
        tl[t + 1] = max(tl[t + 1], r)
    details[0] = speed_max.max()
    details[1] = ratio.max()
    details[2] = jump.max() if t_count >= 3 else 0.0
    details[3] = teleports
    return tl[1:].max()


# -- ground --------------------------------------------------------------------


@njit(cache=True)
def ground_penetration(zmin: np.ndarray, depth: np.ndarray, details: np.ndarray) -> float:
    """Depth below the floor of one clip (see
    :func:`simenv.plausibility.metrics.ground_penetration.ground_penetration`).

    Args:
        zmin: (T,) height of the lowest keypoint, metres.
        depth: (T,) out: timeline, mm. details: out: (mean mm, fraction of
            frames below the floor).

    Returns:
        The value: the deepest frame, mm.
    """
    t_count = zmin.shape[0]
    below = 0
    for t in range(t_count):
        d = max(-zmin[t], 0.0) * 1000.0
        depth[t] = d
        below += d > 0
    details[0] = pairwise_sum(depth, 0, t_count) / t_count
    details[1] = below / t_count
    return depth.max()


@njit(cache=True)
def _foot_floors(p: np.ndarray, zmin: np.ndarray, feet: np.ndarray, ankle: np.ndarray,
                 buf: np.ndarray, tmp: np.ndarray) -> tuple[float, float]:
    """Floors of the foot contact test, metres: toes from the 1st percentile
    of the lowest keypoint ``zmin`` (T,), ankles (``ankle`` True) from that
    of the lowest ankle (the toe floor when there is none). ``buf`` and
    ``tmp`` (T,) are scratch."""
    t_count = zmin.shape[0]
    buf[:] = zmin
    floor = percentile(buf, t_count, 0.01, tmp)
    ankle_floor = floor
    if ankle.any():
        for t in range(t_count):
            m = np.inf
            for f in range(feet.shape[0]):
                if ankle[f]:
                    m = min(m, np.float64(p[2, feet[f], t]))
            buf[t] = m
        ankle_floor = percentile(buf, t_count, 0.01, tmp)
    return floor, ankle_floor


@njit(cache=True)
def _running_mean(v: np.ndarray, window: int, padded: np.ndarray, out: np.ndarray) -> None:
    """out (N,) <- the ``window``-frame running mean of ``v`` (N,), as scipy's
    ``uniform_filter1d(mode="constant")``; ``padded`` (N + window - 1,) is
    scratch whose ends are zero."""
    pairs = v.shape[0]
    half = window // 2
    padded[half:half + pairs] = v
    acc = 0.0
    for k in range(window):
        acc += padded[k]
    out[0] = acc / window
    for k in range(1, pairs):
        acc += padded[k + window - 1] - padded[k - 1]
        out[k] = acc / window


@njit(cache=True)
def _foot_track(p: np.ndarray, foot: int, floor: float, height: float, fps: float,
                skate_speed: float, contact_speed: float, rel: np.ndarray, low: np.ndarray,
                v_h: np.ndarray, planted: np.ndarray, raw_sliding: np.ndarray) -> None:
    """One foot keypoint's states over a clip of T frames, into: rel (T,)
    height above ``floor``, low (T,) below ``height``, v_h (T - 1,)
    horizontal speed per frame pair (m/s), planted (T,) low and slow
    (3-D speed below ``contact_speed``, as
    :func:`simenv.body.foot_contact.foot_contacts`; the last frame reuses the
    last speed), raw_sliding (T - 1,) low at both frames and faster than
    ``skate_speed``."""
    x, y, z = p[0, foot], p[1, foot], p[2, foot]
    t_count = rel.shape[0]
    pairs = t_count - 1
    for t in range(t_count):
        rel[t] = np.float64(z[t]) - floor
        low[t] = rel[t] < height
    for t in range(pairs):
        dx = np.float64(x[t + 1]) - np.float64(x[t])
        dy = np.float64(y[t + 1]) - np.float64(y[t])
        dz = np.float64(z[t + 1]) - np.float64(z[t])
        v_h[t] = np.sqrt(dx * dx + dy * dy) * fps
        slow = np.sqrt((dx * dx + dy * dy) + dz * dz) * fps < contact_speed
        planted[t] = low[t] and slow
        if t == pairs - 1:
            planted[t + 1] = low[t + 1] and slow
        raw_sliding[t] = low[t + 1] and low[t] and v_h[t] > skate_speed


@njit(cache=True)
def _apart_speed(p: np.ndarray, a: int, b: int, fps: float, out: np.ndarray) -> None:
    """out (T - 1,) <- horizontal speed (m/s) of keypoint ``a`` relative to
    ``b`` over each frame pair of the (3, J, T) planes ``p``."""
    for t in range(out.shape[0]):
        dx = ((np.float64(p[0, a, t + 1]) - np.float64(p[0, a, t]))
              - (np.float64(p[0, b, t + 1]) - np.float64(p[0, b, t])))
        dy = ((np.float64(p[1, a, t + 1]) - np.float64(p[1, a, t]))
              - (np.float64(p[1, b, t + 1]) - np.float64(p[1, b, t])))
        out[t] = np.sqrt(dx * dx + dy * dy) * fps


#: Frame pairs a sliding run needs before its speeds can show a fall throughout
#: (:func:`_drop_approaches`): speeds in random order put every pair of the second
#: half below every pair of the first with probability 1 / C(n, n // 2), at most
#: 1 in 20 from 6 pairs on (1 in 2 for 2 pairs, the Kinect rates' shortest slides).
APPROACH_MIN_PAIRS = 6


@njit(cache=True)
def _drop_approaches(sliding: np.ndarray, low: np.ndarray, v_h: np.ndarray,
                     skate_speed: float) -> None:
    """Clear, in place, the runs of ``sliding`` (T - 1,) of one foot that are
    a swing's approach to its touchdown: the run lasts at least
    :data:`APPROACH_MIN_PAIRS` frame pairs, ends at a touchdown (the next
    frame pair the foot is low, ``low`` (T,), and no faster than
    ``skate_speed`` m/s) and every frame pair of its second half is slower
    than every pair of its first half (``v_h`` (T - 1,), m/s; a run of n
    pairs splits at n // 2). A loaded foot sliding holds its speed, so its
    halves overlap, and it ends where it lifts or its slide goes on."""
    pairs = sliding.shape[0]
    t = 0
    while t < pairs:
        if not sliding[t]:
            t += 1
            continue
        start = t
        while t < pairs and sliding[t]:
            t += 1
        half = (t - start) // 2
        if (t - start < APPROACH_MIN_PAIRS or t == pairs or not low[t + 1]
                or v_h[t] > skate_speed):
            continue
        slowest_first = v_h[start]
        for k in range(start + 1, start + half):
            slowest_first = min(slowest_first, v_h[k])
        fastest_second = v_h[start + half]
        for k in range(start + half + 1, t):
            fastest_second = max(fastest_second, v_h[k])
        if fastest_second < slowest_first:
            sliding[start:t] = False


@njit(cache=True)
def _unsupported_slides(rel: np.ndarray, low: np.ndarray, v_h: np.ndarray,
                        v_apart: np.ndarray, raw_sliding: np.ndarray, skate_speed: float,
                        margin: float, stance_speed: float, min_run: int,
                        sliding: np.ndarray) -> None:
    """sliding (F, T - 1) <- the slides of ``raw_sliding`` whose foot carries
    weight (not while the other foot, slower than ``skate_speed``, stands
    more than ``margin`` lower at both frames, nor while both feet slide and
    move apart faster than ``skate_speed`` unless this foot is the one more
    than ``margin`` lower at both frames, nor in a run that is a swing's
    approach to its touchdown, :func:`_drop_approaches`), kept where they
    last ``min_run`` frame pairs. rel, v_h: as :func:`_foot_track`, per
    foot; v_apart (T - 1,): horizontal speed of one foot relative to the
    other, m/s."""
    f_count, pairs = v_h.shape[0], v_h.shape[1]
    for f in range(f_count):
        o = f_count - 1 - f
        for t in range(pairs):
            # The other foot, planted and lower, carries the weight.
            supported = (f_count == 2 and v_h[o, t] <= skate_speed
                         and rel[o, t + 1] + margin < rel[f, t + 1]
                         and rel[o, t] + margin < rel[f, t])
            # Or stands still on the floor: a foot sliding beside it is dragged, unloaded.
            supported = supported or (f_count == 2 and v_h[o, t] < stance_speed
                                      and low[o, t] and low[o, t + 1])
            # Both feet low and fast, moving apart as fast as a slide, neither clearly
            # the lower (the stance foot a low swing passes): the feet move on their
            # own (a hop or a shuffle step), not a body sliding on its stance.
            airborne = (f_count == 2 and raw_sliding[o, t] and v_apart[t] > skate_speed
                        and not (rel[f, t] + margin < rel[o, t]
                                 and rel[f, t + 1] + margin < rel[o, t + 1]))
            sliding[f, t] = raw_sliding[f, t] and not (supported or airborne)
        _drop_approaches(sliding[f], low[f], v_h[f], skate_speed)
        if min_run > 1:
            _keep_long_runs(sliding[f], min_run)


@njit(cache=True)
def foot_skate(p: np.ndarray, zmin: np.ndarray, feet: np.ndarray, heights: np.ndarray,
               ankle: np.ndarray, fps: float, skate_speed: float, margin: float,
               stance_speed: float, min_run: int, window: int, contact_speed: float,
               to_mm: float,
               tl: np.ndarray, details: np.ndarray) -> float:
    """Foot skating of one clip (see
    :func:`simenv.plausibility.metrics.foot_skate.foot_skate`); T >= 2.

    Args:
        p: (3, J, T) planes. zmin: (T,) lowest keypoint height.
        feet: (F,) foot keypoints (F = 1 or 2). heights: (F,) contact
            heights, metres. ankle: (F,) True for an ankle fallback.
        skate_speed, contact_speed: m/s. margin: support margin, metres.
        min_run: frames a slide must last. window: moving-average frames.
        to_mm: m/s to the timeline's mm per reference frame.
        tl: (T,) out: timeline (NaN on frame 0). details: out: (GMD ratio,
            PhysDiff skate mm, max slide mm, contact fraction).

    Returns:
        The value: the skating ratio.
    """
    t_count = zmin.shape[0]
    f_count = feet.shape[0]
    pairs = t_count - 1
    rel = np.empty((f_count, t_count))
    low = np.empty((f_count, t_count), dtype=np.bool_)
    v_h = np.empty((f_count, pairs))
    planted = np.empty((f_count, t_count), dtype=np.bool_)
    raw_sliding = np.empty((f_count, pairs), dtype=np.bool_)
    sliding = np.empty((f_count, pairs), dtype=np.bool_)
    buf = np.empty(t_count)
    tmp = np.empty(t_count)
    padded = np.zeros(pairs + window - 1)
    v_avg = np.empty(pairs)
    slide = np.zeros(pairs)
    disp = np.empty(pairs)
    v_apart = np.zeros(pairs)
    floor, ankle_floor = _foot_floors(p, zmin, feet, ankle, buf, tmp)
    for f in range(f_count):
        _foot_track(p, feet[f], ankle_floor if ankle[f] else floor, heights[f], fps,
                    skate_speed, contact_speed, rel[f], low[f], v_h[f], planted[f],
                    raw_sliding[f])
    if f_count == 2:
        _apart_speed(p, feet[0], feet[1], fps, v_apart)
    _unsupported_slides(rel, low, v_h, v_apart, raw_sliding, skate_speed, margin,
                        stance_speed, min_run, sliding)
    skating_pairs = 0
    gmd_pairs = 0
    for t in range(pairs):
        skating = False
        for f in range(f_count):
            if sliding[f, t]:
                skating = True
                slide[t] = max(slide[t], v_h[f, t])
        skating_pairs += skating
    for f in range(f_count):
        _running_mean(v_h[f], window, padded, v_avg)
        for t in range(pairs):
            # Reused below as "a GMD-skating foot at this pair".
            raw_sliding[f, t] = raw_sliding[f, t] and v_avg[t] > skate_speed
    contact_frames = 0
    for t in range(t_count):
        contact_frames += planted[:, t].any()
    for t in range(pairs):
        gmd = False
        total = 0.0
        count = 0
        for f in range(f_count):
            gmd = gmd or raw_sliding[f, t]
            if planted[f, t + 1] and planted[f, t]:
                total += v_h[f, t]
                count += 1
        gmd_pairs += gmd
        disp[t] = total / max(count, 1)
    tl[0] = np.nan
    for t in range(pairs):
        tl[t + 1] = slide[t] * to_mm
    details[0] = gmd_pairs / pairs
    details[1] = pairwise_sum(disp, 0, pairs) / pairs * to_mm
    details[2] = slide.max() * to_mm
    details[3] = contact_frames / t_count
    return skating_pairs / pairs


@njit(cache=True)
def _mean_height(p: np.ndarray, keypoints: np.ndarray) -> np.ndarray:
    """(T,) mean height of ``keypoints`` (K >= 1) of the (3, J, T) planes
    ``p``, as np.mean over keypoints: a sequential sum, then one division."""
    com_z = p[2, keypoints[0]].astype(np.float64)
    for k in keypoints[1:]:
        zk = p[2, k]
        for t in range(com_z.shape[0]):
            com_z[t] += np.float64(zk[t])
    com_z /= keypoints.shape[0]
    return com_z


@njit(cache=True)
def _ballistic_rms(z: np.ndarray, start: int, n: int, fps: float, half_g: float) -> float:
    """RMS residual (metres) of the best free fall ``z0 + v0 s - g s^2 / 2``
    through ``z[start:start + n]`` (n >= 3): the least-squares line through
    the height plus ``g s^2 / 2``, solved in closed form about the mean time
    (well conditioned)."""
    s_mean = 0.0
    y_mean = 0.0
    for k in range(n):
        s = k / fps
        s_mean += s
        y_mean += z[start + k] + half_g * (s * s)
    s_mean /= n
    y_mean /= n
    sxy = 0.0
    sxx = 0.0
    for k in range(n):
        s = k / fps
        ds = s - s_mean
        sxy += ds * (z[start + k] + half_g * (s * s) - y_mean)
        sxx += ds * ds
    slope = sxy / sxx
    sq = 0.0
    for k in range(n):
        s = k / fps
        r = (z[start + k] + half_g * (s * s) - y_mean) - slope * (s - s_mean)
        sq += r * r
    return np.sqrt(sq / n)


@njit(cache=True)
def floating(p: np.ndarray, zmin: np.ndarray, com: np.ndarray, hands: np.ndarray,
             hand_reach: float, ankles: np.ndarray, ankle_sole: float, float_height: float,
             fps: float, gravity: float, tolerance: float, tl: np.ndarray,
             details: np.ndarray) -> float:
    """Floating (airborne, not ballistic) of one clip (see
    :func:`simenv.plausibility.metrics.floating.floating`); T >= 3.

    Args:
        p: (3, J, T) planes. zmin: (T,) lowest keypoint height.
        com: (K,) keypoints of the centre-of-mass proxy (K >= 1).
        hands: (H,) keypoints counted ``hand_reach`` metres lower.
        ankles: (A,) keypoints counted ``ankle_sole`` metres lower (the ankles of a
            skeleton without toes; empty otherwise).
        float_height: metres. gravity: m/s^2. tolerance: RMS residual of a
            ballistic flight, metres.
        tl: (T,) out: timeline, mm. details: out: (airborne fraction,
            floating fraction, worst residual m, jumps).

    Returns:
        The value: the timeline's maximum.
    """
    t_count = zmin.shape[0]
    half_g = 0.5 * gravity
    lowest = zmin.copy()
    for h in hands:
        zh = p[2, h]
        for t in range(t_count):
            lowest[t] = min(lowest[t], np.float64(zh[t]) - hand_reach)
    for a in ankles:
        za = p[2, a]
        for t in range(t_count):
            lowest[t] = min(lowest[t], np.float64(za[t]) - ankle_sole)
    com_z = _mean_height(p, com)
    tl[:] = 0.0
    worst, jumps, airborne, floating_frames = 0.0, 0, 0, 0
    t = 0
    while t < t_count:
        if not lowest[t] > float_height:
            t += 1
            continue
        start = t
        while t < t_count and lowest[t] > float_height:
            t += 1
        n = t - start
        airborne += n
        residual = _ballistic_rms(com_z, start, n, fps, half_g) if n >= 3 else 0.0
        worst = max(worst, residual)
        if residual > tolerance:
            floating_frames += n
            for k in range(start, t):
                tl[k] = lowest[k] * 1000.0
        else:
            jumps += 1
    details[0] = airborne / t_count
    details[1] = floating_frames / t_count
    details[2] = worst
    details[3] = jumps
    return tl.max()


#: Arguments of a disabled metric slot for :func:`score`, one entry per slot: never
#: read, but of the types of the real ones, so that one compiled version serves every mix.
IDLE_ARGS: dict[int, tuple] = {
    BONE: (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0), 0.0, 0.0),
    FOOT: (np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0, dtype=np.bool_), 0.0, 0.0, 0.0,
           0.0, 0, 0, 0.0, 0.0),
    GROUND: (),
    FLOAT: (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), 0.0,
            np.zeros(0, dtype=np.int64), 0.0, 0.0, 0.0, 0.0, 0.0),
    JITTER: (False, np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.float32), 0.0, 0.0, 0,
             0.0, 0.0, 0.0, 0.0, 0.0, np.zeros((0, 2), dtype=np.int64)),
    VELOCITY: (np.zeros(0), 0.0, 0.0),
}
