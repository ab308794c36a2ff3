"""Joint limits: hinge angles beyond their anatomical ranges that the motion demands.

The metric (:class:`JointLimits`, :func:`joint_limits`) refits the motion onto a
copy of the fitted body whose hinge ranges are widened
(:func:`relaxed_humanoid`), and counts a hinge's excess on a frame only where
its limits cost keypoint accuracy (:func:`joint_limit_demand`). Ranges:
:data:`simenv.body.humanoid.JOINTS`; thresholds: ``joint_limit_*`` of
:class:`~simenv.plausibility.body_thresholds.BodyThresholds`. Metres in,
degrees out.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import partial
from operator import attrgetter

import mujoco
import numpy as np

from simenv.body.geometry import BOX_CORNERS, body_boxes, check_qpos, lowest_box_z
from simenv.body.humanoid import Humanoid
from simenv.body.retarget import RetargetResult, retarget
from simenv.core.motion import Motion
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS, BodyThresholds
from simenv.plausibility.metric import BodyMetric, PersonInputs, not_available
from simenv.plausibility.timeline import MetricResult


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
    started from ``qpos[t]``, when given
    from ``qpos[t]`` with the moving hinges set to ``alternative[t]``'s (the
    limited fit: an in-range split), and from ``qpos[t]`` with the moving hinges
    clipped into their ranges; the lowest final cost wins. (The third start: on the
    real HumanML3D serve 012314, frame 23, the limited fit's start stalled at a cost
    of 812 or 83 as the root moved by 0.1 mm, giving 14.0 or 8.3 deg; the clipped start
    reaches 75 and 8.5 deg from both.)

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
            starts[-1][hq[free]] = alternative[t, hq[free]]
        starts.append(starts[0].copy())
        starts[-1][hq[free]] = np.clip(starts[0][hq[free]], problem.lo[free], problem.hi[free])
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


class JointLimits(BodyMetric):
    """Hinge angles beyond their anatomical ranges that the motion demands
    (:func:`joint_limits`).

    The motion is refitted onto a body with ranges widened by
    ``joint_limit_probe_deg``; per frame ``max_h excess_h(t)`` degrees over the
    hinges whose limits cost more than ``joint_limit_cost_m`` of keypoint
    accuracy; value: the largest excess held for ``joint_limit_min_duration_s``;
    passes at <= ``joint_limit_max_deg``. Off when ``ScoreConfig.joint_limits``
    is False.
    """

    name, unit, limit = "joint_limits", "deg", attrgetter("joint_limit_max_deg")

    def compute(self, inputs: PersonInputs) -> MetricResult:
        if not inputs.config.joint_limits:
            return not_available(self, inputs.frames, inputs.config,
                                 "joint-limit probe disabled in the config")
        return joint_limits(inputs.motion, inputs.config.body, fitted=inputs.fitted)
