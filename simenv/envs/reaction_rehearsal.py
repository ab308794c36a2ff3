"""Rehearse a generated reaction on simulated bodies: a reaction generator answers a
recorded person, and the answer is retargeted, tracked by PD control and scored
(``simenv rehearse SESSION --agent interformer --out DIR``).

Pipeline (one way: load -> Motion -> generate -> retarget/track -> report):

1. The session (one person, any motion file or bundled asset) goes to the 18-keypoint
   layout at 25 fps (:mod:`simenv.data.interaction_data`) and into the actor frame of its
   first frame (:func:`~simenv.data.interaction_data.actor_frame`).
2. **Where the agent starts.** The generator needs the reactor's first frame. It is the
   reactor first frame of the training window whose actor first frame is nearest to the
   user's (flattened actor-frame poses): the agent stands where a real partner stood
   relative to a real actor in that pose. Without the corpus (no ``shared/data``), the
   user's first pose mirrored and turned to face the user from
   :data:`FALLBACK_DISTANCE_M` in front (:class:`~simenv.models.reaction_baselines.MirrorActor`
   geometry). ``summary["start"]`` says which.
3. The generator produces the whole reaction (chunked past its trained window), which is
   put back in the world with the inverse normalisation.
4. :func:`simenv.score` with physics on: both people are retargeted to their own fitted
   humanoids; the agent's motion is tracked in forward simulation by the PD controller
   of the scorer (its root assistance is measured and reported as ``root_residual`` and
   the tracking metric, never hidden); inter-person penetration and contact retention
   are measured between the two bodies.

The scene is the scorer's (a floor), not the furnished room: the generated reactions are
standing two-person interactions (salsa, fist bump, handshake) that need open floor, while
the room's agent sits at a desk (:mod:`simenv.envs.rehearsal` runs that agent).

Outputs in ``out``: ``summary.json`` (verdicts, scores, failed metrics, tracking and
assistance numbers), ``reaction.npz`` (world positions of both people, (T, 18, 3) metres)
and, unless disabled, ``report/report.html`` with timelines and a video.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from simenv.core.errors import SimenvError
from simenv.core.motion import Interaction, Motion
from simenv.data import interaction_data as idata
from simenv.learning.eval_interaction import SHARED
from simenv.models import interaction_model_entry, load
from simenv.models.reaction_baselines import MirrorActor
from simenv.plausibility import report as report_module
from simenv.plausibility.html_report import write_report
from simenv.plausibility.metric import ScoreConfig
from simenv.plausibility.planner import PLANNERS, planner_record, with_planner
from simenv.plausibility.report import score
from simenv.room.session import Session

#: Distance of the fallback start pose in front of the user, metres (a handshake's reach).
FALLBACK_DISTANCE_M = 1.0


def user_motion(session: str | os.PathLike[str] | Motion) -> Motion:
    """The session's person on the 18-keypoint layout at 25 fps.

    Raises:
        SimenvError: no such file or asset, a two-person file, too few frames.
    """
    motion = Session.load(session).motion
    motion = idata.to_layout(motion)
    motion.require_frames(2, "a reaction rehearsal")
    return motion.resample(idata.TARGET_FPS) if motion.fps != idata.TARGET_FPS else motion


def start_pose(user_first: np.ndarray, train: idata.InteractionWindows | None
               ) -> tuple[np.ndarray, dict[str, Any]]:
    """The reactor's first frame for a user whose first frame is ``user_first``.

    Args:
        user_first: (18, 3) the user's first frame in its own actor frame, metres.
        train: training windows for the nearest-neighbour start; None for the fallback.

    Returns:
        ((18, 3) reactor first frame in the same frame, provenance dict).
    """
    if train is not None and len(train):
        d = np.linalg.norm((train.actor[:, 0] - user_first[None]).reshape(len(train), -1),
                           axis=1)
        k = int(np.argmin(d))
        rec = str(train.recording_names[train.recording[k]])
        return train.reactor[k, 0].astype(np.float64), {
            "method": "nearest training window", "recording": rec,
            "start_frame": int(train.start[k]), "pose_distance_m": float(d[k])}
    # The mirror geometry needs a reactor frame: the user's pose turned to face it from
    # FALLBACK_DISTANCE_M ahead (+x is the actor's facing in its own frame).
    facing = user_first * np.array([-1.0, -1.0, 1.0]) + np.array([FALLBACK_DISTANCE_M, 0, 0])
    pose = MirrorActor(reflect=True).generate(user_first[None, None], facing[None])[0, 0]
    return pose.astype(np.float64), {"method": "mirrored user (no corpus)",
                                     "distance_m": FALLBACK_DISTANCE_M}


def generate_reaction(user: Motion, generator: Any,
                      train: idata.InteractionWindows | None = None
                      ) -> tuple[Interaction, dict[str, Any]]:
    """The user and the generated agent as a world-frame :class:`Interaction`.

    Args:
        user: the user on the 18-keypoint layout (:func:`user_motion`).
        generator: a reaction generator (``generate(actor_window, reactor_first_frame)``).
        train: training windows for :func:`start_pose` (None: fallback start).
    """
    origin, yaw = idata.actor_frame(user.positions[:1])
    local = idata.normalise(user.positions[None], origin, yaw)[0].astype(np.float64)
    first, start = start_pose(local[0], train)
    reaction = np.asarray(generator.generate(local, first), np.float64)
    world = idata.denormalise(reaction[None], origin, yaw)[0]
    agent = Motion(world.astype(np.float32), user.fps, user.skeleton,
                   f"{getattr(generator, 'name', 'agent')} reaction",
                   {"source": user.metadata.get("source"), "generator":
                    getattr(generator, "name", type(generator).__name__)})
    inter = Interaction(user, agent, label=None, roles_known=True,
                        name=f"{user.name} + {agent.name}",
                        metadata={"start": start})
    return inter, start


def _training_windows(shared: Path) -> idata.InteractionWindows | None:
    if not shared.is_dir():
        return None
    windows = idata.make_windows(idata.load_recordings(shared))
    return windows.subset(idata.split_by_recording(windows).train)


def rehearse_reaction(session: str | os.PathLike[str] | Motion, model: str | Any,
                      out: str | os.PathLike[str], *, shared: str | os.PathLike[str] |
                      None = None, seconds: float | None = None, report: bool = True,
                      video: bool = True, progress: bool = False,
                      config: ScoreConfig | None = None) -> dict[str, Any]:
    """Generate, track and score the agent's reaction to ``session`` (module docstring).

    Args:
        session: motion file, bundled asset name or Motion (one person).
        model: a shipped reaction generator's name (``interformer``, ``reactive-gan``) or
            any object with ``generate``.
        out: output folder (created).
        shared: corpus root for the start pose (default: ``SIMENV_SHARED_DATA`` or the
            repository's ``../shared/data``).
        seconds: use only the first ``seconds`` of the session.
        report, video: write ``report/report.html`` (and its video).
        progress: say each step on stderr as it starts, with the time so far.
        config: the scorer's settings (default: ``simenv score``'s); e.g. the fast planner,
            :func:`simenv.plausibility.planner.with_planner`. The summary records the
            planner (``scoring``).

    Returns:
        the summary written to ``summary.json``.

    Raises:
        SimenvError: unknown model or a model that is not a reaction generator, bad
            session, ``seconds`` not positive.
    """
    t0 = time.perf_counter()
    name = model if isinstance(model, str) else type(model).__name__

    def step(k: int, text: str) -> None:
        if progress:
            print(f"rehearse {name} [{k}/4, {time.perf_counter() - t0:.0f} s]: {text}",
                  file=sys.stderr, flush=True)

    if isinstance(model, str):
        interaction_model_entry(model, ("reaction",), field="agent")
        model = load(model)
    user = user_motion(session)
    if seconds is not None:
        if not seconds > 0:
            raise SimenvError(f"seconds must be > 0; got {seconds!r}", field="seconds")
        user = user.slice(0, max(2, int(round(seconds * user.fps))))
    corpus = Path(shared or SHARED)
    step(1, f"the agent's start pose from the training windows under {corpus}")
    windows = _training_windows(corpus)
    step(2, f"generating the reaction to {user.num_frames} frames ({user.duration:.1f} s)")
    inter, start = generate_reaction(user, model, windows)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out / "reaction.npz", user=inter.actor.positions,
                        agent=inter.reactor.positions, fps=np.float64(user.fps),
                        joints=np.array(idata.INTER18_JOINTS))
    # The scorer shows no progress of its own: this step is most of the run (measured
    # 361 s for the 2.9-s bundled walk, two people, on a shared 2-core machine).
    step(3, "scoring both people with physics: retargeting, then unassisted MPC tracking "
         "of each (the long step: minutes per second of motion)")
    config = config or report_module.DEFAULT_SCORE_CONFIG
    scored = score(inter, physics=True, config=config)
    agent = scored.people[1]
    pair = scored.interaction or {}
    summary = {
        "session": str(session if not isinstance(session, Motion) else session.name),
        "model": getattr(model, "name", type(model).__name__),
        "frames": user.num_frames, "fps": user.fps, "start": start,
        "agent": {"verdict": agent.verdict, "score": agent.score, "failed": agent.failed,
                  "metrics": {k: {"value": m.value, "threshold": m.threshold,
                                  "passed": m.passed, "unit": m.unit}
                              for k, m in agent.metrics.items()}},
        "user": {"verdict": scored.people[0].verdict, "score": scored.people[0].score},
        "interaction": {"verdict": scored.verdict, **{
            k: {"value": m.value, "passed": m.passed} for k, m in pair.items()}},
        "scoring": planner_record(config),
        "seconds": time.perf_counter() - t0,
    }
    if report:
        step(4, "writing the report" + (" and its video" if video else ""))
        summary["report"] = str(write_report(scored, out / "report", video=video))
    (out / "summary.json").write_text(json.dumps(summary, indent=1, default=_json) + "\n")
    return summary


def _json(x: Any) -> Any:
    if isinstance(x, np.generic):
        return x.item()
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")


#: ``--planner``'s help, shared with ``simenv rehearse``'s parser.
PLANNER_HELP = ("the physics tracking's planner (simenv.plausibility.planner): default, "
                "simenv score's, or fast (simenv.control.FAST: a quarter of the rolled-out "
                "steps, less close tracking; docs/tracking_speed.md)")


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m simenv.envs.reaction_rehearsal SESSION --agent MODEL --out DIR``; 2 on a user
    error."""
    ap = argparse.ArgumentParser(prog="simenv rehearse SESSION --agent MODEL",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("session", help="motion file or bundled asset name (one person)")
    ap.add_argument("--agent", required=True, help="reaction generator (interformer, "
                    "reactive-gan)")
    ap.add_argument("--out", required=True, help="output folder")
    ap.add_argument("--seconds", type=float, help="only the first SECONDS of the session")
    ap.add_argument("--shared", help="corpus root for the start pose")
    ap.add_argument("--no-render", action="store_true", help="no video in the report")
    ap.add_argument("--planner", choices=PLANNERS, default="default", help=PLANNER_HELP)
    return run_args(ap.parse_args(argv))


def run_args(args: argparse.Namespace) -> int:
    """Rehearse with parsed options (``session``, ``agent``, ``out``, ``seconds``,
    ``shared``, ``no_render``, ``planner``: those of :func:`main`), print the one-line
    summary; 2 on a user error."""
    import torch  # heavy; the generator loaded later imports it anyway, here it gets 1 thread

    torch.set_num_threads(1)
    try:
        config = with_planner(report_module.DEFAULT_SCORE_CONFIG, args.planner)
        s = rehearse_reaction(args.session, args.agent, args.out, shared=args.shared,
                              seconds=args.seconds, video=not args.no_render, progress=True,
                              config=config)
    except SimenvError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    a = s["agent"]
    print(f"{s['model']} answering {s['session']} ({s['frames']} frames): agent "
          f"{a['verdict']} (score {a['score']:.0f}; failed: {', '.join(a['failed']) or 'none'}"
          f"); interaction {s['interaction']['verdict']}; outputs in {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
