"""Train the tracking policy (:mod:`simenv.control.policy`) on the planner's own solutions.

Split, by clip, fixed before any training (``TRAIN_CLIPS`` / ``EVAL_CLIPS``): of the 20
clean single-person CMU clips of the shared corpus that the planner is evaluated on
(``benchmarks/eval_tracking.py``, the acrobatic 49_06 left out), every other one in that
script's order (``clips()``, 0-based even positions) is an evaluation clip, the rest
training clips; the six people of the three two-person CMU trials (walk and shake hands,
two salsa takes; none reserved) are training clips too. 02_01.bvh and 02_01.amc, one trial
in two formats, are both training clips.

Steps::

    # 1. behaviour-cloning data: the planner drives and labels (first --seconds of each clip)
    nice -n 10 .venv/bin/python benchmarks/train_tracking_policy.py record --round 0
    # 2. fit the policy to every round recorded so far
    .venv/bin/python benchmarks/train_tracking_policy.py fit --rounds 0 --out out/policy/p0.npz
    # 3. DAgger: the policy drives, the planner labels its states (and takes over past 0.1 m)
    nice -n 10 .venv/bin/python benchmarks/train_tracking_policy.py record --round 1 \
        --policy out/policy/p0.npz
    .venv/bin/python benchmarks/train_tracking_policy.py fit --rounds 0 1 --out out/policy/p1.npz

``record --shard I/N`` records every N-th clip from the I-th, so two processes share a round.
Each clip's data go to ``out/policy/round<R>/<clip>.npz`` (``features`` (S, D), ``offsets``
(S, A) radians, one row per physics step) with the planner's result in a JSON line.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from simenv.body.retarget import RetargetResult, retarget  # noqa: E402
from simenv.control.mpc import FAST  # noqa: E402
from simenv.control.policy import ExpertRecorder, TrackingPolicy, body_error  # noqa: E402
from simenv.control.reference import TrackingReference  # noqa: E402
from simenv.core.config import shared_data_root  # noqa: E402
from simenv.core.motion import Motion  # noqa: E402
from simenv.io.loader import load  # noqa: E402
from simenv.plausibility.body_thresholds import DEFAULT_BODY_THRESHOLDS  # noqa: E402
from simenv.plausibility.dynamics import dynamics_settings  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "out" / "policy"

#: The 20 clean clips of benchmarks/eval_tracking.py in its order (bvh then amc, sorted).
ALL_CLEAN: tuple[str, ...] = (
    "01_01.bvh", "02_01.bvh", "02_06.bvh", "05_02.bvh", "12_01.bvh", "131_01.bvh",
    "131_03.bvh", "16_15.bvh", "35_17.bvh", "49_02.bvh", "49_04.bvh",
    "02_01.amc", "02_03.amc", "02_04.amc", "02_05.amc", "09_06.amc", "103_charleston1.amc",
    "131_04.amc", "135_06.amc", "55_02.amc")
EVAL_CLIPS: tuple[str, ...] = ALL_CLEAN[0::2]
TWO_PERSON: tuple[str, ...] = (
    "18_19_walk_shake_hands/18_01.bvh", "18_19_walk_shake_hands/19_01.bvh",
    "60_61_salsa_05/60_05_scaled.bvh", "60_61_salsa_05/61_05_scaled.bvh",
    "60_61_salsa_10/60_10_scaled.bvh", "60_61_salsa_10/61_10_scaled.bvh")
TRAIN_CLIPS: tuple[str, ...] = ALL_CLEAN[1::2] + TWO_PERSON
#: Seconds of a failed run's recording dropped before the failure.
FALL_DROP_S = 0.5
#: Least feature scale in the normalisation (m, rad, m/s alike; about 3 degrees or 5 cm).
STD_FLOOR = 0.05
#: The planner the data come from: FAST with one rollout thread per process.
EXPERT = replace(FAST, nthread=1)


def clip_path(name: str, data: Path | None = None) -> Path:
    """Where clip ``name`` (a TRAIN_CLIPS / EVAL_CLIPS entry) is in the shared corpus."""
    cmu = (data or shared_data_root()) / "cmu"
    if "/" in name:
        return cmu / "two_person" / name
    return cmu / ("bvh" if name.endswith(".bvh") else "asf_amc") / name


def clip_motion(path: Path, seconds: float) -> Motion:
    """The clip's first ``seconds`` (its first person when it holds several)."""
    m = load(path)
    m = m[0] if isinstance(m, list) else m
    return m.slice(0, min(m.num_frames, int(round(seconds * m.fps)) + 1))


def reference_of(fitted: RetargetResult, seconds: float) -> TrackingReference:
    """The tracking reference as the scorer builds it (its dynamics settings)."""
    return TrackingReference.from_retarget(fitted, fitted.humanoid.model,
                                           dynamics_settings(DEFAULT_BODY_THRESHOLDS), seconds)


def record_clip(fitted: RetargetResult, seconds: float, policy: TrackingPolicy | None
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """Run :class:`ExpertRecorder` over the clip's first ``seconds`` until the body error
    passes the tracking failure distance. Returns features (S, D), offsets (S, A), the
    actuators they go to (A,) and a summary."""
    ref = reference_of(fitted, seconds)
    fail = DEFAULT_BODY_THRESHOLDS.tracking_fail_m
    cpu = time.process_time()
    with ExpertRecorder(fitted.humanoid, ref, EXPERT, policy) as rec:
        data = mujoco.MjData(rec.model)
        rec.reset(data)
        errs = []
        for s in range(ref.n_steps):
            data.ctrl[:] = rec.control(data, s)
            mujoco.mj_step(rec.model, data)
            errs.append(body_error(data, rec.site_ids, ref, s + 1))
            if errs[-1] > fail or not np.isfinite(data.qacc).all():
                break
        feats, offs, actuators = np.array(rec.features), np.array(rec.offsets), rec.actuators
        expert = rec.expert_steps / max(len(rec.features), 1)
    if len(errs) < ref.n_steps:  # the planner's last actions before a fall: not a lesson
        keep = max(0, len(feats) - int(round(FALL_DROP_S / ref.dt)))
        feats, offs = feats[:keep], offs[:keep]
    summary = {"steps": len(errs), "of": ref.n_steps, "tracked": len(errs) == ref.n_steps,
               "mean_error_mm": 1000 * float(np.mean(errs)), "expert_fraction": expert,
               "cpu_s": time.process_time() - cpu}
    return feats, offs, actuators, summary


def record(args: argparse.Namespace) -> None:
    out = OUT / f"round{args.round}"
    out.mkdir(parents=True, exist_ok=True)
    policy = TrackingPolicy.load(args.policy) if args.policy else None
    i, n = map(int, args.shard.split("/"))
    for name in list(args.clips or TRAIN_CLIPS)[i::n]:
        assert name not in EVAL_CLIPS, f"{name} is an evaluation clip"
        target = out / (name.replace("/", "__") + ".npz")
        if target.exists():
            continue
        fitted = retarget(clip_motion(clip_path(name), args.seconds))
        feats, offs, actuators, summary = record_clip(fitted, args.seconds, policy)
        np.savez_compressed(target, features=feats.astype(np.float32),
                            offsets=offs.astype(np.float32), actuators=actuators)
        line = {"clip": name, "round": args.round, "policy": args.policy, **summary,
                "load_average": os.getloadavg()[0]}
        with (out / "log.jsonl").open("a") as f:
            f.write(json.dumps(line) + "\n")
        print(json.dumps(line), flush=True)


def fit(args: argparse.Namespace) -> None:
    import torch

    torch.manual_seed(args.seed)
    torch.set_num_threads(args.threads)
    files = sorted(f for r in args.rounds for f in (OUT / f"round{r}").glob("*.npz"))
    X = np.concatenate([np.load(f)["features"] for f in files]).astype(np.float64)
    Y = np.concatenate([np.load(f)["offsets"] for f in files]).astype(np.float64)
    # A feature nearly constant over the training clips must not blow up elsewhere.
    mean, std = X.mean(0), np.maximum(X.std(0), STD_FLOOR)
    limit = EXPERT.limit_rad
    Xt = torch.tensor((X - mean) / std, dtype=torch.float32)
    # Targets as tanh pre-activations, clipped short of the limit.
    Yt = torch.tensor(np.clip(Y / limit, -0.98, 0.98), dtype=torch.float32)
    dims = [X.shape[1]] + [args.hidden] * args.layers + [Y.shape[1]]
    layers: list[torch.nn.Module] = []
    for a, b in zip(dims[:-1], dims[1:], strict=True):
        layers += [torch.nn.Linear(a, b), torch.nn.ELU()]
    net = torch.nn.Sequential(*layers[:-1])
    opt = torch.optim.Adam(net.parameters(), lr=args.lr, weight_decay=args.weight_decay)
    gen = torch.Generator().manual_seed(args.seed)
    n = len(Xt)
    steps = args.epochs * (n // args.batch)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, steps)
    t0 = time.process_time()
    for epoch in range(args.epochs):
        perm = torch.randperm(n, generator=gen)
        total = 0.0
        for k in range(n // args.batch):
            idx = perm[k * args.batch:(k + 1) * args.batch]
            x = Xt[idx] + args.noise * torch.randn(len(idx), Xt.shape[1], generator=gen)
            loss = torch.mean((torch.tanh(net(x)) - Yt[idx]) ** 2)
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            total += loss.item()
        if epoch % max(1, args.epochs // 10) == 0 or epoch == args.epochs - 1:
            rms = limit * (total / (n // args.batch)) ** 0.5
            print(f"epoch {epoch} rms offset error {rms:.4f} rad", flush=True)
    linears = [m for m in net if isinstance(m, torch.nn.Linear)]
    with torch.no_grad():
        rms = limit * float(torch.mean((torch.tanh(net(Xt)) - Yt) ** 2)) ** 0.5
    clips = sorted({f.name.removesuffix(".npz").replace("__", "/") for f in files})
    info = {"rounds": args.rounds, "clips": clips,
            "train_clips": list(TRAIN_CLIPS), "eval_clips": list(EVAL_CLIPS),
            "samples": n, "expert": "FAST (64 antithetic samples, 8 ms planning step)",
            "hidden": [args.hidden] * args.layers, "epochs": args.epochs, "seed": args.seed,
            "train_rms_rad": rms, "fit_cpu_s": time.process_time() - t0}
    policy = TrackingPolicy(
        tuple(m.weight.detach().numpy().T.astype(np.float64) for m in linears),
        tuple(m.bias.detach().numpy().astype(np.float64) for m in linears),
        mean, std, np.load(files[0])["actuators"], limit, json.dumps(info))
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    policy.save(args.out)
    print(json.dumps(info))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("record", help="record (features, planner offsets) on training clips")
    r.add_argument("--round", type=int, required=True)
    r.add_argument("--policy", help="DAgger: the policy that drives (.npz)")
    r.add_argument("--seconds", type=float, default=6.0)
    r.add_argument("--shard", default="0/1", help="I/N: every N-th clip from the I-th")
    r.add_argument("--clips", nargs="*", help="training clips (default TRAIN_CLIPS)")
    f = sub.add_parser("fit", help="fit the policy to recorded rounds")
    f.add_argument("--rounds", type=int, nargs="+", required=True)
    f.add_argument("--out", required=True)
    f.add_argument("--hidden", type=int, default=256)
    f.add_argument("--layers", type=int, default=2)
    f.add_argument("--epochs", type=int, default=30)
    f.add_argument("--batch", type=int, default=256)
    f.add_argument("--lr", type=float, default=1e-3)
    f.add_argument("--weight-decay", type=float, default=1e-5)
    f.add_argument("--noise", type=float, default=0.05,
                   help="Gaussian noise on the normalised features while fitting")
    f.add_argument("--threads", type=int, default=1)
    f.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    record(args) if args.cmd == "record" else fit(args)


if __name__ == "__main__":
    main()
