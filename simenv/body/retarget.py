"""Retargeting: canonical keypoints -> qpos trajectory of a subject-fitted humanoid.

Per clip, :func:`retarget` solves for every frame t

    min_q  sum_k w_k |site_k(q_t) - x_tk|^2                    (keypoints)
         + w_floor sum_c min(0, z_c(q_t) - f_t)^2               (sole corners above the floor)
         + w_reg |theta_t|^2                                    (neutral pose, null space)
         + w_smooth |q_t - (q_{t-1} + q_{t+1}) / 2|^2           (temporal smoothness)
    s.t.   lower <= theta_t <= upper                            (joint limits)

with ``f_t = min(0, lowest height the data itself implies for the soles)``.

Solver (all frames at once, numpy):

1. **Per-frame analytic initial guess** -- the root from the pelvis-hip-hip
   triangle (the same frame used to measure the body, so it fits exactly),
   then each body in tree order from its bone direction plus a twist cue (the
   knee/elbow flexion plane, blended into the foot direction or the minimal
   swing as the limb straightens; the shoulder line for the spine), decomposed
   in closed form into the joint's hinge angles and clipped to the limits. Of
   the two Euler branches, the one kept is chosen over the whole clip
   (Viterbi: limit violation + angle change), so neither branch flips nor does
   any single frame impose its choice; no frame is warm-started from another,
   so the first frame does not decide the fate of the clip. The toes get the
   smallest extension keeping them above the floor. On a body fitted to the
   clip this guess is already exact (< 0.1 mm) on most frames.
2. **Keypoint refinement** of the other frames (joint limits or bone-length
   noise make them inexact): batched projected Levenberg-Marquardt with
   analytic Jacobians (:mod:`simenv.body.ik`), one 52x52 normal system per frame
   (accumulated over each point's ancestor joints only, Cholesky-solved in a
   compiled per-frame kernel, one call per iteration for all active frames);
   per-frame adaptive damping with accept/reject; limits by projection with an
   active set (hinges held at a bound drop out of the step); steps bounded to
   ``max_step`` radians; the smoothness term uses the neighbours of the
   previous iterate (a Jacobi sweep). Converged frames leave the active set.
3. **Floor**: the same solver on the frames whose sole boxes dip below the
   floor level, moving only the leg joints, with the one-sided floor term.

A skeleton that maps both hips but no pelvis (OpenNI / NiTE and Florence 3D hang the
hips from the torso centre) gets its pelvis keypoint at the hips' midpoint on every
frame (:func:`with_derived_pelvis`), as H36M's pelvis sits on its hip line; the body
is fitted to that motion and the repair is listed in ``RetargetResult.repairs``. The
derivation stays here, not in the canonical mapping: the joint-level metrics judge the
joints the file has, not a point made from two of them.
"""

from __future__ import annotations

import time
import weakref
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from simenv.body.humanoid import (
    Humanoid,
    Scene,
    build_scene,
    fit_humanoid,
    pelvis_frames,
)
from simenv.body.ik import (
    HingeTree,
    PointFit,
    compose_hinges,
    euler_branches,
    half_rotation,
    swing,
    two_vector,
    viterbi2,
)
from simenv.core.errors import RetargetError
from simenv.core.motion import Interaction, Motion
from simenv.core.skeletons import Skeleton

#: Keypoints without which the root cannot be placed.
REQUIRED_KEYPOINTS = ("pelvis", "left_hip", "right_hip")
_DEBUG = False


@dataclass(frozen=True)
class RetargetOptions:
    """Solver settings (weights are relative to keypoint errors in metres).

    Attributes:
        iterations: maximum Levenberg-Marquardt iterations.
        reg: weight of |theta|^2 (per rad^2); settles unobservable joints.
        smooth: weight of the second-difference term (per rad^2 / m^2).
        floor_weight: weight of sole penetration below the floor.
        max_step: largest joint change of one iteration, radians.
        tol: a frame stops iterating when its cost drops by less than this
            fraction (plus 1e-10 m^2) in an iteration...
        step_tol: ... or when its step is below this (radians or metres).
        accept: frames whose analytic initial guess already fits every keypoint
            within this distance (m), with the soles above the floor, are kept
            as they are.
        floor: apply the floor constraint.
    """

    iterations: int = 12
    reg: float = 1e-5
    smooth: float = 2e-5
    floor_weight: float = 100.0
    max_step: float = 0.5
    tol: float = 2e-3
    accept: float = 1e-4
    step_tol: float = 1e-4
    floor: bool = True


class _ResidualStats:
    """Mean, 95th percentile and maximum of a result's ``residuals`` (metres)."""

    residuals: np.ndarray

    @property
    def mean_residual(self) -> float:
        return float(self.residuals.mean())

    @property
    def p95_residual(self) -> float:
        return float(np.percentile(self.residuals, 95))

    @property
    def max_residual(self) -> float:
        return float(self.residuals.max())


@dataclass(eq=False)
class RetargetResult(_ResidualStats):
    """Retargeted trajectory of one person.

    Attributes:
        qpos: (T, nq) float64 MuJoCo configurations of ``humanoid.model``.
        residuals: (T, K) float32 metres, distance between each solved site and
            its target keypoint.
        keypoint_names: the K keypoints the motion provides (targets).
        targets: (T, K, 3) float32 target keypoints, metres.
        humanoid: the model used.
        fps: frame rate of the motion.
        seconds: solver wall time.
        iterations: Levenberg-Marquardt iterations run.
        name: motion name.
        notes: what the body fit assumed (keypoints it lacked, see
            :func:`simenv.body.humanoid.fit_humanoid`).
        repairs: what retargeting changed in the motion before fitting it (the
            ``metadata["repairs"]`` it added, e.g. a pelvis derived at the hips' midpoint).
    """

    qpos: np.ndarray
    residuals: np.ndarray
    keypoint_names: tuple[str, ...]
    targets: np.ndarray
    humanoid: Humanoid
    fps: float
    seconds: float
    iterations: int
    name: str = "motion"
    notes: list[str] = field(default_factory=list)
    repairs: list[str] = field(default_factory=list)

    @property
    def num_frames(self) -> int:
        return int(self.qpos.shape[0])

    @property
    def frames_per_second(self) -> float:
        return self.num_frames / max(self.seconds, 1e-9)

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly summary (no per-frame arrays)."""
        return {
            "name": self.name,
            "frames": self.num_frames,
            "fps": self.fps,
            "mean_residual_m": self.mean_residual,
            "p95_residual_m": self.p95_residual,
            "max_residual_m": self.max_residual,
            "per_keypoint_mean_m": dict(zip(self.keypoint_names,
                                            self.residuals.mean(axis=0).tolist(), strict=True)),
            "seconds": self.seconds,
            "iterations": self.iterations,
            "total_mass_kg": self.humanoid.total_mass,
            "height_m": self.humanoid.dims.height,
            "dimensions": self.humanoid.dims.to_dict(),
            "notes": list(self.notes),
            "repairs": list(self.repairs),
        }


@dataclass(eq=False)
class InteractionRetargetResult(_ResidualStats):
    """Both people of an :class:`Interaction`, each on its own fitted body, in one scene.

    Attributes:
        people: (actor result, reactor result).
        scene: the combined model (prefixes ``actor/`` and ``reactor/``).
        qpos: (T, scene.model.nq) combined trajectory.
    """

    people: tuple[RetargetResult, RetargetResult]
    scene: Scene
    qpos: np.ndarray
    name: str = "interaction"

    @property
    def fps(self) -> float:
        return self.people[0].fps

    @property
    def seconds(self) -> float:
        return sum(p.seconds for p in self.people)

    @property
    def residuals(self) -> np.ndarray:
        return np.concatenate([p.residuals for p in self.people], axis=1)

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "frames": int(self.qpos.shape[0]),
            "fps": self.fps,
            "people": 2,
            "mean_residual_m": self.mean_residual,
            "p95_residual_m": self.p95_residual,
            "max_residual_m": self.max_residual,
            "seconds": self.seconds,
            "per_person": {n: p.to_dict() for n, p in zip(self.scene.names, self.people,
                                                           strict=True)},
        }


# ---------------------------------------------------------------------------
# Problem set-up
# ---------------------------------------------------------------------------


class _Problem:
    """The humanoid's tree with keypoint sites and sole corners as points."""

    def __init__(self, humanoid: Humanoid) -> None:
        m = humanoid.model
        self.humanoid = humanoid
        self.K = len(humanoid.keypoint_names)
        bodies = list(m.site_bodyid[humanoid.site_ids])
        offsets = list(m.site_pos[humanoid.site_ids])
        corners = []
        for g in range(m.ngeom):
            name = m.geom(g).name
            if m.geom_type[g] == 6 and (name.endswith("_foot") or name.endswith("_toes")):
                c, h = m.geom_pos[g], m.geom_size[g]
                # All 8 corners: a strongly bent toe can put its top edge lowest.
                for sx in (-1, 1):
                    for sy in (-1, 1):
                        for sz in (-1, 1):
                            corners.append((m.geom_bodyid[g],
                                            c + [sx * h[0], sy * h[1], sz * h[2]]))
        self.C = len(corners)
        bodies += [b for b, _ in corners]
        offsets += [o for _, o in corners]
        self.tree = HingeTree(m, np.array(bodies), np.array(offsets))
        self.body_id = {m.body(b).name: b for b in range(m.nbody)}
        self.site_offset = {k: m.site_pos[s].copy()
                            for k, s in zip(humanoid.keypoint_names, humanoid.site_ids,
                                            strict=True)}
        foot = [j for j, n in enumerate(humanoid.joint_names)
                if any(f"_{p}_" in n for p in ("thigh", "shin", "foot", "toes"))]
        self.foot_dofs = 6 + np.array(foot)
        # Front sole corners of each toe box, in the toe body's frame.
        self.toe_corners = {}
        for g in range(m.ngeom):
            if m.geom_type[g] == 6 and m.geom(g).name.endswith("_toes"):
                c, h = m.geom_pos[g], m.geom_size[g]
                self.toe_corners[int(m.geom_bodyid[g])] = np.array(
                    [c + [h[0], sy * h[1], -h[2]] for sy in (-1, 1)])
        d = humanoid.dims
        self.sole_height = {"ankle": d.ankle_height, "toe": d.toe_height}
        rest = d.rest_keypoints()
        kp = {k: rest[i] for i, k in enumerate(humanoid.keypoint_names)}
        self.rest_triangle = pelvis_frames(kp["pelvis"][None], kp["left_hip"][None],
                                           kp["right_hip"][None], kp["spine"][None])[0]
        #: Per side, the knee keypoint's sideways rest offset (metres, outwards).
        self.knee_lateral = {s: getattr(d.rest, f"{s}_knee_lateral") for s in ("left", "right")}


#: One problem per humanoid: its tree and point tables depend only on the
#: compiled model, so retargeting many clips onto one body builds them once.
_PROBLEMS: weakref.WeakKeyDictionary[Humanoid, _Problem] = weakref.WeakKeyDictionary()


def _problem(humanoid: Humanoid) -> _Problem:
    prob = _PROBLEMS.get(humanoid)
    if prob is None:
        prob = _PROBLEMS[humanoid] = _Problem(humanoid)
    return prob


#: Name of the joint :func:`with_derived_pelvis` adds.
DERIVED_PELVIS_JOINT = "pelvis (hips' midpoint)"


def with_derived_pelvis(motion: Motion) -> Motion:
    """``motion`` with a pelvis joint at its hips' midpoint when its skeleton maps both
    hips but no pelvis (OpenNI / NiTE, Florence 3D); ``motion`` itself otherwise.

    The added joint (:data:`DERIVED_PELVIS_JOINT`, a root of its own: no rotation channel
    moves it) holds ``(left_hip + right_hip) / 2`` on every frame, metres, and is mapped to
    the canonical pelvis; ``metadata["repairs"]`` gains a note naming the two joints.
    Rotations (T, J, 4) are dropped: the new joint has none.
    """
    sk = motion.skeleton
    c = sk.canonical
    if "pelvis" in c or not {"left_hip", "right_hip"} <= c.keys():
        return motion
    left, right = c["left_hip"], c["right_hip"]
    hips = motion.positions[:, [sk.index(left), sk.index(right)]].astype(np.float64)
    mid = hips.mean(axis=1, keepdims=True)
    width = np.median(np.linalg.norm(hips[:, 0] - hips[:, 1], axis=-1))
    skeleton = Skeleton(sk.name, (*sk.joint_names, DERIVED_PELVIS_JOINT), (*sk.parents, -1),
                        {**c, "pelvis": DERIVED_PELVIS_JOINT})
    note = (f"no pelvis joint: the pelvis keypoint is the midpoint of {left} and {right} on "
            f"every frame (hips {1000 * width:.0f} mm apart, median; simenv.body.retarget)")
    meta = dict(motion.metadata)
    meta["repairs"] = [*meta.get("repairs", []), note]
    positions = np.concatenate([motion.positions, mid.astype(motion.positions.dtype)], axis=1)
    return Motion(positions, motion.fps, skeleton, motion.name, meta)


def _canonical(motion: Motion) -> Motion:
    """``motion`` on the canonical keypoints; it must map the pelvis and both hips (pass it
    through :func:`with_derived_pelvis` first)."""
    canon = motion.to_canonical()
    missing = [k for k in REQUIRED_KEYPOINTS if k not in canon.skeleton.joint_names]
    if missing:
        source = motion.metadata.get("source")
        raise RetargetError(
            f"motion {motion.name!r} (skeleton {motion.skeleton.name!r}) lacks required "
            f"keypoint(s) {missing}; retargeting needs {list(REQUIRED_KEYPOINTS)} (with both "
            f"hips and no pelvis joint, the hips' midpoint is the pelvis). Its joints are "
            f"{', '.join(motion.skeleton.joint_names)}. Map them yourself: `simenv info "
            f"{source or 'FILE'} --write-joint-map map.toml` writes a map to edit, then pass "
            "--joint-map map.toml (Python: simenv.load(path, joint_map='map.toml'))",
            source=source, field=missing[0])
    return canon


# ---------------------------------------------------------------------------
# Analytic initial guess
# ---------------------------------------------------------------------------


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def _euler_angles(tree: HingeTree, b: int, R_local: np.ndarray) -> np.ndarray:
    """Hinge angles of body b reproducing R_local as well as its hinges can.

    Closed-form intrinsic Tait-Bryan decomposition R = R_i(a) R_j(b) R_k(c)
    along the body's hinge axes (completed with the missing axes when the body
    has fewer than three hinges; their angles are dropped), see
    :func:`simenv.body.ik.euler_branches`. Of the two solutions (a, b, c) and
    (a + pi, pi - b, c + pi) the one closer to the joint's limits is kept
    (for 3 hinges: chosen over the whole clip), then clipped.
    """
    hinges = tree.body_hinges[b]
    n = len(hinges)
    idx = [int(np.argmax(np.abs(tree.hinge_axis[j]))) for j in hinges]
    signs = np.sign(tree.hinge_axis[hinges, idx])
    idx += [i for i in range(3) if i not in idx]
    sols, viol, dropped = euler_branches(R_local, tuple(idx), signs, tree.lower[hinges],
                                         tree.upper[hinges])
    if n == 3:
        pick = _continuous_branch(sols, viol)
        return sols[np.arange(len(sols)), pick]
    # The dropped angles should vanish for a pose the joint can reach; the
    # arcsine of the middle angle hides which branch has them vanish.
    score = viol + dropped
    return np.where((score[:, 1] < score[:, 0])[:, None], sols[:, 1], sols[:, 0])


def _continuous_branch(sols: np.ndarray, viol: np.ndarray) -> np.ndarray:
    """Pick one of two Euler branches per frame (Viterbi over the whole clip).

    Cost = 10 * limit violation + |change of the angles| between frames, so the
    branch never flips from one frame to the next unless the limits demand it,
    and no single frame (the first, say) imposes its choice on the others.

    Args:
        sols: (T, 2, n) clipped solutions. viol: (T, 2) their limit violations.
    Returns:
        (T,) index of the chosen branch.
    """
    T = len(sols)
    unary = 10.0 * viol
    # Fast path: the per-frame best branch (ties: smaller angles) already moves
    # smoothly -- the usual case -- so no Viterbi is needed.
    size = np.abs(sols).sum(-1)
    greedy = np.where(np.abs(unary[:, 0] - unary[:, 1]) > 1e-9,
                      np.argmin(unary, axis=1), np.argmin(size, axis=1))
    path = sols[np.arange(T), greedy]
    if T == 1 or np.abs(np.diff(path, axis=0)).sum(-1).max() < 0.5:
        return greedy
    trans = np.abs(sols[1:, :, None, :] - sols[:-1, None, :, :]).sum(-1)  # (T-1, cur, prev)
    return viterbi2(unary, trans)


def _initial_guess(prob: _Problem, targets: dict[str, np.ndarray], T: int,
                   floor: np.ndarray | None = None,
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    tree = prob.tree
    has = targets.__contains__
    bid = prob.body_id
    tri = pelvis_frames(targets["pelvis"], targets["left_hip"], targets["right_hip"],
                        targets.get("spine"))
    root_rot = tri @ prob.rest_triangle.T
    root_pos = targets["pelvis"] - root_rot @ prob.site_offset["pelvis"]
    theta = np.zeros((T, tree.H))
    Rb = np.empty((T, tree.nb, 3, 3))
    xb = np.empty((T, tree.nb, 3))
    Rb[:, 1], xb[:, 1] = root_rot, root_pos
    if has("left_shoulder") and has("right_shoulder"):
        lateral = targets["left_shoulder"] - targets["right_shoulder"]
    else:
        lateral = targets["left_hip"] - targets["right_hip"]
    names = {b: n for n, b in bid.items()}
    y = np.array([0.0, 1.0, 0.0])
    for b in range(2, tree.nb):
        p = tree.parent[b]
        Rp = Rb[:, p]
        x = xb[:, p] + Rp @ tree.body_offset[b]
        if tree.body_has_rot[b]:  # the body's fixed frame rotation (e.g. the arm tilt)
            Rp = Rp @ tree.body_quat_rot[b]
        name = names[b]
        side, _, part = name.partition("_") if name.startswith(("left_", "right_")) \
            else ("", "", name)
        pre = f"{side}_" if side else ""
        child = {"lumbar": "spine", "thorax": "chest", "chest": "neck", "neck": "head",
                 "clavicle": f"{pre}shoulder", "upper_arm": f"{pre}elbow",
                 "forearm": f"{pre}wrist", "hand": f"{pre}hand", "thigh": f"{pre}knee",
                 "shin": f"{pre}ankle", "foot": f"{pre}toe"}.get(part)
        R = Rp
        shared = part == "lumbar" and prob.humanoid.dims.spine_on_pelvis
        if shared:
            # The spine site is on the pelvis and the thorax turns at the lumbar
            # joint: the lumbar takes half the turn towards the chest, the thorax
            # (next body, aimed at the chest) the rest.
            child = "chest"
        if child is not None and has(child) and len(tree.body_hinges[b]):
            v0 = prob.site_offset[child]
            if shared:
                v0 = v0 + tree.body_offset[bid["thorax"]]
            u = targets[child] - x
            ok = np.linalg.norm(v0) > 0.01
            if ok and part in ("lumbar", "thorax", "chest"):
                R = two_vector(v0, y, u, lateral)
                if shared:
                    R = Rp @ half_rotation(np.swapaxes(Rp, -1, -2) @ R)
            elif ok and part in ("upper_arm", "thigh"):
                nxt = {"upper_arm": f"{pre}wrist", "thigh": f"{pre}ankle"}[part]
                R = swing(Rp, v0, u)
                if has(nxt):
                    # Flexion-plane normal of the elbow / knee (hinge axis -y / +y).
                    bend = np.cross(_unit(u), _unit(targets[nxt] - targets[child]))
                    w0 = -y if part == "upper_arm" else y
                    strength = np.linalg.norm(bend, axis=-1)
                    if part == "thigh" and prob.knee_lateral[side]:
                        bend, strength = _knee_axis(u, targets[nxt] - targets[child],
                                                    prob.knee_lateral[side], side)
                    cue = bend
                    if part == "thigh" and has(f"{pre}toe"):
                        # Near-straight or fully folded knee (small sine): the foot
                        # points forward in the knee plane. Crossed with the shin it
                        # hangs from, not the thigh: a full squat's thigh runs along
                        # the foot, so that cross product has no direction.
                        foot = -np.cross(_unit(targets[nxt] - targets[child]),
                                         _unit(targets[f"{pre}toe"] - targets[f"{pre}ankle"]))
                        wgt = np.clip((strength - 0.1) / 0.2, 0, 1)[:, None]
                        cue = wgt * _unit(bend) + (1 - wgt) * _unit(foot)
                        strength = np.maximum(strength, np.linalg.norm(foot, axis=-1))
                    # Blend the plane cue with the minimal-swing twist as the limb
                    # straightens, so the twist never jumps between frames.
                    wgt = np.clip((strength - 0.02) / 0.1, 0, 1)[:, None]
                    cue = wgt * _unit(cue) + (1 - wgt) * (R @ w0)
                    R = two_vector(v0, w0, u, cue)
            elif ok:
                R = swing(Rp, v0, u)
        if len(tree.body_hinges[b]):
            th = _euler_angles(tree, b, np.swapaxes(Rp, -1, -2) @ R)
            theta[:, tree.body_hinges[b]] = th
            R = compose_hinges(Rp, tree.hinge_axis[tree.body_hinges[b]], th)
        if part == "toes" and floor is not None:
            th = _toe_lift(tree, b, Rp, x, prob.toe_corners[b], floor)
            theta[:, tree.body_hinges[b][0]] = th
            R = compose_hinges(Rp, tree.hinge_axis[tree.body_hinges[b][:1]], th[:, None])
        Rb[:, b], xb[:, b] = R, x
    return root_pos, root_rot, theta


def _knee_axis(thigh: np.ndarray, shin: np.ndarray, lateral: float, side: str
               ) -> tuple[np.ndarray, np.ndarray]:
    """The knee's hinge axis when the knee keypoint sits ``lateral`` metres outwards of
    the hip-ankle line along it (:attr:`simenv.body.humanoid.RestGeometry.left_knee_lateral`),
    and how well the pose shows it.

    The hinge J = K - s lateral n (s = +1 left, -1 right; n points left, the flexion
    axis) lies in the plane through the hip-ankle line normal to n, so the knee's
    displacement d from that line has the component ``s lateral`` along n:
    n = r unit(d) + sqrt(1 - r^2) unit(d x e), r = s lateral / |d|, e = unit(hip ->
    ankle), the root taken for flexion (without an offset: the bend plane's normal).
    The bend plane's normal alone would tilt n by the offset: a straight leg's sideways
    kink read as a knee bent sideways.

    Args:
        thigh: (T, 3) hip -> knee keypoint, metres. shin: (T, 3) knee -> ankle keypoint.
        lateral: the rest offset, metres, outwards positive. side: "left" or "right".
    Returns:
        ``(axis, strength)``: (T, 3) the axis, and (T,) the sine of the knee's flexion
        about it (the triangle hip - hinge - ankle), 0 where the leg is as straight as
        the offset or straighter (the axis is then the offset's direction, and the
        flexion plane is not seen).
    """
    sign = 1.0 if side == "left" else -1.0
    line = thigh + shin
    e = _unit(line)
    d = thigh - np.sum(thigh * e, axis=-1, keepdims=True) * e
    dist = np.linalg.norm(d, axis=-1)
    r = np.clip(sign * lateral / np.maximum(dist, 1e-12), -1.0, 1.0)
    axis = r[:, None] * _unit(d) + np.sqrt(1.0 - r * r)[:, None] * _unit(np.cross(d, e))
    a2 = lateral * lateral
    hinge = np.sqrt(np.maximum(dist**2 - a2, 0.0))
    upper = np.sqrt(np.maximum(np.sum(thigh * thigh, axis=-1) - a2, 1e-12))
    lower = np.sqrt(np.maximum(np.sum(shin * shin, axis=-1) - a2, 1e-12))
    strength = np.linalg.norm(line, axis=-1) * hinge / (upper * lower)
    return axis, np.clip(strength, 0.0, 1.0)


def _toe_lift(tree: HingeTree, b: int, Rp: np.ndarray, x: np.ndarray, corners: np.ndarray,
              floor: np.ndarray) -> np.ndarray:
    """Smallest toe extension keeping the toe box's front sole corners above the
    floor: each corner turns about the hinge axis u as
    z(phi) = z_par + p cos(phi) + q sin(phi); solve z(phi) = floor in closed form."""
    j = tree.body_hinges[b][0]
    u = Rp @ tree.hinge_axis[j]
    need = np.zeros(len(x))
    for c in corners:
        r = Rp @ c
        par = np.sum(r * u, axis=1, keepdims=True) * u
        perp = r - par
        p, q = perp[:, 2], np.cross(u, perp)[:, 2]
        d = floor - x[:, 2] - par[:, 2]
        amp = np.hypot(p, q)
        base = np.arctan2(q, p)
        phi = base + np.arccos(np.clip(d / np.maximum(amp, 1e-12), -1, 1))
        phi = (phi + np.pi) % (2 * np.pi) - np.pi
        below = p < d  # at phi = 0 the corner is under the floor
        need = np.maximum(need, np.where(below, np.maximum(phi, 0.0), 0.0))
    return np.clip(need, tree.lower[j], tree.upper[j])


# ---------------------------------------------------------------------------
# Batched projected Levenberg-Marquardt
# ---------------------------------------------------------------------------


def _neighbour_mean(a: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """(n, ...) mean of the two neighbours of each frame ``idx`` of ``a`` (T, ...);
    the end frames take their one neighbour, a one-frame clip itself."""
    T = len(a)
    before = np.where(idx == 0, min(1, T - 1), idx - 1)
    after = np.where(idx == T - 1, max(T - 2, 0), idx + 1)
    return 0.5 * (a[before] + a[after])


def _solve(prob: _Problem, targets: np.ndarray, weights: np.ndarray, floor: np.ndarray | None,
           state: tuple[np.ndarray, np.ndarray, np.ndarray], active: np.ndarray,
           dofs: np.ndarray, opts: RetargetOptions) -> int:
    """Refine ``state`` (root_pos, root_rot, theta; updated in place) on the
    frames ``active`` over the tangent coordinates ``dofs``
    (:meth:`simenv.body.ik.HingeTree.fit_iteration` per iteration). Returns the
    number of iterations run."""
    root_pos, root_rot, theta = state
    fit = PointFit(reg=opts.reg, smooth=opts.smooth, floor_weight=opts.floor_weight,
                   max_step=opts.max_step, tol=opts.tol, step_tol=opts.step_tol)
    mu = np.full(len(theta), 1e-3)
    active = active.copy()
    iters = 0
    for _ in range(opts.iterations):
        idx = np.flatnonzero(active)
        if not len(idx):
            break
        if _DEBUG:
            print("active", len(idx))
        iters += 1
        # Jacobi sweep: every frame's smoothness target comes from the
        # previous iterate, so the frames are independent within an iteration.
        prob.tree.fit_iteration(idx, state, _neighbour_mean(root_pos, idx),
                                _neighbour_mean(theta, idx), mu, active, targets, weights,
                                floor, dofs, fit)
    return iters


# ---------------------------------------------------------------------------
# Public API
# ---------------------------------------------------------------------------


def _floor_levels(prob: _Problem, tg: dict[str, np.ndarray], T: int) -> np.ndarray:
    """Per-frame lowest allowed sole height: 0, or lower where the data's own
    ankles/toes imply a sole below the floor."""
    level = np.zeros(T)
    for side in ("left", "right"):
        for key in ("ankle", "toe"):
            k = f"{side}_{key}"
            if k in tg:
                level = np.minimum(level, tg[k][:, 2] - prob.sole_height[key])
    return level


def retarget_motion(motion: Motion, humanoid: Humanoid | None = None,
                    options: RetargetOptions | None = None) -> RetargetResult:
    """Retarget one person (see :func:`retarget`)."""
    opts = options or RetargetOptions()
    derived = with_derived_pelvis(motion)
    repairs = [] if derived is motion else derived.metadata["repairs"][-1:]
    motion = derived
    canon = _canonical(motion)
    t0 = time.perf_counter()
    notes: list[str] = []
    if humanoid is None:
        humanoid = fit_humanoid(motion)
        notes.extend(humanoid.dims.notes)
    prob = _problem(humanoid)
    names = canon.skeleton.joint_names
    T = canon.num_frames
    pos = canon.positions.astype(np.float64)
    tg = {k: pos[:, i] for i, k in enumerate(names)}
    order = list(humanoid.keypoint_names)
    targets = np.zeros((T, prob.K, 3))
    weights = np.zeros(prob.K)
    for k, i in ((k, order.index(k)) for k in names):
        targets[:, i] = tg[k]
        weights[i] = 1.0
    floor = _floor_levels(prob, tg, T) if opts.floor else None
    root_pos, root_rot, theta = state = _initial_guess(prob, tg, T, floor)
    tree = prob.tree
    # Stage 1: all coordinates, keypoints only, on the frames the analytic
    # guess does not already solve.
    pts = tree.points(*state)
    err = np.linalg.norm(pts[:, :prob.K] - targets, axis=-1) * (weights > 0)
    stage1 = err.max(axis=1) > opts.accept
    iters = _solve(prob, targets, weights, None, state, stage1, np.arange(tree.nv), opts)
    # Only the frames a stage worked on have moved: FK of those alone.
    pts[stage1] = tree.points(root_pos[stage1], root_rot[stage1], theta[stage1])
    # Stage 2: the floor. Only the ankle and toe joints move, on the frames
    # whose soles are below the floor level.
    if floor is not None:
        below = (pts[:, prob.K:, 2] < floor[:, None] - 1e-6).any(axis=1)
        if below.any():
            iters += _solve(prob, targets, weights, floor, state, below, prob.foot_dofs, opts)
            pts[below] = tree.points(root_pos[below], root_rot[below], theta[below])
    if not (np.isfinite(root_pos).all() and np.isfinite(theta).all()):
        bad = np.flatnonzero(~(np.isfinite(theta).all(1) & np.isfinite(root_pos).all(1)))
        raise RetargetError("solver diverged (non-finite configuration)", frame=int(bad[0]))
    qpos = tree.join_qpos(root_pos, root_rot, theta)
    seconds = time.perf_counter() - t0
    sel = [order.index(k) for k in names]
    res = np.linalg.norm(pts[:, sel] - targets[:, sel], axis=-1).astype(np.float32)
    return RetargetResult(qpos=qpos, residuals=res, keypoint_names=tuple(names),
                          targets=pos.astype(np.float32), humanoid=humanoid, fps=motion.fps,
                          seconds=seconds, iterations=iters, name=motion.name, notes=notes,
                          repairs=repairs)


def retarget(motion: Motion | Interaction, humanoid: Humanoid | None = None,
             **options: Any) -> RetargetResult | InteractionRetargetResult:
    """Retarget a motion (or both people of an interaction) onto MuJoCo humanoids.

    Args:
        motion: a :class:`Motion` with at least the canonical hips and pelvis (a
            skeleton with both hips and no pelvis gets one at their midpoint,
            :func:`with_derived_pelvis`), or an :class:`Interaction` (each person gets a
            body fitted to them).
        humanoid: the body to use for a single motion; default: fitted to the
            motion with :func:`simenv.body.humanoid.fit_humanoid`.
        **options: fields of :class:`RetargetOptions` (e.g. ``iterations=8``).

    Returns:
        :class:`RetargetResult`, or :class:`InteractionRetargetResult` whose
        scene names the people ``actor`` and ``reactor``.
    """
    try:
        opts = RetargetOptions(**options)
    except TypeError as exc:
        raise RetargetError(f"unknown retarget option: {exc}") from None
    if isinstance(motion, Interaction):
        if humanoid is not None:
            raise RetargetError("an Interaction gets one fitted body per person; do not pass "
                                "humanoid=")
        people = tuple(retarget_motion(m, None, opts) for m in motion.people)
        scene = build_scene([p.humanoid for p in people], ["actor", "reactor"])
        qpos = scene.combine_qpos([p.qpos for p in people])
        return InteractionRetargetResult(people=people, scene=scene, qpos=qpos,
                                         name=motion.name)
    if not isinstance(motion, Motion):
        raise RetargetError(f"retarget expects a Motion or Interaction; got "
                            f"{type(motion).__name__}")
    return retarget_motion(motion, humanoid, opts)
