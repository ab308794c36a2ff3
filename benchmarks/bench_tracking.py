"""Cost of unassisted tracking (simenv.control), as a ratio to real time.

On the retargeted bundled CMU walk 02_01 (``--seconds`` of it), wall time
per simulated second of:

1. a raw ``mujoco.mj_step`` loop on the humanoid (servo targets only);
2. the assisted PD tracker, :func:`simenv.plausibility.tracking.track`
   with ``assist=True`` (the scorer's previous default);
3. the unassisted MPC tracker (``controller="mpc"``) with its rollouts on 1
   and on 2 threads (goal of issue 35: <= 2x real time on 2 cores), with the default
   planner and with :data:`simenv.control.FAST` on 2 threads;

and, when ``jax`` and ``mujoco.mjx`` import, a batched rollout of the
planner's model (``--mjx-samples`` x ``--mjx-steps`` of the humanoid from one
state: MJX on the CPU is too slow for the planner's full batch) with MJX
(``jit(vmap(scan(mjx.step)))``, compile time excluded) against
``mujoco.rollout`` of the same batch on 1 and 2 threads, printed as a ratio.
MJX is not a dependency of simenv: install ``mujoco-mjx`` (it brings
``jax``) to measure.

The machine may be shared: the load average is printed before and after,
and every timing is the best of ``--repeats`` runs; expect noise of tens of
per cent when other jobs run.

Usage::

    .venv/bin/python benchmarks/bench_tracking.py [--seconds 1.0] [--repeats 2] [--no-mjx] \
        [--samples N]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from dataclasses import replace  # noqa: E402

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from mujoco import rollout  # noqa: E402

from simenv.assets import WALK, asset_path  # noqa: E402
from simenv.body.retarget import RetargetResult, retarget  # noqa: E402
from simenv.control import FAST, MPCConfig, TrackingMPC, TrackingReference  # noqa: E402
from simenv.io import bvh  # noqa: E402
from simenv.plausibility.tracking import track  # noqa: E402

_STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS


def best(fn: Callable[[], float], repeats: int) -> float:
    """Least value of ``fn()`` (a duration) over ``repeats`` calls."""
    return min(fn() for _ in range(repeats))


def raw_step_ratio(result: RetargetResult, seconds: float, repeats: int) -> float:
    """Wall time per simulated second of a bare mj_step loop on the humanoid."""
    ref = TrackingReference.from_retarget(result, max_seconds=seconds, feedforward=False)
    model = result.humanoid.model
    data = mujoco.MjData(model)

    def once() -> float:
        data.qpos[:], data.qvel[:] = ref.qpos0, ref.qvel0
        mujoco.mj_forward(model, data)
        t = time.perf_counter()
        for s in range(ref.n_steps):
            data.ctrl[:] = ref.ctrl[s]
            mujoco.mj_step(model, data)
        return (time.perf_counter() - t) / (ref.n_steps * ref.dt)

    return best(once, repeats)


def track_ratio(result: RetargetResult, seconds: float, repeats: int, **kw: object) -> float:
    def once() -> float:
        tr = track(result, max_seconds=seconds, **kw)
        return tr.wall_s / (tr.steps * result.humanoid.model.opt.timestep)
    return best(once, repeats)


def rollout_shape(result: RetargetResult) -> tuple[mujoco.MjModel, np.ndarray, np.ndarray]:
    """The planner's model, a start state and (N, H, nu) controls of its default shape."""
    cfg = MPCConfig(nthread=1)
    ref = TrackingReference.from_retarget(result, max_seconds=1.0, feedforward=False)
    with TrackingMPC(result.humanoid, ref, cfg) as mpc:
        data = mujoco.MjData(mpc.plan_model)
        mpc.reset(data)
        x0 = np.empty(mujoco.mj_stateSize(mpc.plan_model, _STATE))
        mujoco.mj_getState(mpc.plan_model, data, x0, _STATE)
        steps = ref.window(0, mpc.horizon * cfg.timestep_factor)[::cfg.timestep_factor]
        controls = np.repeat(ref.ctrl[steps][None], cfg.n_samples, axis=0)
        return mpc.plan_model, x0, controls


def rollout_seconds(model: mujoco.MjModel, x0: np.ndarray, controls: np.ndarray,
                    nthread: int, repeats: int) -> float:
    datas = [mujoco.MjData(model) for _ in range(nthread)]
    with rollout.Rollout(nthread=nthread) as pool:
        def once() -> float:
            t = time.perf_counter()
            pool.rollout(model, datas, x0[None], controls)
            return time.perf_counter() - t
        return best(once, repeats + 1)


def mjx_seconds(model: mujoco.MjModel, x0: np.ndarray, controls: np.ndarray,
                repeats: int) -> tuple[float, float] | str:
    """(seconds per batched rollout, compile seconds) with MJX on the CPU, or why not."""
    try:  # optional: MJX (and jax) are not among simenv's dependencies
        import jax
        from mujoco import mjx
    except ImportError as exc:
        return f"not installed ({exc.name}); pip install mujoco-mjx to measure"
    try:
        mx = mjx.put_model(model)
    except (NotImplementedError, ValueError) as exc:
        return f"model not supported by MJX: {exc}"
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, x0, _STATE)
    mujoco.mj_forward(model, data)
    dx0 = mjx.put_data(model, data)
    ctrl = jax.numpy.asarray(controls)

    def one(u: jax.Array) -> jax.Array:
        def body(d: mjx.Data, uk: jax.Array) -> tuple[mjx.Data, jax.Array]:
            d = mjx.step(mx, d.replace(ctrl=uk))
            return d, d.qpos
        return jax.lax.scan(body, dx0, u)[1]

    fn = jax.jit(jax.vmap(one))
    t = time.perf_counter()
    fn(ctrl).block_until_ready()
    compile_s = time.perf_counter() - t

    def once() -> float:
        t0 = time.perf_counter()
        fn(ctrl).block_until_ready()
        return time.perf_counter() - t0

    return best(once, repeats), compile_s


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seconds", type=float, default=1.0, help="simulated seconds per run")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--no-mjx", action="store_true", help="skip the MJX comparison")
    ap.add_argument("--mjx-samples", type=int, default=4)
    ap.add_argument("--mjx-steps", type=int, default=10)
    ap.add_argument("--samples", type=int, default=None,
                    help="MPC rollouts per replan (default MPCConfig's)")
    args = ap.parse_args()
    print(f"load average before: {os.getloadavg()}  (2 cores, shared: timings are noisy)")
    result = retarget(bvh.read(asset_path(WALK)).slice(0, int(args.seconds * 120) + 2))
    raw = raw_step_ratio(result, args.seconds, args.repeats)
    pd = track_ratio(result, args.seconds, args.repeats, assist=True)
    cfg = MPCConfig(**({} if args.samples is None else {"n_samples": args.samples}))
    mpc1 = track_ratio(result, args.seconds, args.repeats, controller="mpc",
                       mpc=replace(cfg, nthread=1))
    mpc2 = track_ratio(result, args.seconds, args.repeats, controller="mpc",
                       mpc=replace(cfg, nthread=2))
    fast2 = track_ratio(result, args.seconds, args.repeats, controller="mpc",
                        mpc=replace(FAST, nthread=2))
    print(f"\nwalk 02_01, {args.seconds:.1f} s simulated; MPC: {cfg.n_samples} samples x "
          f"{cfg.horizon_s:.2f} s horizon, replan every {cfg.replan_steps} steps, planning "
          f"step x{cfg.timestep_factor}")
    print(f"{'tracker':34s} {'x real time':>12s} {'vs assisted PD':>15s}")
    for name, ratio in (("raw mj_step", raw), ("assisted PD (track assist=True)", pd),
                        ("unassisted MPC, 1 thread", mpc1), ("unassisted MPC, 2 threads", mpc2),
                        ("unassisted MPC FAST, 2 threads", fast2)):
        print(f"{name:34s} {ratio:12.2f} {ratio / pd:15.1f}")
    for name, ratio in (("default", mpc2), ("FAST", fast2)):
        print(f"goal <= 2x real time on 2 cores (issue 35), {name} planner: "
              f"{'met' if ratio <= 2 else 'NOT met'} ({ratio:.1f}x)")
    print(f"2 threads / 1 thread speed-up {mpc1 / mpc2:.2f}; FAST / default {fast2 / mpc2:.2f}")
    if not args.no_mjx:
        model, x0, controls = rollout_shape(result)
        n, h = controls.shape[:2]
        r1 = rollout_seconds(model, x0, controls, 1, args.repeats)
        r2 = rollout_seconds(model, x0, controls, 2, args.repeats)
        print(f"\nplanner batch {n} x {h} steps: mujoco.rollout 1 thread {r1 * 1e3:.1f} ms, "
              f"2 threads {r2 * 1e3:.1f} ms ({r2 / (n * h) * 1e6:.1f} us/step)")
        small = controls[:args.mjx_samples, :args.mjx_steps]
        n, h = small.shape[:2]
        s1 = rollout_seconds(model, x0, small, 1, args.repeats)
        s2 = rollout_seconds(model, x0, small, 2, args.repeats)
        mj = mjx_seconds(model, x0, small, args.repeats)
        if isinstance(mj, str):
            print(f"MJX: {mj}")
        else:
            print(f"batch {n} x {h} steps: MJX (jax CPU) {mj[0] / (n * h) * 1e6:,.0f} us/step "
                  f"(compile {mj[1]:.0f} s), mujoco.rollout {s1 / (n * h) * 1e6:,.0f} us/step "
                  f"on 1 thread, {s2 / (n * h) * 1e6:,.0f} on 2: MJX is {mj[0] / s2:,.0f}x "
                  f"slower than mujoco.rollout on 2 threads ({mj[0] / s1:,.0f}x vs 1 thread)")
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
