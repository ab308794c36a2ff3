"""Body-level plausibility metrics on the retargeted MuJoCo humanoid(s).

Where :mod:`simenv.plausibility.contact` looks at keypoints (joint centres),
these metrics look at the body's collision geoms (capsules and boxes that
stand for the skin) posed by a retargeted qpos trajectory
(:func:`simenv.body.retarget.retarget`). World Z-up, floor = plane z = 0, metres
internally, millimetres and degrees in the results.

=================== ================================================= =============
name                what                                              input
=================== ================================================= =============
body_penetration    lowest geom point below the floor                 RetargetResult
body_floating       airborne geoms without a ballistic centre of mass RetargetResult
joint_limits        hinge angles beyond the anatomical ranges         Motion / result
self_penetration    depth between non-neighbouring geoms of one body  RetargetResult
inter_penetration   depth between the geoms of two people             interaction result
contact             key joint-pair distances (JPD) and their contacts interaction result
=================== ================================================= =============

Poses are computed once per trajectory
(:func:`simenv.body.geometry.body_poses`: ``mj_kinematics`` per frame, then
every geometric quantity vectorised over frames). Each metric
returns a :class:`~simenv.plausibility.timeline.MetricResult` with a per-frame
timeline; thresholds are in
:class:`~simenv.plausibility.body_thresholds.BodyThresholds`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import partial

import mujoco
import numpy as np

from simenv.body.geometry import (
    BOX_CORNERS,
    BodyPoses,
    body_boxes,
    body_geoms,
    body_poses,
    check_qpos,
    contact_depths,
    geom_lowest_z,
    lowest_box_z,
)
from simenv.body.humanoid import Humanoid
from simenv.body.retarget import InteractionRetargetResult, RetargetResult, retarget
from simenv.core.errors import MotionError
from simenv.core.motion import Interaction, Motion
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS, BodyThresholds
from simenv.plausibility.contact import ballistic_residual
from simenv.plausibility.timeline import MetricResult

#: Key joint pairs (person A keypoint, person B keypoint) of an interaction:
#: the handshake pair and the interaction-augmentation seed's A right hand -
#: B spine, plus its mirror.
DEFAULT_CONTACT_PAIRS: tuple[tuple[str, str], ...] = (
    ("right_hand", "right_hand"),
    ("right_hand", "spine"),
    ("spine", "right_hand"),
)


# -- ground ----------------------------------------------------------------------


def _lowest(result: RetargetResult, poses: BodyPoses | None) -> tuple[np.ndarray, BodyPoses]:
    """(T,) height of the lowest body geom point, metres, and the poses used
    (``poses`` when given, else computed)."""
    model = result.humanoid.model
    if poses is None:
        poses = body_poses(model, result.qpos)
    return geom_lowest_z(model, poses, body_geoms(model)).min(axis=1), poses


def body_penetration(result: RetargetResult,
                     thresholds: BodyThresholds = DEFAULT_BODY_THRESHOLDS, *,
                     poses: BodyPoses | None = None) -> MetricResult:
    """Depth of the body's lowest geom point below the floor.

    Timeline: ``max(0, -min_g z_low,g(t)) * 1000`` mm over every body geom
    (:func:`~simenv.body.geometry.geom_lowest_z`: exact for capsules and boxes), so a sinking foot,
    knee or hand counts. Value: the maximum over frames; passes when at most
    ``geom_penetration_max_mm``. Details: ``mean_mm`` (PhysDiff's
    "penetrate", here on geoms instead of mesh vertices) and
    ``frames_below_floor`` (fraction of frames deeper than 1 mm). ``poses``:
    ``result``'s forward kinematics when the caller has them.
    """
    lowest, _ = _lowest(result, poses)
    depth = np.maximum(-lowest, 0.0) * 1000.0
    return MetricResult.from_timeline(
        "body_penetration", depth, float(depth.max()), "mm",
        thresholds.geom_penetration_max_mm,
        details={"mean_mm": float(depth.mean()), "frames_below_floor": float((depth > 1).mean())},
    )


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of each run of True in a 1-D mask."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def body_floating(result: RetargetResult,
                  thresholds: BodyThresholds = DEFAULT_BODY_THRESHOLDS, *,
                  poses: BodyPoses | None = None) -> MetricResult:
    """Floating on geoms: airborne frames whose centre of mass does not fall.

    A frame is airborne when every body geom is more than
    ``geom_float_clearance_m`` above the floor (hands, knees and the back all
    count as support: the geoms are the skin). Each maximal airborne run is
    a jump when the true centre of mass (body masses of the model) follows a
    free-fall parabola within ``ballistic_tolerance_m`` RMS
    (:func:`simenv.plausibility.contact.ballistic_residual`), and floating
    otherwise. Timeline: clearance (mm) of the lowest geom on floating frames,
    0 elsewhere; value: its maximum; passes when no frame floats. Details:
    ``airborne_fraction``, ``floating_fraction``, ``worst_residual_m``,
    ``jumps``. Assumes the floor is the only support. ``poses``: ``result``'s
    forward kinematics when the caller has them.
    """
    thr = thresholds.geom_float_clearance_m * 1000.0
    T = result.num_frames
    if T < 3:
        return MetricResult.not_available(
            "body_floating", T, "mm", thr,
            f"needs at least 3 frames to tell a jump from floating; the motion has {T}")
    lowest, poses = _lowest(result, poses)
    airborne = lowest > thresholds.geom_float_clearance_m
    floating_mask = np.zeros(T, dtype=bool)
    worst, jumps = 0.0, 0
    for start, stop in _runs(airborne):
        residual = ballistic_residual(poses.com[start:stop, 2], result.fps,
                                      thresholds.gravity_mps2)
        worst = max(worst, residual)
        if residual > thresholds.ballistic_tolerance_m:
            floating_mask[start:stop] = True
        else:
            jumps += 1
    timeline = np.where(floating_mask, lowest * 1000.0, 0.0)
    return MetricResult.from_timeline(
        "body_floating", timeline, float(timeline.max()), "mm", thr,
        details={"airborne_fraction": float(airborne.mean()),
                 "floating_fraction": float(floating_mask.mean()),
                 "worst_residual_m": worst, "jumps": float(jumps)},
    )


# -- joint limits ----------------------------------------------------------------


def relaxed_humanoid(humanoid: Humanoid, margin_deg: float) -> Humanoid:
    """A copy of ``humanoid`` whose hinge ranges in ``model.jnt_range`` are
    widened by ``margin_deg`` on both sides (for probing what a motion
    demands); its :attr:`Humanoid.joint_limits` keep the anatomical ranges."""
    wide = Humanoid(humanoid.dims, name=humanoid.name)
    hinges = np.flatnonzero(wide.model.jnt_type == mujoco.mjtJoint.mjJNT_HINGE)
    margin = np.deg2rad(margin_deg)
    wide.model.jnt_range[hinges, 0] -= margin
    wide.model.jnt_range[hinges, 1] += margin
    return wide


def joint_limit_excess(humanoid: Humanoid, qpos: np.ndarray) -> np.ndarray:
    """Per-frame excess of each hinge beyond its anatomical range.

    Args:
        humanoid: gives the ranges (:attr:`Humanoid.joint_limits`) and layout.
        qpos: (T, nq) configurations.

    Returns:
        (T, H) degrees, 0 inside the range, in :attr:`Humanoid.joint_names` order.
    """
    q = check_qpos(humanoid.model, qpos)[:, humanoid.hinge_qpos]
    lo, hi = humanoid.joint_limits[:, 0], humanoid.joint_limits[:, 1]
    return np.rad2deg(np.maximum(lo - q, 0.0) + np.maximum(q - hi, 0.0))


def observed_hinges(humanoid: Humanoid, keypoints: Sequence[str]) -> np.ndarray:
    """(H,) bool: hinges that move at least one of ``keypoints``' sites.

    The others (the toes: no keypoint sits beyond the metatarsophalangeal
    joint) get their angle from the retargeting's regulariser and floor
    constraint only, not from the motion, so their limits say nothing
    about it.
    """
    return hinge_keypoints(humanoid, keypoints).any(axis=1)


def hinge_keypoints(humanoid: Humanoid, keypoints: Sequence[str]) -> np.ndarray:
    """(H, K) bool: which of ``keypoints`` (in that order) each hinge moves.

    A hinge moves the keypoint sites on the bodies of its body's subtree
    (e.g. ``left_foot_flex`` moves ``left_toe`` only: the ankle site sits on
    the shin). Rows in :attr:`Humanoid.joint_names` order.
    """
    m = humanoid.model
    index = dict(zip(humanoid.keypoint_names, humanoid.site_ids, strict=True))
    site_body = m.site_bodyid[[index[k] for k in keypoints]]
    hinges = np.flatnonzero(m.jnt_type == mujoco.mjtJoint.mjJNT_HINGE)
    out = np.zeros((len(hinges), len(site_body)), dtype=bool)
    for i, b0 in enumerate(site_body):
        b = int(b0)
        while b > 0:  # every ancestor body's hinges move this site
            out[m.jnt_bodyid[hinges] == b, i] = True
            b = int(m.body_parentid[b])
    return out


def joint_limit_clamp_cost(humanoid: Humanoid, qpos: np.ndarray, targets: np.ndarray,
                           keypoints: Sequence[str], candidates: np.ndarray) -> np.ndarray:
    """What clamping one hinge back into its range costs, without re-solving.

    For each candidate (frame, hinge): the hinge alone is set to the nearest
    end of its anatomical range in ``qpos`` (every other coordinate kept),
    forward kinematics (``mj_kinematics``) places the keypoint sites, and the
    cost is the increase of the worst residual over the keypoints that hinge
    moves (:func:`hinge_keypoints`).

    Args:
        humanoid: gives the ranges (:attr:`Humanoid.joint_limits`) and model.
        qpos: (T, nq) configurations (a relaxed fit).
        targets: (T, K, 3) target keypoints, metres, in ``keypoints`` order.
        keypoints: the K keypoint names of ``targets``.
        candidates: (N, 2) int (frame, hinge index) pairs.

    Returns:
        (N,) metres (negative when clamping brings the sites closer).
    """
    m, d = humanoid.model, mujoco.MjData(humanoid.model)
    moves = hinge_keypoints(humanoid, keypoints)
    index = dict(zip(humanoid.keypoint_names, humanoid.site_ids, strict=True))
    sites = np.array([index[k] for k in keypoints])
    lo, hi = humanoid.joint_limits[:, 0], humanoid.joint_limits[:, 1]
    cost = np.zeros(len(candidates))
    last = -1
    for n, (t, h) in enumerate(np.asarray(candidates, dtype=int).reshape(-1, 2)):
        ks = moves[h]
        if not ks.any():
            continue
        if t != last:
            d.qpos[:] = qpos[t]
            mujoco.mj_kinematics(m, d)
            before = np.linalg.norm(d.site_xpos[sites] - targets[t], axis=1)
            last = t
        q = qpos[t].copy()
        a = humanoid.hinge_qpos[h]
        q[a] = np.clip(q[a], lo[h], hi[h])
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        after = np.linalg.norm(d.site_xpos[sites[ks]] - targets[t, ks], axis=1)
        cost[n] = after.max() - before[ks].max()
    return cost


class _LeastExcess:
    """The per-frame least-squares problem of :func:`joint_limit_least_excess`:
    residuals and Jacobians over the hinges of the bodies allowed to move."""

    #: Weight per metre of a keypoint beyond its tolerance or a corner below the floor.
    WEIGHT = 1e4
    #: Degrees per radian: the hinge excess terms are in degrees.
    DEG = float(np.rad2deg(1.0))

    def __init__(self, humanoid: Humanoid, keypoints: Sequence[str], targets: np.ndarray,
                 tolerance: np.ndarray, floor: np.ndarray | None) -> None:
        m = humanoid.model
        self.model, self.data = m, mujoco.MjData(m)
        index = dict(zip(humanoid.keypoint_names, humanoid.site_ids, strict=True))
        self.sites = np.array([index[k] for k in keypoints])
        self.lo, self.hi = humanoid.joint_limits[:, 0], humanoid.joint_limits[:, 1]
        self.hq = humanoid.hinge_qpos
        hinge_ids = np.flatnonzero(m.jnt_type == mujoco.mjtJoint.mjJNT_HINGE)
        self.hv, self.hbody = m.jnt_dofadr[hinge_ids], m.jnt_bodyid[hinge_ids]
        self.observed = observed_hinges(humanoid, keypoints)
        self.targets, self.tolerance, self.floor = targets, tolerance, floor
        self.jac = np.zeros((3, m.nv))
        self.boxes = body_boxes(m)

    def soles(self, free: np.ndarray) -> np.ndarray:
        """The box geoms on the bodies the ``free`` hinges move (their bodies'
        subtrees)."""
        m = self.model
        inside = np.isin(np.arange(m.nbody), self.hbody[free])
        for b in range(1, m.nbody):  # parents precede children
            inside[b] |= inside[m.body_parentid[b]]
        return self.boxes[inside[m.geom_bodyid[self.boxes]]]

    def excess(self, q: np.ndarray) -> np.ndarray:
        """(H,) radians beyond the range of each observed hinge of ``q``."""
        lo, hi, hq = self.lo, self.hi, self.hq
        return np.where(self.observed,
                        np.maximum(lo - q[hq], 0.0) + np.maximum(q[hq] - hi, 0.0), 0.0)

    def residual(self, q: np.ndarray, t: int, free: np.ndarray,
                 soles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residuals (keypoints beyond tolerance, sole corners below the floor,
        hinge excess) of ``q`` on frame ``t`` and their Jacobian over the
        ``free`` hinges."""
        m, d, jac, sites, weight, deg = (self.model, self.data, self.jac, self.sites,
                                         self.WEIGHT, self.DEG)
        hv, hq, hi, floor = self.hv, self.hq, self.hi, self.floor
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)  # mj_jacSite / mj_jac read the com-based frames
        diff = d.site_xpos[sites] - self.targets[t]
        dist = np.linalg.norm(diff, axis=1)
        over = dist - self.tolerance[t]
        ex = self.excess(q)[free]
        corners = (d.geom_xpos[soles, None] + np.einsum(
            "gij,gpj->gpi", d.geom_xmat[soles].reshape(-1, 3, 3),
            BOX_CORNERS * m.geom_size[soles, None])).reshape(-1, 3)
        sink = (floor[t] - corners[:, 2]) if floor is not None else np.zeros(0)
        r = np.concatenate([weight * np.maximum(over, 0.0), weight * np.maximum(sink, 0.0),
                            deg * ex])
        J = np.zeros((len(r), len(free)))
        for k in np.flatnonzero(over > 0):
            mujoco.mj_jacSite(m, d, jac, None, int(sites[k]))
            J[k] = weight * (diff[k] / max(dist[k], 1e-9)) @ jac[:, hv[free]]
        for c in np.flatnonzero(sink > 0):
            mujoco.mj_jac(m, d, jac, None, corners[c], int(m.geom_bodyid[soles[c // 8]]))
            J[len(sites) + c] = -weight * jac[2, hv[free]]
        h = np.flatnonzero(ex > 0)
        J[len(sites) + len(sink) + h, h] = np.where(q[hq[free[h]]] > hi[free[h]], deg, -deg)
        return r, J


def _levenberg_marquardt(residual: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
                         q: np.ndarray, coords: np.ndarray, iterations: int
                         ) -> tuple[float, np.ndarray]:
    """Minimise ``|residual(q)|^2`` over ``q[coords]`` from ``q`` (Marquardt's
    diagonal damping); returns the final cost and ``q``."""
    r, J = residual(q)
    cost, lam = float(r @ r), 1e-3
    for _ in range(iterations):
        H = J.T @ J
        step = -np.linalg.solve(H + lam * (np.diag(np.diag(H)) + 1e-6 * np.eye(len(coords))),
                                J.T @ r)
        trial = q.copy()
        trial[coords] += step
        rt, Jt = residual(trial)
        ct = float(rt @ rt)
        if ct < cost:
            done = cost - ct < 1e-6 * cost + 1e-9
            q, r, J, cost, lam = trial, rt, Jt, ct, lam * 0.3
            if done:
                break
        else:
            lam *= 10.0
            if lam > 1e8:
                break
    return cost, q


def joint_limit_least_excess(humanoid: Humanoid, qpos: np.ndarray, targets: np.ndarray,
                             keypoints: Sequence[str], frames: np.ndarray,
                             flagged: np.ndarray, tolerance: np.ndarray,
                             alternative: np.ndarray | None = None,
                             floor: np.ndarray | None = None,
                             iterations: int = 30) -> np.ndarray:
    """The least excess with which the flagged bodies still reach the keypoints.

    A fit's hinge angles on one body are one decomposition of that body's
    orientation relative to its parent among several the keypoints cannot
    tell apart: a foot whose ankle and toe are seen, but not its roll about
    their line, is reached with abduction, inversion and flexion in many
    proportions, and a solver with widened ranges has no reason to pick the
    split closest to the anatomical ranges. Per frame ``t`` only the hinges
    of the bodies that carry a flagged hinge move (everything else stays at
    ``qpos[t]``, so the split is re-chosen within each body and nothing is
    moved to another joint: an elbow bent backwards stays an elbow bent
    backwards, it does not become an upper arm twisted half a turn) and

        min  sum_h e_h^2 + sum_k (W max(0, |site_k - x_tk| - tol_k))^2
                         + sum_c (W max(0, f_t - z_c))^2

    with ``e_h`` the excess of hinge ``h`` beyond its range (degrees),
    ``tol_k`` the allowed distance of keypoint ``k`` (metres), ``z_c`` the
    heights of the corners of the moving box geoms (soles, hands), ``f_t``
    the floor level of the frame (``floor``; the fits keep the soles above
    the floor too, and a re-split must not buy its accuracy by pushing a
    foot through it) and ``W = 10^4`` per metre (1 mm beyond a tolerance
    weighs like 10 degrees, so the tolerances are nearly hard).
    Levenberg-Marquardt with analytic Jacobians (``mj_jacSite``, ``mj_jac``),
    started from ``qpos[t]`` and, when given,
    from ``qpos[t]`` with the moving hinges set to ``alternative[t]``'s (the
    limited fit: an in-range split); the lower final cost wins.

    Args:
        humanoid: gives the ranges (:attr:`Humanoid.joint_limits`) and model.
        qpos: (T, nq) configurations (a relaxed fit).
        targets: (T, K, 3) target keypoints, metres, in ``keypoints`` order.
        keypoints: the K keypoint names of ``targets``.
        frames: (N,) int frames to solve.
        flagged: (N, H) bool, the hinges whose bodies may move per frame.
        tolerance: (T, K) metres.
        alternative: optional (T, nq) second start.
        floor: optional (T,) lowest allowed corner height, metres (default:
            no floor term).
        iterations: Levenberg-Marquardt iterations per start.

    Returns:
        (N, H) degrees, the excess of each hinge in the solution (0 on the
        hinges no keypoint observes), :attr:`Humanoid.joint_names` order.
    """
    problem = _LeastExcess(humanoid, keypoints, targets, tolerance, floor)
    hq, hbody = problem.hq, problem.hbody
    out = np.zeros((len(frames), len(hq)))
    for n, t in enumerate(np.asarray(frames, dtype=int)):
        free = np.flatnonzero(np.isin(hbody, hbody[flagged[n]]))
        frame_residual = partial(problem.residual, t=t, free=free, soles=problem.soles(free))
        starts = [np.array(qpos[t], dtype=np.float64)]
        if alternative is not None:
            starts.append(starts[0].copy())
            starts[1][hq[free]] = alternative[t, hq[free]]
        best_cost, best_q = np.inf, starts[0]
        for start in starts:
            cost, q = _levenberg_marquardt(frame_residual, start, hq[free], iterations)
            if cost < best_cost:
                best_cost, best_q = cost, q
        out[n] = problem.DEG * problem.excess(best_q)
    return out


def joint_limit_demand(motion: Motion, thresholds: BodyThresholds = DEFAULT_BODY_THRESHOLDS,
                       *, fitted: RetargetResult | None = None
                       ) -> tuple[np.ndarray, RetargetResult, RetargetResult]:
    """Per frame and hinge, the excess beyond the anatomical range the motion demands.

    ``motion`` is retargeted onto its fitted body (``fitted`` when given) and
    onto :func:`relaxed_humanoid` (ranges widened by
    ``joint_limit_probe_deg``). A hinge's excess in the relaxed fit counts on
    a frame only when both hold:

    * *the limits cost accuracy where the hinge acts*: over the keypoints the
      hinge moves (:func:`hinge_keypoints`), the limited fit's worst residual
      exceeds the relaxed fit's by more than ``joint_limit_cost_m``. (A
      per-hinge form of the whole-frame test: a frame whose worst keypoint
      is a toe the ankle limit costs does not make a wrist the relaxed solver
      bent on the same frame count, and an unrelated noisy keypoint does not
      hide a knee bent backwards.)
    * *this hinge's violation buys it*: clamping that hinge alone back into
      its range in the relaxed solution raises the worst residual of the
      keypoints it moves by more than ``joint_limit_cost_m``
      (:func:`joint_limit_clamp_cost`). A hinge the relaxed solver twists
      freely because no keypoint observes it (a foot rolled about its long
      axis, which the ankle and toe keypoints barely see) costs nothing to
      clamp, so it is not blamed for a cost another hinge causes.

    On the frames where some hinge passes both tests the excess is then re-
    measured as the *least* the flagged bodies need, each re-splitting its own
    orientation (:func:`joint_limit_least_excess`): every keypoint within
    ``joint_limit_cost_m`` of where the relaxed fit put it (the tests' own
    notion of accuracy the limits may cost), and no sole or hand box lower
    than either fit put it on that frame. A frame keeps the relaxed fit's
    excess when that is not larger. Measured on real CMU clips
    (``benchmarks/calibrate_joint_limits.py``): the relaxed fit's foot angles
    are one split of a foot orientation the ankle and toe keypoints see only
    in part, and the widened ranges let it pick one far outside them (see the
    table in :mod:`simenv.plausibility.body_thresholds`).

    Returns:
        ``(demand, limited, relaxed)``: (T, H) degrees in
        :attr:`Humanoid.joint_names` order (0 where not demanded, and on the
        hinges no keypoint observes), and the two fits.
    """
    fitted = fitted if fitted is not None else retarget(motion)
    relaxed = retarget(motion, humanoid=relaxed_humanoid(
        fitted.humanoid, thresholds.joint_limit_probe_deg))
    body, names = fitted.humanoid, relaxed.keypoint_names
    excess = joint_limit_excess(body, relaxed.qpos)
    moves = hinge_keypoints(body, names)
    excess[:, ~moves.any(axis=1)] = 0.0
    cand = np.argwhere(excess > 0.0)
    if len(cand):
        t, h = cand[:, 0], cand[:, 1]
        lim_res = np.where(moves[h], fitted.residuals[t], -np.inf).max(axis=1)
        rel_res = np.where(moves[h], relaxed.residuals[t], -np.inf).max(axis=1)
        local = lim_res - rel_res > thresholds.joint_limit_cost_m
        clamp = np.zeros(len(cand), dtype=bool)
        clamp[local] = joint_limit_clamp_cost(
            body, relaxed.qpos, relaxed.targets.astype(np.float64), names, cand[local]
        ) > thresholds.joint_limit_cost_m
        excess[t[~clamp], h[~clamp]] = 0.0
    frames = np.flatnonzero(excess.max(axis=1) > 0.0)
    if len(frames):
        tolerance = relaxed.residuals.astype(np.float64) + thresholds.joint_limit_cost_m
        floor = np.full(len(relaxed.qpos), np.inf)
        floor[frames] = np.minimum(lowest_box_z(body.model, relaxed.qpos[frames]),
                                   lowest_box_z(body.model, fitted.qpos[frames]))
        least = joint_limit_least_excess(body, relaxed.qpos, relaxed.targets.astype(np.float64),
                                         names, frames, excess[frames] > 0.0, tolerance,
                                         alternative=fitted.qpos, floor=floor)
        lower = least.max(axis=1) < excess[frames].max(axis=1)
        excess[frames[lower]] = least[lower]
    return excess, fitted, relaxed


def joint_limits(source: Motion | RetargetResult,
                 thresholds: BodyThresholds = DEFAULT_BODY_THRESHOLDS, *,
                 fitted: RetargetResult | None = None) -> MetricResult:
    """Anatomical joint-angle violations.

    A trajectory from :func:`simenv.body.retarget.retarget` respects the limits by
    construction (the solver projects onto them), so a :class:`Motion` is
    retargeted twice, onto its fitted body and onto :func:`relaxed_humanoid`
    (ranges widened by ``joint_limit_probe_deg``), and a hinge's excess in
    the relaxed fit counts on a frame only where the motion demands it
    (:func:`joint_limit_demand`): the limits cost more than
    ``joint_limit_cost_m`` of keypoint accuracy where that hinge acts, and
    clamping that hinge alone back into its range costs that much too.
    Elsewhere a relaxed angle beyond a limit is an equivalent pose the
    limited fit also reaches (a twist shared between hip rotation and foot
    abduction, a wrist bend the solver put into deviation instead of
    pronation plus flexion), or a rotation no keypoint observes. A
    :class:`RetargetResult` is measured as it is (qpos from a policy, a
    generator, a relaxed fit), every frame counting. ``fitted``: the
    motion's retargeting onto its fitted body when the caller already has
    it (saves one of the two fits).

    Timeline: ``max_h excess_h(t)`` degrees (:func:`joint_limit_excess`) over
    the hinges the motion's keypoints observe (:func:`observed_hinges`), 0
    where not demanded; on the frames a hinge is demanded, the least excess
    the flagged bodies need (:func:`joint_limit_least_excess`). Value: the
    largest excess the timeline holds for ``joint_limit_min_duration_s``
    (:func:`sustained_max`; one frame below 40 fps); passes when at most
    ``joint_limit_max_deg``. ``peak_deg`` in the details is the single-frame
    maximum. Details:
    ``frames_over`` (fraction of frames above 1 degree), ``joints_over``
    (hinges above the threshold anywhere), ``mean_deg``, ``worst_hinge``
    (index into :attr:`Humanoid.joint_names` of the hinge with the largest
    excess, -1 when none), and for a Motion ``limit_cost_p95_mm`` (95th
    percentile over frames of the worst residual the limits add).
    """
    details: dict[str, float] = {}
    if isinstance(source, Motion):
        excess, fitted, relaxed = joint_limit_demand(source, thresholds, fitted=fitted)
        cost = fitted.residuals.max(axis=1) - relaxed.residuals.max(axis=1)
        details["limit_cost_p95_mm"] = float(np.percentile(cost, 95) * 1000.0)
    else:
        excess = joint_limit_excess(source.humanoid, source.qpos)
        excess[:, ~observed_hinges(source.humanoid, source.keypoint_names)] = 0.0
    timeline = excess.max(axis=1)
    thr = thresholds.joint_limit_max_deg
    fps = source.fps
    held = sustained_max(timeline, max(1, int(np.ceil(thresholds.joint_limit_min_duration_s
                                                      * fps - 1e-9))))
    peak = excess.max(axis=0)
    details.update({"frames_over": float((timeline > 1.0).mean()),
                    "joints_over": float((peak > thr).sum()),
                    "mean_deg": float(timeline.mean()),
                    "peak_deg": float(timeline.max()) if len(timeline) else 0.0,
                    "worst_hinge": float(peak.argmax()) if peak.max() > 0 else -1.0})
    return MetricResult.from_timeline("joint_limits", timeline, held, "deg",
                                      thr, details=details)


def sustained_max(timeline: np.ndarray, frames: int) -> float:
    """The largest value a (T,) timeline holds for ``frames`` consecutive frames:
    ``max_t min(timeline[t : t + frames])`` (the plain maximum for one frame, or
    when the timeline is shorter than ``frames``)."""
    x = np.asarray(timeline, dtype=float)
    if len(x) == 0:
        return 0.0
    if frames <= 1 or len(x) < frames:
        return float(x.max())
    windows = np.lib.stride_tricks.sliding_window_view(x, frames)
    return float(windows.min(axis=1).max())


# -- penetration between geoms ---------------------------------------------------


def _penetration_result(name: str, depth: np.ndarray, pair: np.ndarray, thr: float
                        ) -> MetricResult:
    mm = depth * 1000.0
    return MetricResult.from_timeline(
        name, mm, float(mm.max()), "mm", thr,
        details={"mean_mm": float(mm.mean()), "frames_over": float((mm > thr).mean()),
                 "frames_touching": float((pair[:, 0] >= 0).mean())},
    )


def self_penetration(result: RetargetResult,
                     thresholds: BodyThresholds = DEFAULT_BODY_THRESHOLDS) -> MetricResult:
    """Penetration between non-neighbouring geoms of one retargeted body.

    Pairs of bodies at tree distance 1 (parent-child, filtered by MuJoCo) and
    2 (siblings, grandparents: excluded by :mod:`simenv.body.humanoid`) overlap at
    the joints by construction and are not counted; everything else (an arm
    in the torso, a hand in the head, thigh in thigh) is. Timeline: deepest
    penetration (mm) per frame (``mj_collision`` contact distance); value:
    its maximum; passes when at most ``self_penetration_max_mm``. Details:
    ``mean_mm``, ``frames_over`` (fraction above the threshold),
    ``frames_touching`` (any counted contact). See :func:`self_contact_pairs`
    for the geom names per frame.
    """
    model = result.humanoid.model
    body = model.geom_bodyid > 0
    depth, pair = contact_depths(model, result.qpos, body[:, None] & body[None, :])
    return _penetration_result("self_penetration", depth, pair,
                               thresholds.self_penetration_max_mm)


def self_contact_pairs(result: RetargetResult) -> list[tuple[int, str, str, float]]:
    """Every frame with a self-contact: ``(frame, geom a, geom b, depth mm)``
    of its deepest pair (for reports naming the parts)."""
    model = result.humanoid.model
    body = model.geom_bodyid > 0
    depth, pair = contact_depths(model, result.qpos, body[:, None] & body[None, :])
    return [(t, model.geom(int(a)).name, model.geom(int(b)).name, float(d * 1000))
            for t, ((a, b), d) in enumerate(zip(pair, depth, strict=True)) if a >= 0]


def inter_penetration(result: InteractionRetargetResult,
                      thresholds: BodyThresholds = DEFAULT_BODY_THRESHOLDS) -> MetricResult:
    """Penetration between the geoms of two people of one scene.

    A geom belongs to the person whose root body carries it
    (``body_rootid``). Timeline: deepest penetration (mm) between geoms of
    different people per frame; value: its maximum; passes when at most
    ``inter_penetration_max_mm``. Details as :func:`self_penetration`
    (``frames_touching``: the people's geoms touch).
    """
    model = result.scene.model
    root = model.body_rootid[model.geom_bodyid]
    person = np.where(model.geom_bodyid > 0, root, -1)
    keep = (person[:, None] >= 0) & (person[None, :] >= 0) & (person[:, None] != person[None, :])
    depth, pair = contact_depths(model, result.qpos, keep)
    return _penetration_result("inter_penetration", depth, pair,
                               thresholds.inter_penetration_max_mm)


# -- interaction contacts ----------------------------------------------------------


def _keypoint_tracks(names: Sequence[str], positions: np.ndarray,
                     wanted: Sequence[str]) -> dict[str, np.ndarray]:
    return {k: positions[:, list(names).index(k)] for k in wanted if k in names}


def pair_distances(result: InteractionRetargetResult,
                   pairs: Sequence[tuple[str, str]] = DEFAULT_CONTACT_PAIRS) -> np.ndarray:
    """Distances between key joint pairs on the retargeted bodies.

    Args:
        result: two retargeted people in one scene.
        pairs: (keypoint of person A, keypoint of person B), canonical names.

    Returns:
        (T, len(pairs)) metres, from the bodies' keypoint sites.
    """
    scene = result.scene
    poses = body_poses(scene.model, result.qpos)
    names = list(scene.humanoids[0].keypoint_names)
    for a, b in pairs:
        for k in (a, b):
            if k not in names:
                raise MotionError(f"contact pair ({a!r}, {b!r}): {k!r} is not a canonical "
                                  f"keypoint; expected one of {', '.join(names)}", field=k)
    sa = [scene.site_ids[0][names.index(a)] for a, _ in pairs]
    sb = [scene.site_ids[1][names.index(b)] for _, b in pairs]
    return np.linalg.norm(poses.site_xpos[:, sa] - poses.site_xpos[:, sb], axis=-1)


def _reference_distances(reference: Interaction | InteractionRetargetResult,
                         pairs: Sequence[tuple[str, str]], T: int) -> np.ndarray:
    """(T, P) reference pair distances in metres; NaN where a keypoint is missing."""
    if isinstance(reference, InteractionRetargetResult):
        people = [(p.keypoint_names, p.targets) for p in reference.people]
    else:
        people = []
        for m in reference.people:
            canon = m.to_canonical()
            people.append((canon.skeleton.joint_names, canon.positions))
    for _, pos in people:
        if len(pos) != T:
            raise MotionError(f"reference has {len(pos)} frames; the scored interaction has "
                              f"{T}: JPD compares frame by frame", field="reference")
    out = np.full((T, len(pairs)), np.nan)
    (na, pa), (nb, pb) = people
    ta = _keypoint_tracks(na, pa, [a for a, _ in pairs])
    tb = _keypoint_tracks(nb, pb, [b for _, b in pairs])
    for i, (a, b) in enumerate(pairs):
        if a in ta and b in tb:
            out[:, i] = np.linalg.norm(ta[a].astype(float) - tb[b].astype(float), axis=-1)
    return out


def contact(result: InteractionRetargetResult,
            reference: Interaction | InteractionRetargetResult | None = None,
            pairs: Sequence[tuple[str, str]] = DEFAULT_CONTACT_PAIRS,
            thresholds: BodyThresholds = DEFAULT_BODY_THRESHOLDS) -> MetricResult:
    """Key joint-pair distance error (JPD) and contact retention.

    For each pair (A keypoint, B keypoint) -- by default A right hand - B right
    hand (handshake), A right hand - B spine (the interaction-augmentation
    seed's pair) and its mirror -- the distance ``d_p(t)`` on the retargeted
    bodies is compared with the reference distance ``r_p(t)``: the keypoints
    the bodies were fitted to (default), or another interaction of the same
    length (e.g. the ground truth of a generated one).

    Timeline: ``mean_p |d_p(t) - r_p(t)| * 1000`` mm (pairs missing in the
    reference are skipped); value: its mean over frames (JPD); passes when at
    most ``jpd_max_mm``. Details per pair ``i``: ``retention_i``, the fraction
    of reference contact frames (``r_p < contact_distance_m``) on which the
    bodies are in contact too (1 when the reference never touches),
    ``min_mm_i`` (closest approach on the bodies) and ``reference_contact_i``
    (fraction of frames in contact in the reference).
    """
    thr = thresholds.jpd_max_mm
    T = result.qpos.shape[0]
    d = pair_distances(result, pairs)
    r = _reference_distances(reference if reference is not None else result, pairs, T)
    have = ~np.isnan(r[0])
    if not have.any():
        return MetricResult.not_available(
            "contact", T, "mm", thr, "the reference has none of the key joint pairs "
            f"{list(pairs)}")
    err = np.abs(d[:, have] - r[:, have]) * 1000.0
    timeline = err.mean(axis=1)
    details: dict[str, float] = {}
    cd = thresholds.contact_distance_m
    for i in np.flatnonzero(have):
        ref_contact = r[:, i] < cd
        kept = (d[:, i] < cd) & ref_contact
        details[f"retention_{i}"] = float(kept.sum() / ref_contact.sum()) if ref_contact.any() \
            else 1.0
        details[f"min_mm_{i}"] = float(d[:, i].min() * 1000.0)
        details[f"reference_contact_{i}"] = float(ref_contact.mean())
    return MetricResult.from_timeline("contact", timeline, float(timeline.mean()), "mm", thr,
                                      details=details)
