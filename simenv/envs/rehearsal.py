"""Offline interaction rehearsal: replay a session in the room and record how the agent reacts.

:func:`rehearse` runs :class:`~simenv.envs.interaction_room.InteractionRoomEnv` on a session
with one of the agents below, and writes to ``out``:

* ``rehearsal.mp4`` (unless ``render=False``): the room seen from the camera of
  :meth:`~simenv.envs.interaction_room.InteractionRoomEnv.camera` (the user's front, the
  agent's face and hands), 25 fps, one frame per ``log.jsonl`` line (the state at the end of
  that step), each captioned (:func:`simenv.body.render.caption_frame`) with what the agent
  perceived: the time and labelled gesture, the last perception tick's three most probable
  classes and its stage, the last decision and the reaction executing, and each object's
  state label and level (% of its joint's range). H.264 when this OpenCV build can encode
  it, else ``mp4v``, with then the same frames in VP8 in ``rehearsal.webm`` for browsers
  (:class:`simenv.body.render.WebVideo`);
* ``log.jsonl``: one JSON line per step, flushed as it goes: ``t``, the labelled ``gesture``,
  the last perception's ``probabilities``, ``stage`` and ``predicted_motion_m``, the
  ``decision``, the reaction ``executing``, ``objects`` (states, m or rad), ``levels``
  (fractions of each joint's range), ``labels``, and the external help on the agent at
  the step, ``assistance_n`` (N) and ``assistance_bw`` (body weights): applied forces and
  torques on its bodies and free joint and equality constraints other than the hands'
  grasps (:meth:`simenv.room.room.Room.assist_wrench`). The room has no assistance mechanism
  (the agent walks on its own legs), so it reads 0 on every line;
* ``summary.json``: ``session``, ``gestures`` (the labelled ones), ``reactions`` (only those
  the agent started: ``gesture``, ``t_onset``,
  ``t_decision``, ``t_object_changed``, ``object``, ``reaction``, ``success``,
  ``t_success``; ``facing_deg_min`` for a greeting, ``grasped`` for a grasping reaction,
  ``stages`` -- each with its ``assistance`` and, for the stages on the feet, its
  ``outcome`` (``fell``, ``lowest_pelvis_m``, ``goal_error_m``, ``success``) -- the total
  ``assistance``, ``fell`` and ``failed_stage`` (a stage whose body fell ends the chain)
  for a chained reaction such as ``close_window``; ``failure``: why a reaction that did not
  succeed failed, with the measurements it cites -- see
  :class:`~simenv.envs.interaction_room.InteractionRoomEnv`),
  ``decisions`` (every decision, with ``not_started``: why it was not carried out, and for
  the scripted agent the perception ``stage`` that took it: ``real`` or ``predicted``),
  ``decision_latency_s``
  (statistics of decision time - gesture onset over labelled gestures),
  ``agent_plausibility`` (joint-level metrics of the agent's keypoints,
  :func:`simenv.plausibility.kinematic_metrics`: foot skate, ground penetration, jitter,
  ...), ``agent_physics`` (the agent's simulated contacts: deepest penetration into the
  floor, the furniture, the objects, itself and the user, and the largest assistance
  force on its bodies -- the residual force of a simulated agent, measured),
  ``perception_compute_s``, ``timing_s`` (wall time of the preparation -- retargeting,
  room --, the simulation loop -- rendering included when on -- and the outputs, and the
  loop's real-time factor), and with the video ``video``: ``file``, ``codec`` (FourCC),
  ``webm`` (the WebM copy's file or None), ``width`` and ``height`` (pixels), ``frames``;
* ``report.html``: the video (``<video>`` with relative sources ``rehearsal.webm`` and
  ``rehearsal.mp4``: keep the files together),
  a timeline of gestures, decisions and object states, the reactions started, and the
  agent's plausibility table, in the style of the plausibility reports
  (:func:`simenv.plausibility.html_report.html_page`).

Agents: ``"scripted"`` is the room's agent, :class:`~simenv.perception.room_agent.RoomAgent`
(perceive -> decide -> act) with a :class:`~simenv.perception.loop.PerceptionLoop` (predict,
classify, decide every second; by default the shipped ``gesture-tcn-ensemble`` and
``predictor-gesture-25-50``, falling back to templates from the gesture corpus and constant
velocity, :func:`simenv.perception.loop.default_classifier` /
:func:`~simenv.perception.loop.load_predictor`; ``summary.json`` names them under
``perception`` and gives each decision's ``stage``; it perceives while the recording plays,
no tick whose 1-s window lies wholly in the pose the user holds after it), ``"labels"``
decides the scenario's
reaction on the first frame of each labelled gesture (an oracle that rehearses execution
without perception errors or latency), ``"random"`` decides a seeded random
reaction at each perception tick.
"""

from __future__ import annotations

import argparse
import base64
import html
import io
import json
import os
import time
from collections.abc import Sequence
from contextlib import nullcontext
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from simenv.core.errors import SimenvError
from simenv.core.joint_map import JOINT_MAP_HELP
from simenv.core.motion import Motion
from simenv.core.skeletons import canonical_skeleton
from simenv.data.gestures import GESTURE_LABELS, load_gesture_clips
from simenv.envs.interaction_room import OBJECTS, PENETRATION_TOLERANCE_M, InteractionRoomEnv
from simenv.perception.loop import (
    FALLBACK_PREDICTOR,
    GestureModel,
    PerceptionLoop,
    TemplateClassifier,
    TrainedClassifier,
    default_classifier,
    load_predictor,
    tick_due,
    vocabulary_map,
)
from simenv.perception.room_agent import RoomAgent, Tick
from simenv.plausibility import kinematic_metrics
from simenv.plausibility.html_report import html_page
from simenv.room.scenario import REACTIONS, Scenario, load_scenario
from simenv.room.session import PERCEPTION_FPS, GestureEvent, Session, session_recipes

if TYPE_CHECKING:
    from simenv.body.render import WebVideo

AGENTS = ("scripted", "labels", "random")
#: Accepted video width and height, pixels: room for the scene under the five caption lines
#: (at least 10 px each), and within the offscreen buffers OpenGL drivers provide.
VIDEO_SIZE_RANGE = (96, 4096)


def rehearse(session: Session | str | os.PathLike[str] | Motion, out: str | os.PathLike[str],
             *, scenario: Scenario | str = "default", agent: str = "scripted",
             classifier: GestureModel | None = None, predictor: Any = "auto",
             render: bool = True, width: int = 480, height: int = 360,
             seed: int = 0, data: str | os.PathLike[str] | None = None) -> dict[str, Any]:
    """Rehearse ``session`` and write the outputs (module docstring) to ``out``.

    Args:
        session: a Session, motion file, bundled asset or recipe name, or a Motion.
        out: output folder.
        scenario: bundled scenario name or TOML file.
        agent: one of :data:`AGENTS`.
        classifier: the scripted agent's :class:`~simenv.perception.loop.GestureModel`
            (default :func:`~simenv.perception.loop.default_classifier` for the scenario's
            vocabulary).
        predictor: the perception loop's predictor,
            :func:`~simenv.perception.loop.load_predictor` (``"auto"``: the shipped
            ``predictor-gesture-25-50`` when present, else constant velocity). It runs at the
            perception ticks only: the environment's own ``user_future`` observation,
            which none of these agents reads, is the constant-velocity baseline's (the
            WGAN on every step would cost ~14 ms of each 40 ms frame).
        render, width, height: the video and its size, pixels (integers in
            :data:`VIDEO_SIZE_RANGE`; 640 x 480 for a larger view).
        seed: seed of the environment and the random agent.
        data: root of the shared corpus (session recipes, the template fallback).

    Returns:
        the summary (as written to ``summary.json``).

    Raises:
        SimenvError: unknown agent, video size outside :data:`VIDEO_SIZE_RANGE`, and the
            errors of the environment and the perception.
    """
    _check_options(agent, width, height)
    out = Path(out)
    clock = [time.perf_counter()]
    scenario = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    loop = None
    if agent == "scripted":
        if classifier is None:
            classifier = default_classifier(scenario.behaviour.vocabulary, data)
        loop = PerceptionLoop(classifier, load_predictor(predictor))
    # The user's history observed as far back as the scripted agent's ticks read it.
    history = {} if loop is None else {"history_frames": loop.history_frames}
    env = InteractionRoomEnv(session, scenario=scenario, predictor=FALLBACK_PREDICTOR,
                             render_mode="rgb_array" if render else None,
                             width=width, height=height, data=data, **history)
    room_agent = None if loop is None else env.room_agent(loop)
    out.mkdir(parents=True, exist_ok=True)
    episode = _Episode(env, agent, room_agent, np.random.default_rng(seed))
    observation, _ = env.reset(seed=seed)
    clock.append(time.perf_counter())
    video = episode.play(out, render, observation)
    clock.append(time.perf_counter())
    env.close()
    ticks = [] if room_agent is None else room_agent.ticks
    summary = _summary(env, np.array(episode.agent_kp), ticks)
    if video is not None:
        summary["video"] = {"file": video.mp4.path.name, "codec": video.mp4.codec,
                            "webm": None if video.webm is None else video.webm.path.name,
                            "width": width, "height": height, "frames": video.mp4.count}
    if room_agent is not None:
        ahead = loop.predictor
        summary["perception"] = {
            "classifier": getattr(classifier, "name", type(classifier).__name__),
            "predictor": getattr(ahead, "name", type(ahead).__name__),
            "real_frames": loop.real_frames, "context_frames": list(loop.context_frames),
            "window_rule": loop.window_rule, "period": loop.period,
            "threshold": loop.threshold, "cooldown_s": room_agent.cooldown_s}
    summary["agent_physics"] = _physics(np.array(episode.depths), episode.assistance)
    _report(out, summary)
    clock.append(time.perf_counter())
    prep, loop_s, outputs = np.diff(clock)
    summary["timing_s"] = {"preparation": prep, "loop": loop_s, "outputs": outputs,
                           "loop_real_time_factor": summary["duration_s"] / loop_s}
    (out / "summary.json").write_text(json.dumps(summary, indent=2), encoding="utf-8")
    return summary


def _check_options(agent: str, width: int, height: int) -> None:
    """Refuse an unknown agent or a video size outside :data:`VIDEO_SIZE_RANGE`."""
    if agent not in AGENTS:
        raise SimenvError(f"unknown agent {agent!r}; expected one of {list(AGENTS)}",
                          field="agent")
    low, high = VIDEO_SIZE_RANGE
    for name, size in (("width", width), ("height", height)):
        if not isinstance(size, int | np.integer) or isinstance(size, bool) \
                or not low <= size <= high:
            raise SimenvError(f"video {name} {size!r}; expected a whole number of pixels "
                              f"from {low} to {high}", field=name)


@dataclass
class _Episode:
    """The simulation loop of a rehearsal: each step the agent decides (:meth:`decide`),
    the environment steps, and what happened is measured and written (:meth:`record`,
    :meth:`play`); the measurements the summary needs are kept here."""

    env: InteractionRoomEnv
    agent: str
    #: The scripted agent (None for the oracle and the random agent).
    room_agent: RoomAgent | None
    rng: np.random.Generator
    #: The last decision with its time, s.
    decided: tuple[str, float] | None = None
    #: Labelled gestures the oracle answered (indexes into the session's gestures).
    answered: set[int] = field(default_factory=set)
    #: Per step: the agent's keypoints (K, 3), m, and its penetration depths (5,), m; the
    #: largest assistance force on the agent, N.
    agent_kp: list[np.ndarray] = field(default_factory=list)
    depths: list[list[float]] = field(default_factory=list)
    assistance: float = 0.0

    def decide(self, step: int, observation: dict[str, np.ndarray]) -> int:
        """The action index at ``step`` (0: none) given the environment's ``observation``:
        the scripted agent's (:meth:`RoomAgent.act`), the oracle's answer to a labelled
        gesture, or the random agent's draw at a perception tick."""
        if self.room_agent is not None:
            return self.room_agent.act(observation)
        if self.agent == "labels":
            return _oracle(self.env, step / PERCEPTION_FPS, self.answered)
        if self.agent == "random" and tick_due(step):
            return int(self.rng.integers(0, self.env.action_space.n))
        return 0

    def record(self, t: float, action: int, info: dict[str, Any]) -> dict[str, Any]:
        """Measure the step just taken at time ``t`` (s) and return its ``log.jsonl`` line
        (module docstring)."""
        env = self.env
        last = None if self.room_agent is None or self.room_agent.last is None \
            else self.room_agent.last.perception
        self.agent_kp.append(env.room.agent_keypoints(env.data))
        self.depths.append(list(env.agent_penetration().values()))
        help_n = env.agent_assistance_n()
        self.assistance = max(self.assistance, help_n)
        weight = env.room.agent.total_mass * 9.81  # N, for assistance as a fraction of it
        return {
            "t": round(t, 4), "gesture": info.get("gesture"),
            "probabilities": None if last is None else last.probabilities,
            "stage": None if last is None else last.stage.value,
            "predicted_motion_m": None if last is None else last.predicted_motion_m,
            "decision": env.reactions[action], "executing": info.get("executing"),
            "objects": env.room.object_states(env.data),
            "levels": dict(zip(OBJECTS, map(float, env.object_levels()), strict=True)),
            "labels": info.get("object_labels"),
            "assistance_n": help_n, "assistance_bw": help_n / weight,
        }

    def play(self, out: Path, render: bool, observation: dict[str, np.ndarray]
             ) -> WebVideo | None:
        """Run the environment, just reset to ``observation``, and the agent to the
        episode's end, writing ``log.jsonl`` and with ``render`` the captioned video in
        ``out``; the video writer (:class:`simenv.body.render.WebVideo`, closed) or None."""
        env, video = self.env, None
        if render:
            # The video writer loads OpenCV: only a rendered rehearsal needs it.
            from simenv.body.render import WebVideo, caption_frame

            # Written as it goes: a long session's frames would not fit in memory.
            video = WebVideo(out / "rehearsal.mp4", PERCEPTION_FPS)
        step, done = 0, False
        with (out / "log.jsonl").open("w", encoding="utf-8") as log, video or nullcontext():
            while not done:
                t = step / PERCEPTION_FPS
                action = self.decide(step, observation)
                observation, _, _, done, info = env.step(action)
                if action:
                    self.decided = (env.reactions[action], t)
                step += 1
                row = self.record(t, action, info)
                log.write(json.dumps(row) + "\n")
                log.flush()
                if video is not None:
                    video.write(caption_frame(env.render(), _caption(row, self.decided)))
        return video


def _caption(row: dict[str, Any], decided: tuple[str, float] | None) -> list[str]:
    """The caption lines of the video frame of ``log.jsonl`` line ``row``: time (s) and
    labelled gesture; the last perception tick's three most probable classes with their
    probabilities and its stage; the last decision ``decided`` (reaction, time in s) and
    the reaction executing; each object's state label and level (% of its joint's range)."""
    best = sorted((row["probabilities"] or {}).items(), key=lambda kv: -kv[1])[:3]
    perceived = "  ".join(f"{label} {p:.2f}" for label, p in best) or "-"
    stage = f" ({row['stage']})" if row["stage"] else ""
    decision = "-" if decided is None else f"{decided[0]} at {decided[1]:.2f} s"
    labels = row["labels"] or {}  # None on a step whose physics diverged
    objects = [f"{name} {labels.get(name, '?')} {100 * row['levels'][name]:.0f}%"
               for name in OBJECTS]
    return [f"t {row['t']:.2f} s   labelled gesture: {row['gesture'] or '-'}",
            f"perceived{stage}: {perceived}",
            f"decision: {decision}   executing: {row['executing'] or '-'}",
            "   ".join(objects[:3]), "   ".join(objects[3:])]


def _oracle(env: InteractionRoomEnv, t: float, answered: set[int]) -> int:
    """The scenario's reaction to the first unanswered labelled gesture under way."""
    for i, g in enumerate(env.session.gestures):
        if i not in answered and g.onset_s <= t <= g.end_s:
            answered.add(i)
            reaction = env.scenario.behaviour.reaction_for(g.label).name
            return env.reactions.index(reaction) if reaction in env.reactions else 0
    return 0


def _summary(env: InteractionRoomEnv, agent_kp: np.ndarray,
             ticks: list[Tick]) -> dict[str, Any]:
    reactions, latencies = [], []
    for entry in env.log:
        if not entry["started"]:
            continue
        onset = next((g.onset_s for g in env.session.gestures
                      if g.label == entry["gesture"] and g.onset_s <= entry["t_decision"]),
                     None)
        if onset is not None:
            latencies.append(entry["t_decision"] - onset)
        reaction = {"gesture": entry["gesture"], "t_onset": onset,
                    "t_decision": entry["t_decision"],
                    "t_object_changed": entry["t_object_changed"],
                    "object": REACTIONS[entry["reaction"]].object,
                    "reaction": entry["reaction"], "success": entry["success"],
                    "t_success": entry["t_success"]}
        # greeting / grasping / chained (stand, walk, act; measured help, falls) reactions
        for key in ("facing_deg_min", "dip_max_deg", "grasped", "stages", "assistance",
                    "returned", "fell", "failed_stage", "failure", "object_level_start",
                    "object_level_best", "hand_distance_min_m", "t_hand_closest",
                    "hand_raised", "user_contact"):
            if key in entry:
                reaction[key] = entry[key]
        reactions.append(reaction)
    lat = np.array(latencies)
    motion = Motion(agent_kp.astype(np.float32), PERCEPTION_FPS, canonical_skeleton(),
                    name="agent")
    metrics = kinematic_metrics(motion) if len(agent_kp) >= 3 else {}
    compute = np.array([tick.perception.compute_s for tick in ticks])
    # The tick whose reaction became the decision (steps are 1/25 s: match to the step).
    stage = {tick.step: tick.perception.stage.value for tick in ticks if tick.reaction}
    return {
        "session": env.session.motion.name, "scenario": env.scenario.name,
        "duration_s": len(agent_kp) / PERCEPTION_FPS,
        "gestures": [{"label": g.label, "onset_s": g.onset_s, "end_s": g.end_s}
                     for g in env.session.gestures],
        "reactions": reactions,
        "decisions": [{"t_decision": e["t_decision"], "reaction": e["reaction"],
                       "started": e["started"], "not_started": e["not_started"],
                       **({"stage": stage.get(round(e["t_decision"] * PERCEPTION_FPS))}
                          if ticks else {})}
                      for e in env.log],
        "decision_latency_s": {"n": int(lat.size),
                               **({"mean": float(lat.mean()), "median": float(np.median(lat)),
                                   "max": float(lat.max())} if lat.size else {})},
        "agent_plausibility": {name: {"value": float(m.value), "unit": m.unit,
                                      "passed": m.passed} for name, m in metrics.items()},
        "perception_compute_s": {"n": int(compute.size),
                                 **({"mean": float(compute.mean()),
                                     "max": float(compute.max())} if compute.size else {})},
    }


def _physics(depths: np.ndarray, assistance: float) -> dict[str, Any]:
    """The agent's simulated contacts over the session: per kind of contact (columns of
    ``depths`` (T, 5), m, in :meth:`InteractionRoomEnv.agent_penetration` order) the
    deepest penetration and the 95th percentile over steps, and the steps deeper than
    :data:`PENETRATION_TOLERANCE_M`; and the largest assistance force, N (external force
    on the agent's bodies: the residual force a simulated agent needs; none here)."""
    kinds = ("floor", "furniture", "object", "self", "user")
    d = depths.reshape(-1, len(kinds))
    return {
        "penetration_m": {k: {"max": float(d[:, i].max(initial=0.0)),
                              "p95": float(np.percentile(d[:, i], 95)) if len(d) else 0.0,
                              "steps_over_tolerance": int((d[:, i]
                                                           > PENETRATION_TOLERANCE_M).sum())}
                          for i, k in enumerate(kinds)},
        "tolerance_m": PENETRATION_TOLERANCE_M,
        "assistance_max_n": float(assistance),
    }


def _report(out: Path, summary: dict[str, Any]) -> None:
    """``report.html``: the video, the timeline (from ``log.jsonl``), the reactions and
    the plausibility table."""
    e = html.escape
    rows = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    image = _timeline_png(rows, summary["decisions"])
    reactions = "".join(
        "<tr>" + "".join(_cell(r[c]) for c in (
            "gesture", "t_onset", "t_decision", "reaction", "object", "t_object_changed",
            "t_success")) + _verdict(r["success"]) + _cell(r.get("failure")) + "</tr>"
        for r in summary["reactions"])
    title = f"simenv rehearsal: {summary['session']}"
    (out / "report.html").write_text(html_page(title, f"""
<h1>Rehearsal of {e(summary['session'])} ({e(summary['scenario'])})</h1>
<h2>Video</h2>{_film(summary.get('video'))}
<h2>Timeline</h2><img class="timeline" src="data:image/png;base64,{image}" alt="timeline">
<h2>Reactions started</h2><table><tr><th>gesture</th><th>onset (s)</th>
<th>decision (s)</th><th>reaction</th><th>object</th><th>object changed (s)</th>
<th>success measured (s)</th><th>success</th><th>why it failed</th></tr>{reactions}</table>
<h2>Agent plausibility</h2><table><tr><th>metric</th><th>value</th><th>verdict</th>
</tr>{_plausibility_rows(summary)}</table>
"""), encoding="utf-8")


def _timeline_png(rows: list[dict[str, Any]], decisions: list[dict[str, Any]]) -> str:
    """The report's timeline figure, base64 PNG: the labelled gestures as bands and the
    decisions as lines (black when started) over the ``log.jsonl`` lines ``rows``, and
    each object's level (fraction of its joint's range) below."""
    import matplotlib  # heavy, and only the report's figure needs it

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.array([r["t"] for r in rows])
    fig, axes = plt.subplots(2, 1, figsize=(9, 4.5), sharex=True)
    gestures = sorted({r["gesture"] for r in rows if r["gesture"]})
    for k, g in enumerate(gestures):
        on = np.array([r["gesture"] == g for r in rows])
        axes[0].fill_between(t, k, k + 0.8, where=on, step="post", alpha=0.5)
        axes[0].text(t[np.argmax(on)], k + 0.3, g, fontsize=8)
    for d in decisions:
        axes[0].axvline(d["t_decision"], color="k" if d["started"] else "grey", lw=1)
        axes[0].text(d["t_decision"], len(gestures) + 0.1, d["reaction"], fontsize=7,
                     rotation=60)
    axes[0].set_yticks([])
    axes[0].set_title("gestures (bands) and decisions (lines; black = started)")
    for name in OBJECTS:
        axes[1].plot(t, [r["levels"][name] for r in rows], label=name)
    axes[1].set_xlabel("time (s)")
    axes[1].set_ylabel("object state (fraction of range)")
    axes[1].set_ylim(-0.05, 1.05)
    axes[1].legend(fontsize=7, ncol=5)
    buf = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode()


def _verdict(passed: bool | str | None) -> str:
    """A verdict cell: pass / fail, or a reason it is not judged (``n/a`` for None)."""
    e = html.escape
    if passed is None or isinstance(passed, str):  # not available, or not judged
        return f"<td class='na'>{e(passed or 'n/a')}</td>"
    return f"<td class='{'pass' if passed else 'fail'}'>{'pass' if passed else 'fail'}</td>"


def _cell(value: Any) -> str:
    """A table cell of the reactions: a dash for None, a time (s) for a float, else text."""
    if value is None:  # not applicable, or never happened
        return "<td class='na'>&ndash;</td>"
    if isinstance(value, float):  # a time, s
        return f"<td class='num'>{value:.2f}</td>"
    return f"<td>{html.escape(str(value))}</td>"


def _plausibility_rows(summary: dict[str, Any]) -> str:
    """The plausibility table's rows: the joint-level metrics, then the agent's physics
    (penetration per kind of contact, the largest assistance force) when measured."""
    e = html.escape
    table = "".join(
        f"<tr><td>{e(k)}</td><td class='num'>{v['value']:.4g} {e(v['unit'])}</td>"
        f"{_verdict(v['passed'])}</tr>" for k, v in summary["agent_plausibility"].items())
    phys = summary.get("agent_physics")
    if phys is not None:
        table += "".join(
            f"<tr><td>penetration into {e(k)} (max / p95)</td>"
            f"<td class='num'>{1000 * v['max']:.1f} / {1000 * v['p95']:.1f} mm</td>"
            + _verdict(v["steps_over_tolerance"] == 0 if k != "user" else "n/a (user pushes)")
            + "</tr>" for k, v in phys["penetration_m"].items())
        table += (f"<tr><td>assistance force (max)</td><td class='num'>"
                  f"{phys['assistance_max_n']:.3g} N</td>"
                  f"{_verdict(phys['assistance_max_n'] == 0)}</tr>")
    return table


def _film(video: dict[str, Any] | None) -> str:
    """The report's video section for the summary's ``video`` entry (None: not rendered)."""
    e = html.escape
    if video is None:
        return "<p class='na'>No video (rendering was off).</p>"
    # Relative sources, the browser's pick first (it plays H.264 and VP8, not mp4v):
    # the folder can be moved or served as is.
    sources = [(video["file"], "video/mp4"), (video["webm"], "video/webm")]
    if video["codec"] != "avc1":
        sources.reverse()
    return ("<video controls muted width='{}' height='{}'>{}</video>".format(
                video["width"], video["height"],
                "".join(f"<source src='{e(src)}' type='{kind}'>" for src, kind in sources
                        if src))
            + "<p class='small'>The room as the agent sees it; captions: the time, the "
            "labelled gesture, the last perception tick's three most probable classes "
            "and its stage (real or predicted frames), the last decision, the reaction "
            "executing, and the objects' states. "
            f"<a href='{e(video['file'])}'>Download the MP4</a> "
            f"({e(video['codec'])}).</p>")


def _gesture(text: str) -> GestureEvent:
    try:
        label, onset, end = text.split(":")
        return GestureEvent(label, float(onset), float(end))
    except ValueError:
        raise SimenvError(f"--gesture {text!r}: expected LABEL:ONSET_S:END_S",
                          field="gesture") from None


def add_arguments(parser: argparse.ArgumentParser, generators: Sequence[str] = ()) -> None:
    """The rehearsal's options, on ``parser``; ``generators`` (reaction generator names,
    which ``simenv rehearse`` hands to :mod:`simenv.envs.reaction_rehearsal`) join the
    choices of ``--agent``."""
    parser.add_argument("session", help="motion file, bundled asset name, or session recipe "
                        "(.toml or a bundled recipe name: "
                        f"{', '.join(session_recipes()) or 'none'})")
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--joint-map", metavar="FILE.toml", help=JOINT_MAP_HELP)
    parser.add_argument("--agent", choices=(*AGENTS, *generators), default="labels",
                        help="who reacts: scripted (perceives with the recogniser and the "
                        "forecaster), labels (an oracle acting on the labelled gestures) or "
                        "random (a seeded random reaction each second)"
                        + (f"; {', '.join(generators)}: a reaction generator answers the "
                           "session on open floor (tracked and scored)" if generators else ""))
    parser.add_argument("--scenario", default="default", help="bundled name or TOML file")
    parser.add_argument("--gesture", action="append", type=_gesture, default=[],
                        metavar="LABEL:ONSET_S:END_S", help="a labelled gesture (repeatable)")
    parser.add_argument("--data", help="root of the shared corpus (session recipes, "
                        "templates); default $SIMENV_SHARED_DATA or ../shared/data")
    parser.add_argument("--predictor", default="auto", help="perception predictor: a shipped "
                        "predictor-* name or constant-velocity-50 (default: "
                        "predictor-gesture-25-50 when shipped)")
    parser.add_argument("--classifier", help="shipped classifier name for the scripted agent "
                        "(default: gesture-tcn-ensemble when shipped, else templates)")
    parser.add_argument("--templates", help="gesture recordings folder (msr_action3d/, "
                        "utkinect/, florence3d/): the scripted agent classifies with "
                        "nearest-neighbour templates from it instead")
    parser.add_argument("--no-render", action="store_true", help="skip the video")
    parser.add_argument("--width", type=int, default=480, help="video width, pixels "
                        "(default 480; e.g. 640 with --height 480)")
    parser.add_argument("--height", type=int, default=360, help="video height, pixels "
                        "(default 360)")


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m simenv.envs.rehearsal SESSION --out DIR [...]`` (``--help`` lists options)."""
    parser = argparse.ArgumentParser(prog="python -m simenv.envs.rehearsal",
                                     description=__doc__.splitlines()[0])
    add_arguments(parser)
    return run_args(parser.parse_args(argv))


def run_args(args: argparse.Namespace) -> int:
    """Rehearse with the options of :func:`add_arguments`; prints the summary line, 0."""
    scenario = load_scenario(args.scenario)
    vocabulary = scenario.behaviour.vocabulary
    classifier = None
    if args.templates:
        classifier = TemplateClassifier.from_clips(load_gesture_clips(args.templates),
                                                   vocabulary_map(GESTURE_LABELS, vocabulary))
    elif args.classifier:
        classifier = TrainedClassifier.shipped(args.classifier, vocabulary)
    session = Session.load(args.session, args.gesture, data=args.data,
                           joint_map=args.joint_map)
    summary = rehearse(session, args.out, scenario=scenario, agent=args.agent,
                       classifier=classifier, predictor=args.predictor,
                       render=not args.no_render, width=args.width,
                       height=args.height, data=args.data)
    print(outcome_lines(summary, args.out))
    return 0


def outcome_lines(summary: dict[str, Any], out: str | os.PathLike[str]) -> str:
    """The rehearsal's result for people: how many reactions started and succeeded, why
    each one that did not succeed failed, and why decisions were not carried out."""
    reactions = summary["reactions"]
    done = sum(bool(r["success"]) for r in reactions)
    lines = [f"{len(reactions)} reaction(s) started, {done} succeeded; outputs in {out}"]
    for r in reactions:
        if not r["success"]:
            lines.append(f"  {r['reaction']} (decided at {r['t_decision']:.2f} s) "
                         f"{'failed' if r['success'] is False else 'was not judged'}: "
                         f"{r.get('failure') or 'no reason recorded'}")
    skipped: dict[str, int] = {}
    for d in summary["decisions"]:
        if not d["started"]:
            why = f"{d['reaction']}: {d['not_started']}"
            skipped[why] = skipped.get(why, 0) + 1
    lines += [f"  not carried out ({n}x) {why}" for why, n in skipped.items()]
    return "\n".join(lines)


__all__ = ["AGENTS", "VIDEO_SIZE_RANGE", "add_arguments", "main", "outcome_lines", "rehearse",
           "run_args"]


if __name__ == "__main__":
    raise SystemExit(main())
