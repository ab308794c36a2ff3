"""Cost of one perception tick, the room's recogniser against the previous stack.

A tick of the room's agent, :class:`simenv.perception.room_agent.RoomAgent` (perceive, then
decide: what :meth:`~simenv.perception.room_agent.RoomAgent.act` runs at a tick), on real
keypoints (the bundled CMU walk retargeted into the room, as the rehearsal gives them: the
history its ticks read, ``RoomAgent.history_frames`` -- 75 frames for the room's three real
windows --, its first frame held before the walk as when a session starts): the real stage
alone, and the real + forecast stage (forced by a threshold of 1.1, so both stages always
run). Stacks:

* ``gesture-tcn-ensemble`` + ``predictor-gesture-25-50`` (the room's now: two TCNs run as
  one fused network),
* ``gesture-tcn`` + ``predictor-gesture-25-50`` (one TCN: the room's before),
* ``gesture-classifier`` (transformer) + ``predictor-25-50`` (PredictiveMA-WGAN): the
  reference both replace,
* the room's ensemble run member by member (``ensemble_one_by_one``: what the fusion saves).

``--members PATH ...`` adds the room's loop with an ensemble
(:class:`simenv.perception.loop.TrainedClassifier` with several members): ``gesture-tcn``
plus the first 1, 2, ... of these SkeletonTCN checkpoints (e.g. fold networks of
``benchmarks/loop_variants.py``: same architecture, so the same cost as all-subject
members), written under ``room_members`` by member count.

One torch thread (a 90 Hz frame is 11 ms of one core); the median over ``--ticks`` ticks
of the wall time and of the thread's CPU time (``*_cpu_ms``; on a shared machine the wall
time also counts the other processes' turns), every stack taking turns tick by tick, and
the ratios other / room are printed,
and ``--json`` writes them.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import torch  # noqa: E402

import simenv  # noqa: E402
import simenv.models  # noqa: E402
from simenv.assets import WALK, asset_path  # noqa: E402
from simenv.models.skeleton_tcn import SkeletonTCN  # noqa: E402
from simenv.perception.loop import PerceptionLoop, TrainedClassifier, load_predictor  # noqa: E402
from simenv.perception.room_agent import RoomAgent  # noqa: E402
from simenv.room.scenario import load_scenario  # noqa: E402
from simenv.room.session import Session, user_track  # noqa: E402

STACKS = {"room": ("gesture-tcn-ensemble", "predictor-gesture-25-50"),
          "one_network": ("gesture-tcn", "predictor-gesture-25-50"),
          "reference": ("gesture-classifier", "predictor-25-50")}


class OneByOne:
    """A member network :class:`TrainedClassifier` does not fuse (not a ``SkeletonTCN``):
    an ensemble of these runs member by member, with ``record``'s loop settings."""

    def __init__(self, net: SkeletonTCN, record: object) -> None:
        self.net, self.config = net, net.config
        self.metadata = getattr(record, "metadata", {})

    def predict_proba(self, x: np.ndarray, valid: np.ndarray) -> np.ndarray:
        return self.net.predict_proba(x, valid)


def one_by_one(name: str) -> TrainedClassifier:
    """The shipped ensemble ``name`` run member by member."""
    ensemble = simenv.models.load(name)
    return TrainedClassifier([OneByOne(m, ensemble) for m in ensemble.members],
                             name=f"{name}, member by member")


def tick_ms(stacks: dict[str, tuple[TrainedClassifier, str]], keypoints: np.ndarray,
            ticks: int) -> dict[str, dict[str, float]]:
    """Median ms of a tick with the real stage only and with both stages, wall time
    (``*_ms``) and this thread's CPU time (``*_cpu_ms``: what the tick costs one core,
    whatever else the machine runs), per stack (name -> classifier, predictor name). The
    stacks take turns tick by tick, so a change in the machine's load falls on all alike."""
    behaviour = load_scenario("default").behaviour
    ahead = {name: load_predictor(predictor) for name, (_, predictor) in stacks.items()}
    out: dict[str, dict[str, float]] = {name: {} for name in stacks}
    for stage, threshold in (("real_stage", 0.0), ("both_stages", 1.1)):
        agents = {name: RoomAgent(PerceptionLoop(clf, ahead[name], threshold=threshold,
                                                 use_forecast=True), behaviour, (None,))
                  for name, (clf, _) in stacks.items()}
        need = max(agent.history_frames for agent in agents.values())
        # Before the walk its first pose is held, as when a session starts.
        held = np.concatenate([np.repeat(keypoints[:1], need, axis=0), keypoints])
        wall: dict[str, list[float]] = {name: [] for name in agents}
        cpu: dict[str, list[float]] = {name: [] for name in agents}
        for k in range(ticks):
            end = need + k % (len(held) - need)
            for name, agent in agents.items():
                start, start_cpu = time.perf_counter(), time.thread_time()
                agent.decide(agent.perceive(held[end - need:end], end / 25.0))
                wall[name].append(time.perf_counter() - start)
                cpu[name].append(time.thread_time() - start_cpu)
        for name in agents:
            out[name][f"{stage}_ms"] = round(1000 * float(np.median(wall[name][5:])), 2)
            out[name][f"{stage}_cpu_ms"] = round(1000 * float(np.median(cpu[name][5:])), 2)
    return out


def ensemble_ticks(members: list[Path], keypoints: np.ndarray, ticks: int
                   ) -> dict[str, dict[str, float]]:
    """Tick cost of the room's stack with ``gesture-tcn`` plus the first 0, 1, ...
    ``members`` as an ensemble, keyed by member count ("1", "2", ...)."""
    classifier, predictor = STACKS["one_network"]
    shipped = simenv.models.load(classifier)
    extra = [SkeletonTCN.load(path) for path in members]
    out = tick_ms({str(k + 1): (TrainedClassifier([shipped, *extra[:k]]), predictor)
                   for k in range(len(extra) + 1)}, keypoints, ticks)
    for k, r in out.items():
        print(f"room, {k} member(s): real stage {r['real_stage_ms']} ms "
              f"({r['real_stage_cpu_ms']} ms CPU), both stages {r['both_stages_ms']} ms "
              f"({r['both_stages_cpu_ms']} ms CPU) a tick")
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=200)
    parser.add_argument("--json", help="write the results here")
    parser.add_argument("--members", nargs="*", type=Path, default=[],
                        help="SkeletonTCN checkpoints added to gesture-tcn as ensemble members")
    args = parser.parse_args()
    torch.set_num_threads(1)
    kp = user_track(Session(simenv.load(asset_path(WALK)))).keypoints.astype(np.float32)
    stacks = {}
    for stack, (classifier, predictor) in STACKS.items():
        if not {classifier, predictor} <= set(simenv.models.available()):
            print(f"{stack}: {classifier} / {predictor} not shipped; skipped")
            continue
        stacks[stack] = (TrainedClassifier.shipped(classifier), predictor)
    if "room" in stacks:
        stacks["ensemble_one_by_one"] = (one_by_one(STACKS["room"][0]), STACKS["room"][1])
    results: dict[str, object] = {}
    for stack, r in tick_ms(stacks, kp, args.ticks).items():
        results[stack] = {"classifier": stacks[stack][0].name, "predictor": stacks[stack][1],
                          **r}
        print(f"{stack:>19} ({stacks[stack][0].name} + {stacks[stack][1]}): real stage "
              f"{r['real_stage_ms']} ms, both stages {r['both_stages_ms']} ms a tick (CPU: "
              f"{r['real_stage_cpu_ms']} / {r['both_stages_cpu_ms']} ms)")
    for other in ("reference", "one_network", "ensemble_one_by_one"):
        for key in ("real_stage_cpu_ms", "both_stages_cpu_ms"):
            if {"room", other} <= set(results):
                ratio = results[other][key] / results["room"][key]
                results[f"ratio_{other}_{key}"] = round(ratio, 2)
                print(f"{other} / room, {key}: {ratio:.2f}x")
    if args.members:
        results["room_members"] = ensemble_ticks(args.members, kp, args.ticks)
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
