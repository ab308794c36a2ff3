"""Build the room agent's walking primitives from real motion capture
(``assets/walk-primitives/mocap_walk.json``, read by :mod:`simenv.agents.mocap_walk`).

What it does, deterministically (seeded planner, one fixed clip):

1. retargets the bundled CMU 02_01 walk (real motion capture, 1.1 m/s) onto the room
   agent's body (the ``discomfort`` scenario's agent);
2. makes it an endless straight walk: one gait cycle, from a left mid-swing (the ankles
   level along the walk, the left one moving forward) to the next, repeated, its hinge
   angles' and the root's small mismatch between the cycle's ends spread linearly over
   the cycle and its heading drift removed (:func:`looped_clip`);
3. writes the reference one tracking run follows (:func:`composite_reference`): the
   standing pose (arms hanging as the room's stepping gait holds them), a blend into the
   clip's left mid-swing pose, the clip accelerated from rest to its recorded pace, gait
   cycles (straight, straight, a left bend, straight, a right bend, straight: a bend is
   the walk's root path mapped onto a curve whose curvature rises and falls within the
   cycle, turning :data:`TURN_DEG`), the clip slowed to rest at a left mid-swing and a
   blend back to standing;
4. tracks it with the unassisted sampling MPC (:class:`simenv.control.TrackingMPC`, its
   default settings; nothing acts on the root) and records the state and the servo targets
   of every physics step; a run whose body error passes 0.5 m (the tracker's failure
   distance) is retried with the next seed;
5. cuts the tracked run at the cycle boundaries into the primitives ``start`` (standing
   to the end of the first full cycle), ``start_short``, ``straight``, ``half_a``,
   ``half_b``, ``left`` and the half cycles ``half_c`` and ``half_d`` that chain them in
   the run's order (:data:`CUTS`: the walk joins pieces only where one starts on the
   other's last tracked state);
6. tracks one stop after each of them (:data:`STOP_AFTER`, :func:`track_stop`: from its
   last tracked state, the same planner and seed), and gives every primitive
   time-varying feedback gains: discrete LQR (:func:`lqr_gains`) on
   ``mujoco.mjd_transitionFD`` linearisations about the tracked states;
7. with ``--close PIECE ...``, tracks a *closing* stop after those pieces
   (:data:`CLOSE_AFTER`, :func:`track_close`): the gait to the frame nearest the start of
   real motion capture of a person coming to rest with a short last step (CMU 19_01,
   :data:`CLOSE_CLIP`), a cross-fade into it, the clip to rest, then a blend onto the
   stepping gait's upright stance over the same feet (:func:`gait_stance`): the walk ends
   with the feet 0.1 m apart along the walk instead of 0.45-0.5 m, the pelvis upright and
   the feet flat, a stance the stepping gait starts from (without the blend the tracked
   body ended on the ball of the rear foot, its pelvis tilted 12-32 deg, and the stepping
   gait fell from there, measured). A halt or closing stop the tracker fails, or whose
   error passes :data:`KEEP_MAX_ERR_M`, is left out.

Usage::

    python benchmarks/build_mocap_walk.py [--out assets/walk-primitives/mocap_walk.json]
        [--seed 0] [--tracked /tmp/mw_tracked.npz] [--close start_short start]
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np

import simenv
from simenv.agents.gait import ARM_ABD, quat_yaw
from simenv.agents.reach import hinge_adr, min_jerk
from simenv.assets import WALK, asset_path
from simenv.body.humanoid import Humanoid
from simenv.body.retarget import RetargetResult, retarget_motion
from simenv.control import MPCConfig, TrackingMPC, TrackingReference, fast_planner
from simenv.core.config import shared_data_root
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS
from simenv.plausibility.dynamics import dynamics_settings
from simenv.room.room import Room

#: Heading change of one bend cycle, deg.
TURN_DEG = 15.0
#: Reference phases, s: standing still, blend into the clip's pose, speed-up from rest,
#: slow-down to rest, standing still at the end (in the clip's double support, feet in
#: stride: blending from a mid-swing pose to feet side by side fell in the tracker, seed 0,
#: and in the replay, measured).
HOLD_S, BLEND_S, ACCEL_S = 0.3, 1.0, 0.8
DECEL_S, END_S = 0.7, 1.2
#: The cycles between the start and the stop: 0 straight, +1 left bend, -1 right bend.
CYCLES = (0, 0, 1, 0)
#: Gaussian smoothing of the looped cycle's hinges, frames (standard deviation).
SMOOTH_FRAMES = 4
#: The tracker's failure distance (mean keypoint error), m.
FAIL_M = 0.5
#: LQR weights: per unit of state error (rad, m; rad/s, m/s) squared, and per rad^2 of
#: servo target.
Q_POS, Q_ROOT, Q_VEL, R_CTRL = 100.0, 500.0, 1.0, 1.0
_STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS


def _quat_z(yaw: float) -> np.ndarray:
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.zeros(4)
    mujoco.mju_mulQuat(out, a, b)
    return out


def agent_body() -> Humanoid:
    """The room agent's standalone humanoid (``discomfort`` scenario)."""
    return Room("discomfort").agent


def _rotate_root(q: np.ndarray, yaw: float, about: np.ndarray) -> np.ndarray:
    """(nq,) ``q`` turned by ``yaw`` rad about the vertical through ``about`` (2,)."""
    c, s = np.cos(yaw), np.sin(yaw)
    out = q.copy()
    d = q[:2] - about
    out[:2] = about + [c * d[0] - s * d[1], s * d[0] + c * d[1]]
    out[3:7] = _qmul(_quat_z(yaw), q[3:7])
    return out


def left_midswings(h: Humanoid, q: np.ndarray) -> np.ndarray:
    """Frames where the left ankle passes the right one moving forward (along the clip's
    overall direction), (M,)."""
    kp = h.keypoints(q)
    names = list(h.keypoint_names)
    la, ra = kp[:, names.index("left_ankle"), :2], kp[:, names.index("right_ankle"), :2]
    fwd = q[-1, :2] - q[0, :2]
    fwd /= np.linalg.norm(fwd)
    d = (la - ra) @ fwd
    return np.flatnonzero((d[:-1] < 0) & (d[1:] >= 0)) + 1


def looped_clip(h: Humanoid, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One gait cycle of the retargeted clip ``q`` (T, nq) made periodic (module
    docstring, 2), walking along +x from the origin: the cycle's frames (P, nq) and the
    root's advance per cycle (2,), m."""
    m = left_midswings(h, q)
    a, b = int(m[0]), int(m[1])
    cyc = q[a:b + 1].copy()
    P = b - a
    ramp = np.arange(P + 1)[:, None] / P
    # Heading drift over the cycle removed (turned back about the cycle's first root).
    drift = quat_yaw(cyc[-1, 3:7]) - quat_yaw(cyc[0, 3:7])
    for i in range(P + 1):
        cyc[i] = _rotate_root(cyc[i], -drift * i / P, cyc[0, :2])
    # Hinges, root height and tilt: the end's mismatch spread over the cycle.
    e = cyc[-1, 7:] - cyc[0, 7:]
    cyc[:, 7:] -= ramp * e
    cyc[:, 2] -= ramp[:, 0] * (cyc[-1, 2] - cyc[0, 2])
    adv = cyc[-1, :2] - cyc[0, :2]
    yaw = -np.arctan2(adv[1], adv[0])
    for i in range(P + 1):
        cyc[i] = _rotate_root(cyc[i], yaw, cyc[0, :2])
    cyc[:, :2] -= cyc[0, :2]
    adv = cyc[-1, :2] - cyc[0, :2]
    cyc = cyc[:-1]
    # The retargeted hinges jump between IK branches from frame to frame (the spine's
    # split of a bend, the neck: up to 1.9 rad in one frame on 02_01): smoothed round the
    # cycle, as the root's height and its sway about the straight advance.
    kernel = np.exp(-0.5 * (np.arange(-4 * SMOOTH_FRAMES, 4 * SMOOTH_FRAMES + 1)
                            / SMOOTH_FRAMES) ** 2)
    kernel /= kernel.sum()
    line = np.arange(P)[:, None] / P * adv
    cols = [0, 1, 2, *range(7, cyc.shape[1])]
    x = cyc[:, cols].copy()
    x[:, :2] -= line
    pad = len(kernel) // 2
    wrapped = np.concatenate([x[-pad:], x, x[:pad]])
    x = np.stack([np.convolve(wrapped[:, c], kernel, mode="valid") for c in range(x.shape[1])],
                 axis=1)
    x[:, :2] += line
    cyc[:, cols] = x
    return cyc, adv


def standing_pose(h: Humanoid) -> np.ndarray:
    """(nq,) the room's standing pose: rest pose, arms hanging (``ARM_ABD``)."""
    q = h.default_qpos()
    for side in ("left", "right"):
        q[hinge_adr(h, f"{side}_upper_arm_abd")] = ARM_ABD
    return q


def _place_standing(h: Humanoid, stand: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """``stand`` facing ``pose``'s heading with its right ankle where ``pose`` has it."""
    q = stand.copy()
    yaw = quat_yaw(pose[3:7])
    q[3:7] = _quat_z(yaw)
    q[:2] = 0.0
    names = list(h.keypoint_names)
    ra = names.index("right_ankle")
    q[:2] = h.keypoints(pose)[ra, :2] - h.keypoints(q)[ra, :2]
    return q


def _blend(a: np.ndarray, b: np.ndarray, w: float) -> np.ndarray:
    out = (1 - w) * a + w * b
    qa, qb = a[3:7], b[3:7]
    if qa @ qb < 0:
        qb = -qb
    out[3:7] = (1 - w) * qa + w * qb
    out[3:7] /= np.linalg.norm(out[3:7])
    return out


def _bend(xs: np.ndarray, turns: list[tuple[float, float, float]]
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Heading theta(s) and the curve A(s) (N, 2) of the bent path at arc lengths ``xs``
    (sorted), for bends (s0, length, turn rad) whose curvature is
    ``kappa = 2 turn / length sin^2(pi (s - s0) / length)``."""
    grid = np.linspace(xs.min() - 1e-6, xs.max() + 1e-6, 20000)
    kappa = np.zeros_like(grid)
    for s0, length, turn in turns:
        inside = (grid >= s0) & (grid <= s0 + length)
        kappa[inside] += 2 * turn / length * np.sin(np.pi * (grid[inside] - s0) / length) ** 2
    ds = np.diff(grid, prepend=grid[0])
    theta = np.cumsum(kappa * ds)
    pts = np.cumsum(np.stack([np.cos(theta), np.sin(theta)], 1) * ds[:, None], axis=0)
    pts += [grid[0], 0.0]
    th = np.interp(xs, grid, theta)
    return th, np.stack([np.interp(xs, grid, pts[:, 0]), np.interp(xs, grid, pts[:, 1])], 1), \
        np.interp(xs, grid, kappa)


def double_support(h: Humanoid, cyc: np.ndarray) -> int:
    """Frame of the looped cycle (after its left mid-swing, before the right one) where
    both ankles are lowest: the left foot down ahead of the right."""
    names = list(h.keypoint_names)
    kp = h.keypoints(cyc[: len(cyc) // 2])
    z = kp[:, names.index("left_ankle"), 2] + kp[:, names.index("right_ankle"), 2]
    return int(np.argmin(z))


def clip_at(cyc: np.ndarray, adv: np.ndarray, tau: float) -> np.ndarray:
    """(nq,) the looped clip (cycle ``cyc`` (P, nq), advancing ``adv`` (2,) m a cycle) at
    (fractional) frame ``tau``, walking straight."""
    P = len(cyc)
    k = int(np.floor(tau))
    c, f = divmod(k, P)
    c1, f1 = divmod(k + 1, P)
    a = cyc[f].copy()
    a[:2] += c * adv
    b = cyc[f1].copy()
    b[:2] += c1 * adv
    return _blend(a, b, tau - k)


def composite_reference(h: Humanoid, cyc: np.ndarray, adv: np.ndarray, fps: float,
                        cycles: tuple[int, ...] = CYCLES) -> tuple[np.ndarray, dict]:
    """The reference (T, nq) at ``fps`` (module docstring, 3) and the times (s) of the
    cycle boundaries (``cycle_k`` for the start of ``CYCLES[k]``, ``end``), and ``taus``:
    (T,) each frame's place in the looped clip, in cycles (0 at the first left
    mid-swing)."""
    P = len(cyc)

    def clip(tau: float) -> np.ndarray:
        return clip_at(cyc, adv, tau)

    stand = standing_pose(h)
    start_stand = _place_standing(h, stand, clip(0.0))
    frames: list[np.ndarray] = []
    taus: list[float] = []
    dt = 1.0 / fps
    for _ in np.arange(0, HOLD_S, dt):
        frames.append(start_stand)
        taus.append(0.0)
    for t in np.arange(0, BLEND_S, dt):
        frames.append(_blend(start_stand, clip(0.0), min_jerk(t / BLEND_S)))
        taus.append(0.0)
    tau = 0.0
    times: dict[str, float] = {}
    for t in np.arange(0, ACCEL_S, dt):  # speed 0 -> 1 (min-jerk profile)
        tau += fps * dt * min_jerk(t / ACCEL_S)
        frames.append(clip(tau))
        taus.append(tau)
    n_full = len(cycles) + 1
    decel_frames = fps * DECEL_S / 2
    # The walk ends at rest in the double support after the right foot's last swing.
    end_tau = (n_full + 0.5) * P + double_support(h, cyc)
    while tau + 1 < end_tau - decel_frames:
        tau += 1
        frames.append(clip(tau))
        taus.append(tau)
    for t in np.arange(0, DECEL_S, dt):  # speed 1 -> 0
        tau += fps * dt * (1 - min_jerk(t / DECEL_S))
        frames.append(clip(tau))
        taus.append(tau)
    last = clip(tau)
    for _ in np.arange(0, END_S, dt):
        frames.append(last)
        taus.append(tau)
    q = np.array(frames)
    taus_a = np.array(taus)
    # Cycle boundaries (tau = k P): the first full cycle starts at P.
    for k in range(1, n_full + 1):
        i = int(np.searchsorted(taus_a, k * P))
        times[f"cycle_{k - 1}"] = i / fps
    times["end"] = (len(q) - 1) / fps
    times["taus"] = taus_a / P  # type: ignore[assignment]
    # Bends: the root path mapped onto a curve (arc length = the straight x).
    xs = q[:, 0].copy()
    order = np.argsort(xs, kind="stable")
    turns = []
    for k, sign in enumerate(cycles):
        if sign:
            s0 = float(cyc[0, 0] + (k + 1) * adv[0])
            turns.append((s0, float(adv[0]), sign * np.deg2rad(TURN_DEG)))
    th, pts, _ = _bend(xs[order], turns)
    theta = np.empty_like(xs)
    theta[order] = th
    curve = np.empty((len(xs), 2))
    curve[order] = pts
    for i in range(len(q)):
        y = q[i, 1]
        q[i, :2] = curve[i] + y * np.array([-np.sin(theta[i]), np.cos(theta[i])])
        q[i, 3:7] = _qmul(_quat_z(theta[i]), q[i, 3:7])
    return q, times


def settled_start(h: Humanoid, q0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The agent's state (qpos, qvel) standing where ``q0`` puts its pelvis, facing its
    heading, as :func:`simenv.agents.gait.standing_agent` leaves it in the room."""
    from simenv.agents.gait import standing_agent

    room = Room("discomfort")
    data = standing_agent(room, q0[:2], quat_yaw(q0[3:7]))
    return data.qpos[room.agent_qpos].copy(), data.qvel[room.agent_qvel].copy()


def track_reference(h: Humanoid, base: RetargetResult, q: np.ndarray, fps: float,
                    seed: int, log: Path | None = None, fast: bool = False,
                    state: tuple[np.ndarray, np.ndarray] | None = None
                    ) -> dict[str, np.ndarray]:
    """Track ``q`` with the MPC (module docstring, 4); per physics step ``qpos``, ``qvel``,
    ``ctrl`` (the targets applied at that step), ``err`` (mean keypoint error at the
    frames, m) and ``ok`` (whether it stayed within :data:`FAIL_M`). From ``state``
    (qpos (nq,), qvel (nv,)) when given, else from the room's standing body; ``fast``:
    :func:`simenv.control.fast_planner`'s search."""
    T = len(q)
    K = len(h.keypoint_names)
    result = replace(base, qpos=q, fps=fps, residuals=np.zeros((T, K), np.float32),
                     targets=np.zeros((T, K, 3), np.float32), name="mocap_walk_reference")
    ref = TrackingReference.from_retarget(result, h.model,
                                          dynamics_settings(DEFAULT_BODY_THRESHOLDS), 60.0)
    cfg = fast_planner(MPCConfig(seed=seed)) if fast else MPCConfig(seed=seed)
    qs, vs, us, errs = [], [], [], []
    ok = True
    t0 = time.perf_counter()
    with TrackingMPC(h, ref, cfg) as mpc:
        model = mpc.model
        data = mujoco.MjData(model)
        mpc.reset(data)
        # From the standing body the room gives (the rest pose balanced 1 s), not from the
        # reference's first pose: replayed from the latter, the walk fell from the former.
        data.qpos[:], data.qvel[:] = settled_start(h, q[0]) if state is None else state
        mujoco.mj_forward(model, data)
        for s in range(ref.n_steps):
            u = mpc.control(data, s)
            qs.append(data.qpos.copy())
            vs.append(data.qvel.copy())
            us.append(u.copy())
            data.ctrl[:] = u
            mujoco.mj_step(model, data)
            if (s + 1) % 50 == 0:
                i = min(int(round((s + 1) * ref.dt * fps)), ref.n_frames - 1)
                err = float(np.linalg.norm(data.site_xpos[h.site_ids] - ref.frame_keypoints[i],
                                           axis=-1).mean())
                errs.append(err)
                if log is not None and (s + 1) % 500 == 0:
                    with log.open("a") as f:
                        f.write(f"seed {seed} t {(s + 1) * ref.dt:.2f}/{ref.n_steps * ref.dt:.2f}"
                                f" err {err:.3f} pelvis {data.qpos[2]:.2f} wall "
                                f"{time.perf_counter() - t0:.0f}\n")
                if err > FAIL_M or not np.isfinite(data.qpos).all():
                    ok = False
                    break
    return {"qpos": np.array(qs), "qvel": np.array(vs), "ctrl": np.array(us),
            "err": np.array(errs), "ok": np.array(ok), "wall_s": np.array(time.perf_counter() - t0),
            "dt": np.array(ref.dt)}


def lqr_gains(model: mujoco.MjModel, qpos: np.ndarray, qvel: np.ndarray, ctrl: np.ndarray,
              fb: np.ndarray, stride: int) -> np.ndarray:
    """Time-varying LQR gains (N // stride + 1, len(fb), 2 nv) about the tracked states (N
    steps) for the servos ``fb``: ``u = ctrl - K dx``, ``dx`` = (``mj_differentiatePos``
    from the reference to the state, velocity minus the reference's). The linearisation
    (``mjd_transitionFD``, centred) of ``stride`` physics steps with the targets held is
    the product of the per-step ones; the Riccati recursion runs backwards from the
    cost-to-go ``Q`` at the run's end (standing still)."""
    nv = model.nv
    n = len(qpos)
    data = mujoco.MjData(model)
    A = np.zeros((2 * nv, 2 * nv))
    B = np.zeros((2 * nv, model.nu))
    As, Bs = [], []
    for i in range(0, n, stride):
        Ak, Bk = np.eye(2 * nv), np.zeros((2 * nv, len(fb)))
        for j in range(i, min(i + stride, n)):
            data.qpos[:], data.qvel[:], data.ctrl[:] = qpos[j], qvel[j], ctrl[j]
            mujoco.mj_forward(model, data)
            mujoco.mjd_transitionFD(model, data, 1e-6, 1, A, B, None, None)
            Ak = A @ Ak
            Bk = A @ Bk + B[:, fb]  # the target is held over the stride
        As.append(Ak)
        Bs.append(Bk)
    Q = np.diag(np.concatenate([np.full(6, Q_ROOT), np.full(nv - 6, Q_POS),
                                np.full(nv, Q_VEL)]))
    # Where on the floor the body is and its heading are the composition's business; its
    # height is the contacts'.
    Q[0, 0] = Q[1, 1] = Q[2, 2] = Q[5, 5] = 0.0
    Rm = R_CTRL * np.eye(len(fb)) * stride
    S = Q.copy()
    gains = [np.zeros((len(fb), 2 * nv))] * len(As)
    for k in reversed(range(len(As))):
        Ak, Bk = As[k], Bs[k]
        BS = Bk.T @ S
        Kk = np.linalg.solve(Rm + BS @ Bk, BS @ Ak)
        S = Q * stride + Ak.T @ S @ (Ak - Bk @ Kk)
        S = 0.5 * (S + S.T)
        gains[k] = Kk
    return np.array(gains)


#: The primitives cut from the tracked run: name -> (start, end) in cycles of the looped
#: clip (``None``: the run's first or last step), the phases they join at (the foot at
#: mid-swing: whole cycles start at a left one). ``CYCLES``: [1, 2) and [2, 3) straight,
#: [3, 4) the left bend, [4, 5) straight, the slow-down ends in the double support after
#: 5.5; the right bend is the left one mirrored
#: (:mod:`simenv.agents.mocap_walk`), as are the primitives joining at the other foot.
#: ``half_c`` ([1, 1.5)) and ``half_d`` ([2.5, 3)) chain the others in the run's order:
#: start -> half_c -> half_b -> half_a or straight -> half_d or left (pieces of different
#: cycles at the same phase differ by 0.12-0.2 rad rms and joined there fell in 4 of 8
#: composed walks, measured).
CUTS: dict[str, tuple[float | None, float | None, str, str]] = {
    "start": (None, 1.0, "stand", "left"),
    "start_short": (None, 0.5, "stand", "right"),
    "straight": (2.0, 3.0, "left", "left"),
    "half_a": (2.0, 2.5, "left", "right"),
    "half_b": (1.5, 2.0, "right", "left"),
    "left": (3.0, 4.0, "left", "left"),
    "half_c": (1.0, 1.5, "left", "right"),
    "half_d": (2.5, 3.0, "right", "left"),
}
#: The stops: one tracking run after each walking primitive that ends where no other
#: stop starts (``half_d`` ends on ``straight``'s last state), from its last tracked
#: state, of the reference's tail from the same gait phase (cycle 5.0 after a left
#: mid-swing, 4.5 after a right one) to the end (the slow-down and standing). Cut from the
#: main run after one kind of piece only, the stop fell after every other kind (and,
#: entered at a seam, after that kind too): 8 of 8 composed walks on open floor fell in
#: the stop (measured).
STOP_AFTER = ("start", "start_short", "straight", "half_a", "half_b", "left", "half_c")
#: Physics steps between stored steps (and per feedback gain).
STRIDE = 5


def _placed_on(h: Humanoid, tail: np.ndarray, at: np.ndarray) -> np.ndarray:
    """``tail`` (T, nq) turned about the vertical and shifted so that its first frame's leg
    keypoints lie on those of the pose ``at`` (nq,) (:func:`simenv.agents.mocap_walk.fit_frame`);
    changes ``tail`` in place and returns it."""
    from simenv.agents.mocap_walk import ANCHOR_KEYPOINTS, fit_frame

    idx = [list(h.keypoint_names).index(k) for k in ANCHOR_KEYPOINTS]
    psi, off = fit_frame(h.keypoints(tail[0])[idx, :2], h.keypoints(at)[idx, :2])
    c, sn = np.cos(psi), np.sin(psi)
    tail[:, :2] = tail[:, :2] @ np.array([[c, sn], [-sn, c]]) + off
    for i in range(len(tail)):
        tail[i, 3:7] = _qmul(_quat_z(psi), tail[i, 3:7])
    return tail


def stop_reference(h: Humanoid, q: np.ndarray, taus: np.ndarray, phase: str,
                   at: np.ndarray) -> np.ndarray:
    """(T, nq) the tail of the reference ``q`` (its frames' places ``taus`` in cycles)
    from the last gait phase ``phase`` before the slow-down, placed on the floor (turned
    about the vertical and shifted, :func:`simenv.agents.mocap_walk.fit_frame` on the
    legs' keypoints) onto the pose ``at`` (nq,)."""
    i0 = int(np.searchsorted(taus, 5.0 if phase == "left" else 4.5))
    tail = q[i0:].copy()
    return _placed_on(h, tail, at)


def track_stop(h: Humanoid, base: RetargetResult, q: np.ndarray, taus: np.ndarray,
               fps: float, run: dict[str, np.ndarray], after: str, seed: int, tries: int,
               log: Path | None) -> dict[str, np.ndarray]:
    """The tracked stop following primitive ``after`` of the main ``run`` (:data:`STOP_AFTER`):
    from its last tracked state, the reference's tail (:func:`stop_reference`); retried
    with the next seed while the tracker fails."""
    return _track_tail_after(h, base, fps, taus, run, after, seed, tries, log,
                             lambda at: stop_reference(h, q, taus, CUTS[after][3], at))


def _track_tail_after(h: Humanoid, base: RetargetResult, fps: float, taus: np.ndarray,
                      run: dict[str, np.ndarray], after: str, seed: int, tries: int,
                      log: Path | None, tail_on: Callable[[np.ndarray], np.ndarray]
                      ) -> dict[str, np.ndarray]:
    """The tracked tail ``tail_on(at)`` (T, nq) from the main ``run``'s last tracked state
    of primitive ``after`` (its pose ``at``); retried with the next seed while the tracker
    fails."""
    dt = float(run["dt"])
    step = int(round(int(np.searchsorted(taus, CUTS[after][1])) / fps / dt / STRIDE)) * STRIDE
    state = (run["qpos"][step].copy(), run["qvel"][step].copy())
    tail = tail_on(state[0])
    for s in range(seed, seed + tries):
        out = track_reference(h, base, tail, fps, s, log, state=state)
        out["seed"] = np.array(s)
        if bool(out["ok"]):
            break
    return out


def halt_reference(h: Humanoid, cyc: np.ndarray, adv: np.ndarray, fps: float,
                   at: np.ndarray) -> np.ndarray:
    """(T, nq) a stop from a right mid-swing as short as those from a left one: the looped
    clip from its right mid-swing (frame P / 2) slowed to rest (minimum-jerk speed over
    :data:`DECEL_S`) in the double support as the left foot lands after its swing (frame
    P + :func:`double_support`), then :data:`END_S` still; placed on the floor onto the
    pose ``at`` (nq,) as :func:`stop_reference` places its tail. The stops of
    :data:`STOP_AFTER` from a right mid-swing walk one more cycle (their reference comes to
    rest after a right swing); coming to rest as the right foot itself lands (0.15 s after
    mid-swing) would stop 1.2 m/s within 0.3 s."""
    P = len(cyc)
    tau0 = 0.5 * P
    end_tau = tau0 + 0.5 * P + double_support(h, cyc)
    decel_s = min(DECEL_S, 2.0 * (end_tau - tau0) / fps)
    tau, frames, dt = tau0, [], 1.0 / fps
    while tau + 1 < end_tau - fps * decel_s / 2:
        frames.append(clip_at(cyc, adv, tau))
        tau += 1
    for t in np.arange(0, decel_s, dt):
        frames.append(clip_at(cyc, adv, tau))
        tau += fps * dt * (1 - min_jerk(t / decel_s))
    last = clip_at(cyc, adv, tau)
    frames += [last] * int(round(END_S * fps))
    tail = np.array(frames)
    return _placed_on(h, tail, at)


#: A tracked stop whose keypoint error passed this at some step is left out of the
#: library, m (the stop after ``half_c`` tracked with seed 0, max 0.39 m, fell when
#: replayed; the kept stops reach 0.06-0.25 m).
KEEP_MAX_ERR_M = 0.3
#: The short stops (``halt_after_<piece>``, :func:`halt_reference`): one tracking run after
#: each piece ending at a right mid-swing.
HALT_AFTER = ("start_short", "half_c", "half_a")


def track_halt(h: Humanoid, base: RetargetResult, cyc: np.ndarray, adv: np.ndarray,
               fps: float, taus: np.ndarray, run: dict[str, np.ndarray], after: str,
               seed: int, tries: int, log: Path | None) -> dict[str, np.ndarray]:
    """The tracked short stop after primitive ``after`` (:data:`HALT_AFTER`), as
    :func:`track_stop` but of :func:`halt_reference`."""
    return _track_tail_after(h, base, fps, taus, run, after, seed, tries, log,
                             lambda at: halt_reference(h, cyc, adv, fps, at))


#: Real motion capture of a person coming to rest from a walk with the feet close: CMU
#: 19_01 ("walk, shake hands", subject B; the shared corpus's
#: ``cmu/two_person/18_19_walk_shake_hands/19_01.bvh``) walks in at 1.1 m/s, shortens its
#: last step (the left foot lands 0.27 m ahead of the right, a stride being 0.55 m) and
#: is at rest by 1.1 s, the feet 0.15-0.2 m apart along the walk and 0.2 m aside, the
#: right heel still raised (measured on the retargeted clip). Its first frame is 0.14 s
#: after a right heel strike.
CLOSE_CLIP = ("cmu", "two_person", "18_19_walk_shake_hands", "19_01.bvh")
#: Where that clip is at rest, s. (Played on, slowed to rest at 1.6 s, where the subject
#: has lowered the right heel and drifts back to step away, the tracked body did not
#: lower the heel and stepped back off its balance at the end: error 0.44 m, measured.)
CLOSE_REST_S = 1.1
#: Cross-fade from the walk's gait into the closing clip, s.
CLOSE_FADE_S = 0.1
#: The closing clip's heading: its pelvis's travel over its first this many s.
CLOSE_DIR_S = 0.3
#: After the clip, a blend onto the stepping gait's upright stance over the same feet
#: (:func:`gait_stance`), s (without it the tracked body ended on the ball of the rear
#: foot, the pelvis tilted 12-32 deg, and the stepping gait fell from there, measured).
CLOSE_STAND_S = 1.5
#: The pieces a closing stop (``close_after_<piece>``, :func:`close_reference`) may be
#: tracked after (``--close``), shortest chains first.
CLOSE_AFTER = ("start_short", "start", "half_c", "half_b", "half_a", "straight", "left")


def closing_clip(h: Humanoid) -> np.ndarray:
    """(T, nq) :data:`CLOSE_CLIP` retargeted onto ``h`` up to :data:`CLOSE_REST_S`."""
    res = retarget_motion(simenv.load(shared_data_root().joinpath(*CLOSE_CLIP)), h)
    return np.asarray(res.qpos[: int(round(CLOSE_REST_S * res.fps)) + 1], float)


def close_reference(h: Humanoid, cyc: np.ndarray, adv: np.ndarray, fps: float,
                    clip: np.ndarray, phase: str, at: np.ndarray) -> np.ndarray:
    """(T, nq) a stop that ends with the feet close: the looped clip (cycle ``cyc``,
    advance ``adv``) from the mid-swing ``phase`` (``"left"``: frame 0, ``"right"``: P / 2)
    to the frame whose leg hinges are nearest the closing ``clip``'s first (rms), a
    cross-fade over :data:`CLOSE_FADE_S` into ``clip`` (turned onto the walk by its
    pelvis's travel), the clip to rest, a blend over :data:`CLOSE_STAND_S` onto the
    stepping gait's stance over the same feet (:func:`gait_stance`) and :data:`END_S`
    still; placed on the floor onto the pose ``at`` (nq,) as :func:`stop_reference` places
    its tail."""
    P = len(cyc)
    legs = [i for i, n in enumerate(h.joint_names)
            if any(k in n for k in ("thigh", "shin", "foot", "toes"))]
    tau0 = 0.0 if phase == "left" else 0.5 * P
    rms = [float(np.sqrt(np.mean((cyc[f, 7:][legs] - clip[0, 7:][legs]) ** 2)))
           for f in range(P)]
    f = int(np.argmin(rms))
    tau1 = float(f if f > tau0 else f + P)
    frames = [clip_at(cyc, adv, t) for t in np.arange(tau0, tau1)]
    # The clip turned onto the looped walk's direction (+x) by its pelvis's travel over
    # its first CLOSE_DIR_S and shifted onto the join frame's pelvis (placed by one
    # frame's leg keypoints instead, the other subject's stride turned it 25 deg, measured).
    d = clip[int(round(CLOSE_DIR_S * fps)), :2] - clip[0, :2]
    psi = -float(np.arctan2(d[1], d[0]))
    placed = clip.copy()
    c, sn = np.cos(psi), np.sin(psi)
    placed[:, :2] = (clip[:, :2] - clip[0, :2]) @ np.array([[c, sn], [-sn, c]])
    placed[:, :2] += clip_at(cyc, adv, tau1)[:2]
    for i in range(len(placed)):
        placed[i, 3:7] = _qmul(_quat_z(psi), placed[i, 3:7])
    n = int(round(CLOSE_FADE_S * fps))
    frames += [_blend(clip_at(cyc, adv, tau1 + k), placed[k], min_jerk(k / n))
               for k in range(n)]
    frames += list(placed[n:])
    up = gait_stance(h, placed[-1])
    k = int(round(CLOSE_STAND_S * fps))
    frames += [_blend(placed[-1], up, min_jerk(j / k)) for j in range(1, k + 1)]
    frames += [frames[-1]] * int(round(END_S * fps))
    return _placed_on(h, np.array(frames), at)


def gait_stance(h: Humanoid, q: np.ndarray) -> np.ndarray:
    """(nq,) the stepping gait's standing pose (:func:`simenv.agents.gait.balanced_pose`:
    the pelvis upright :data:`simenv.agents.gait.STAND_DROP_M` below standing, the centre
    of mass over the middle of the soles, the arms hanging) with the feet flat where they
    stand in ``q`` (nq,)."""
    from simenv.agents import gait

    m = h.model
    d = mujoco.MjData(m)
    d.qpos[:] = q
    mujoco.mj_kinematics(m, d)
    feet = {}
    for side in gait.SIDES:
        b = m.body(f"{side}_foot").id
        fwd = d.xmat[b].reshape(3, 3)[:2, 0]
        feet[side] = (d.xpos[b, :2].copy(), float(np.arctan2(fwd[1], fwd[0])))
    ik = gait.leg_ik(h)
    upper = standing_pose(h)
    mid = 0.5 * (gait.support_centre(*feet["left"]) + gait.support_centre(*feet["right"]))
    yaw = float(np.angle(np.exp(1j * feet["left"][1]) + np.exp(1j * feet["right"][1])))
    pose, _ = gait.balanced_pose(ik, upper, {s: ik.place(s, *feet[s]) for s in gait.SIDES},
                                 mid, yaw, float(upper[2]) - gait.STAND_DROP_M, q)
    return pose


def track_close(h: Humanoid, base: RetargetResult, cyc: np.ndarray, adv: np.ndarray,
                fps: float, taus: np.ndarray, run: dict[str, np.ndarray], clip: np.ndarray,
                after: str, seed: int, tries: int, log: Path | None
                ) -> dict[str, np.ndarray]:
    """The tracked closing stop after primitive ``after`` (:data:`CLOSE_AFTER`), as
    :func:`track_stop` but of :func:`close_reference`."""
    return _track_tail_after(h, base, fps, taus, run, after, seed, tries, log,
                             lambda at: close_reference(h, cyc, adv, fps, clip,
                                                        CUTS[after][3], at))


#: Rank of the gains' basis over time. Measured on the start's first 2 s in the tracked
#: model, pushed sideways 0.2 m/s: the pelvis 0.27 m off the tracked run after 2 s with
#: the full gains (Q 10 / 50 / 0.1), 0.28 m at rank 100, 0.35 at rank 40; at rank 5 (99.9 %
#: of the gains' squared norm, the stiff contact directions' gains dominating it) the
#: feedback was worse than none. Open loop 1.3 m (fallen); Q 100 / 500 / 1: 0.25 m, and
#: 0.42 m pushed 0.4 m/s (Q 10 / 50 / 0.1: 1.6 m, fallen).
GAIN_RANK = 80
#: The servos the feedback drives (the planner's sampled parts).
FEEDBACK_PARTS = ("lumbar", "thigh", "shin", "foot", "toes")


def _advance(h: Humanoid, q0: np.ndarray, q1: np.ndarray) -> list[float]:
    """Where pose ``q1``'s pelvis is from ``q0``'s on the floor (m; every primitive starts
    where the tracked path heads along +x) and the turn between them (rad: the placement
    of the legs' keypoints, :func:`simenv.agents.mocap_walk.fit_frame`)."""
    from simenv.agents.mocap_walk import ANCHOR_KEYPOINTS, fit_frame

    idx = [list(h.keypoint_names).index(k) for k in ANCHOR_KEYPOINTS]
    turn, _ = fit_frame(h.keypoints(q0)[idx, :2], h.keypoints(q1)[idx, :2])
    d = q1[:2] - q0[:2]
    return [float(d[0]), float(d[1]), float(turn)]


def build_library(h: Humanoid, run: dict[str, np.ndarray], taus: np.ndarray, fps: float,
                  out: Path, provenance: dict, stops: dict[str, dict[str, np.ndarray]],
                  rank: int = GAIN_RANK) -> dict:
    """Cut the tracked ``run`` into :data:`CUTS`, add the tracked ``stops`` (their names,
    ``stop_after_<piece>`` or ``halt_after_<piece>`` -> its run, :func:`track_stop`,
    :func:`track_halt`), give them LQR gains (on a basis of rank ``rank`` over time) and
    write the library to ``out`` (:data:`simenv.agents.mocap_walk.LIBRARY`'s JSON); returns its
    metadata."""
    from simenv.agents.mocap_walk import body_signature, pack_array

    dt = float(run["dt"])
    n = len(run["qpos"])

    def step(tau: float | None, last: int) -> int:
        if tau is None:
            return 0 if last == 0 else (n - 1) - (n - 1) % STRIDE
        frame = int(np.searchsorted(taus, tau))
        return int(round(frame / fps / dt / STRIDE)) * STRIDE

    model, _ = planning_model_of(h)
    names = [model.actuator(i).name for i in range(model.nu)]
    fb = np.array([i for i, nm in enumerate(names) if any(p in nm for p in FEEDBACK_PARTS)])
    spans = {k: (step(a, 0), step(b, 1)) for k, (a, b, _, _) in CUTS.items()}
    # The spans joined where they overlap: one Riccati recursion over each group.
    groups: list[list[int]] = []
    for a, b in sorted(spans.values()):
        if groups and a <= groups[-1][1]:
            groups[-1][1] = max(groups[-1][1], b)
        else:
            groups.append([a, b])
    gain_at: dict[int, np.ndarray] = {}
    for a, b in groups:
        g = lqr_gains(model, run["qpos"][a:b + 1], run["qvel"][a:b + 1], run["ctrl"][a:b + 1],
                      fb, STRIDE)
        for k in range(len(g)):
            gain_at[a + k * STRIDE] = g[k]
    stop_gains = {n: lqr_gains(model, sr["qpos"], sr["qvel"], sr["ctrl"], fb, STRIDE)
                  for n, sr in stops.items()}
    used = sorted(gain_at)
    flat = np.concatenate([np.array([gain_at[k] for k in used]).reshape(len(used), -1),
                           *[g.reshape(len(g), -1) for g in stop_gains.values()]])
    _, sv, vt = np.linalg.svd(flat, full_matrices=False)
    r = min(rank, len(sv))
    basis = vt[:r]
    arrays: dict[str, np.ndarray] = {}
    meta: dict = {"primitives": {}, **provenance, "rank": r, "stride": STRIDE,
                  "joint_names": list(h.joint_names), "actuator_names": names}
    for name, (a, b) in spans.items():
        k = np.arange(a, b + 1, STRIDE)
        gk = np.array([gain_at[i] for i in k]).reshape(len(k), -1)
        arrays[f"{name}_qpos"] = run["qpos"][k].astype(np.float32)
        arrays[f"{name}_qvel"] = run["qvel"][k].astype(np.float32)
        arrays[f"{name}_ctrl"] = run["ctrl"][k].astype(np.float32)
        arrays[f"{name}_coef"] = (gk @ basis.T).astype(np.float32)
        meta["primitives"][name] = {
            "phase_in": CUTS[name][2], "phase_out": CUTS[name][3],
            "steps": [int(a), int(b)], "seconds": (b - a) * dt,
            "advance": _advance(h, run["qpos"][a], run["qpos"][b])}
    for name, srun in stops.items():
        after = name.split("_after_", 1)[1]
        b = len(srun["qpos"]) - 1
        k = np.arange(0, b - b % STRIDE + 1, STRIDE)
        gk = stop_gains[name][: len(k)].reshape(len(k), -1)
        arrays[f"{name}_qpos"] = srun["qpos"][k].astype(np.float32)
        arrays[f"{name}_qvel"] = srun["qvel"][k].astype(np.float32)
        arrays[f"{name}_ctrl"] = srun["ctrl"][k].astype(np.float32)
        arrays[f"{name}_coef"] = (gk @ basis.T).astype(np.float32)
        meta["primitives"][name] = {
            "phase_in": CUTS[after][3], "phase_out": "stand", "after": after,
            "seed": int(srun["seed"]), "seconds": float(k[-1] * dt),
            "tracked_mean_err_m": float(srun["err"].mean()),
            "tracked_max_err_m": float(srun["err"].max()),
            "tracking_wall_s": float(srun["wall_s"]),
            "advance": _advance(h, srun["qpos"][0], srun["qpos"][k[-1]])}
    err = np.linalg.norm(flat @ basis.T @ basis - flat) / np.linalg.norm(flat)
    meta["gain_relative_error"] = float(err)
    out.parent.mkdir(parents=True, exist_ok=True)
    meta["dt"] = dt
    arrays.update(gain_basis=basis.reshape(r, len(fb), -1).astype(np.float16),
                  feedback_ctrl=fb, dims=body_signature(h))
    out.write_text(json.dumps({"meta": meta, "arrays": {k: pack_array(v)
                                                        for k, v in arrays.items()}}))
    return meta


def planning_model_of(h: Humanoid) -> tuple[mujoco.MjModel, object]:
    """The simulated model the tracker used (the humanoid with its sensors)."""
    from simenv.control import planning_model
    return planning_model(h, 1)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("assets/walk-primitives/mocap_walk.json"))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--tries", type=int, default=3)
    parser.add_argument("--tracked", type=Path, default=Path("/tmp/mw_tracked.npz"),
                        help="the tracked run (reused when present)")
    parser.add_argument("--log", type=Path, default=Path("/tmp/mw_build.log"))
    parser.add_argument("--close", nargs="*", default=[], choices=CLOSE_AFTER,
                        help="pieces to track a closing stop after (module docstring, 7)")
    parser.add_argument("--rank", type=int, default=GAIN_RANK,
                        help="rank of the gains' basis over time (GAIN_RANK)")
    parser.add_argument("--stride", type=int, default=5,
                        help="physics steps per gain (held in between)")
    args = parser.parse_args()
    h = agent_body()
    base = retarget_motion(simenv.load(asset_path(WALK)), h)
    fps = float(base.fps)
    cyc, adv = looped_clip(h, base.qpos)
    q, times = composite_reference(h, cyc, adv, fps)
    with args.log.open("a") as f:
        f.write(f"cycle {len(cyc)} frames, advance {adv.round(3).tolist()} m, reference "
                f"{len(q) / fps:.2f} s, cycle starts "
                f"{json.dumps({k: v for k, v in times.items() if k != 'taus'})}\n")
    if args.tracked.exists():
        run = dict(np.load(args.tracked))
    else:
        for seed in range(args.seed, args.seed + args.tries):
            run = track_reference(h, base, q, fps, seed, args.log)
            run["seed"] = np.array(seed)
            np.savez(args.tracked.with_name(f"{args.tracked.stem}_seed{seed}.npz"), **run)
            if bool(run["ok"]):
                break
        np.savez(args.tracked, **run)
    with args.log.open("a") as f:
        f.write(f"tracked ok={bool(run['ok'])} seed={int(run['seed'])} steps {len(run['qpos'])} "
                f"mean err {run['err'].mean():.3f} max {run['err'].max():.3f} wall "
                f"{float(run['wall_s']):.0f} s\n")
    if not bool(run["ok"]):
        print("the tracker failed on every seed: no library written")
        return 1
    provenance = {
        "source": "CMU 02_01 walk (assets/cmu_02_01_walk.bvh), real motion capture, "
                  "mocap.cs.cmu.edu (NSF EIA-0196217)",
        "generator": "benchmarks/build_mocap_walk.py", "seed": int(run["seed"]),
        "planner": "simenv.control.TrackingMPC, MPCConfig defaults but seed",
        "turn_deg": TURN_DEG, "cycles": list(CYCLES), "stop_after": list(STOP_AFTER),
        "halt_after": list(HALT_AFTER),
        "tracked_mean_err_m": float(run["err"].mean()),
        "tracked_max_err_m": float(run["err"].max()),
        "tracking_wall_s": float(run["wall_s"]),
        "lqr": {"q_pos": Q_POS, "q_root": Q_ROOT, "q_vel": Q_VEL, "r_ctrl": R_CTRL}}
    taus = np.asarray(times["taus"])
    clip = None
    if args.close:
        clip = closing_clip(h)
        provenance["close_after"] = list(args.close)
        provenance["close_source"] = ("CMU 19_01 walk, shake hands, subject B (shared corpus "
                                      f"{'/'.join(CLOSE_CLIP)}), real motion capture, "
                                      "mocap.cs.cmu.edu (NSF EIA-0196217), to "
                                      f"{CLOSE_REST_S} s, then {CLOSE_STAND_S} s onto the "
                                      "stepping gait's stance")
    stops = {}
    for kind, afters in (("stop", STOP_AFTER), ("halt", HALT_AFTER), ("close", args.close)):
        for after in afters:  # each tracked run is cached beside the main one
            name = f"{kind}_after_{after}"
            suffix = f"stop_{after}" if kind == "stop" else name
            path = args.tracked.with_name(f"{args.tracked.stem}_{suffix}.npz")
            if not path.exists():
                if kind == "stop":
                    out = track_stop(h, base, q, taus, fps, run, after, args.seed, args.tries,
                                     args.log)
                elif kind == "halt":
                    out = track_halt(h, base, cyc, adv, fps, taus, run, after, args.seed,
                                     args.tries, args.log)
                else:
                    assert clip is not None
                    out = track_close(h, base, cyc, adv, fps, taus, run, clip, after,
                                      args.seed, args.tries, args.log)
                np.savez(path, **out)
            stops[name] = dict(np.load(path))
            sr = stops[name]
            with args.log.open("a") as f:
                f.write(f"{name}: ok={bool(sr['ok'])} seed {int(sr['seed'])} mean err "
                        f"{sr['err'].mean():.3f} max {sr['err'].max():.3f}\n")
            if not bool(sr["ok"]) and kind == "stop":
                print(f"the tracker failed {name} on every seed: no library")
                return 1
            if not bool(sr["ok"]) or float(sr["err"].max()) > KEEP_MAX_ERR_M:
                del stops[name]
                provenance.setdefault("left_out", []).append(
                    {"stop": name, "seed": int(sr["seed"]), "max_err_m": float(sr["err"].max())})
                with args.log.open("a") as f:
                    f.write(f"{name} left out (max error over {KEEP_MAX_ERR_M} m)\n")
    t0 = time.perf_counter()
    meta = build_library(h, run, taus, fps, args.out, provenance, stops, args.rank)
    with args.log.open("a") as f:
        f.write(f"library {args.out}: rank {meta['rank']}, gain error "
                f"{meta['gain_relative_error']:.4f}, {time.perf_counter() - t0:.0f} s, "
                f"{args.out.stat().st_size / 1e6:.2f} MB\n")
        for k, v in meta["primitives"].items():
            f.write(f"  {k}: {v['seconds']:.2f} s, advance {np.round(v['advance'], 3)}\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
