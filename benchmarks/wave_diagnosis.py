"""What the recogniser is shown as ``wave``, per source (issue 34: MSR Action3D's waves,
75 clips, were read as ``wave`` 6 times by the network that never saw MSR Action3D).

For every ``wave`` clip of the cross-dataset corpus (the three room corpora and, with
``--kindergator``, Kinder-Gator's waves) the script measures, on the clip normalised as
the recogniser reads it (:func:`simenv.data.gestures.normalise_windows` over the whole clip,
then :func:`simenv.data.sensor_invariance.canonical_body`: metres of the reference body,
x forward, y to the person's left, z up, origin the first frames' spine):

* the clip's length, s, and the source frame rate;
* which arm waves: each wrist's path length relative to the spine; ``one hand`` when
  the other wrist travels less than :data:`TWO_HAND_RATIO` of it, the hand named (``left`` /
  ``right`` as the reader labels it);
* the waving wrist's height over the head: median over the clip, and the share of frames
  it is above the head;
* the direction of its motion: the share of its path that is vertical (z) against
  sideways (y) and forward (x);
* its dominant frequency, Hz (largest peak of the spectrum of its sideways position).

``--json FILE`` writes the per-source medians; ``--plot FILE`` draws, per source, the
waving wrist's height over the head against time for every clip.
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from simenv.core.config import shared_data_root
from simenv.data.gestures import (
    GESTURE15_JOINTS,
    GESTURE_FPS,
    load_gesture_clips,
    normalise_windows,
)
from simenv.data.sensor_invariance import canonical_body
from simenv.learning.cross_dataset import kinder_gator_clips

#: The other wrist travelling less than this share of the waving wrist's path: one hand.
TWO_HAND_RATIO = 0.5
_J = {n: i for i, n in enumerate(GESTURE15_JOINTS)}


def measure(positions: np.ndarray, fps: float = GESTURE_FPS) -> dict[str, Any]:
    """The measures of the module docstring for one clip ((T, 15, 3) metres, Z up)."""
    x = canonical_body(normalise_windows(positions))
    rel = {s: x[:, _J[f"{s}_wrist"]] - x[:, _J["spine"]] for s in ("left", "right")}
    travel = {s: float(np.linalg.norm(np.diff(rel[s], axis=0), axis=-1).sum()) for s in rel}
    hand = max(travel, key=travel.__getitem__)
    other = "left" if hand == "right" else "right"
    w = x[:, _J[f"{hand}_wrist"]]
    over = w[:, 2] - x[:, _J["head"], 2]
    step = np.abs(np.diff(w, axis=0)).sum(axis=0)
    side = w[:, 1] - w[:, 1].mean()
    spectrum = np.abs(np.fft.rfft(side * np.hanning(len(side)))) if len(side) > 4 else None
    freqs = np.fft.rfftfreq(len(side), 1.0 / fps)
    peak = (float(freqs[1:][np.argmax(spectrum[1:])]) if spectrum is not None
            and len(spectrum) > 1 else float("nan"))
    return {"seconds": len(positions) / fps,
            "hands": "two" if travel[other] >= TWO_HAND_RATIO * travel[hand] else hand,
            "over_head_median_m": float(np.median(over)),
            "above_head_share": float((over > 0).mean()),
            "vertical_share": float(step[2] / max(step.sum(), 1e-9)),
            "sideways_share": float(step[1] / max(step.sum(), 1e-9)),
            "frequency_hz": peak}


def diagnose(clips: list[Any]) -> dict[str, dict[str, Any]]:
    """Per (dataset, source class) of the ``wave`` clips: clip count, source frame rate,
    hands used (counts) and the medians of :func:`measure`."""
    rows: dict[str, list[dict[str, Any]]] = defaultdict(list)
    fps: dict[str, float] = {}
    for c in clips:
        if c.label != "wave":
            continue
        key = f"{c.dataset}: {c.source_label}"
        rows[key].append(measure(c.positions))
        fps[key] = round(float(c.source.fps), 1) if c.source is not None else GESTURE_FPS
    out = {}
    for key, r in rows.items():
        hands: dict[str, int] = defaultdict(int)
        for m in r:
            hands[m["hands"]] += 1
        out[key] = {"clips": len(r), "source_fps": fps[key], "hands": dict(hands),
                    **{k: round(float(np.nanmedian([m[k] for m in r])), 3)
                       for k in r[0] if k != "hands"}}
    return out


def table(result: dict[str, dict[str, Any]]) -> str:
    """Markdown table of :func:`diagnose`."""
    lines = ["| source | clips | source fps | hands (as labelled) | length, s | waving wrist "
             "over the head, m (median) | frames wrist above head | path vertical / "
             "sideways | frequency, Hz |", "|---|---|---|---|---|---|---|---|---|"]
    for key, r in result.items():
        hands = ", ".join(f"{k} {v}" for k, v in sorted(r["hands"].items()))
        lines.append(f"| {key} | {r['clips']} | {r['source_fps']:g} | {hands} | "
                     f"{r['seconds']:.2f} | {r['over_head_median_m']:+.2f} | "
                     f"{r['above_head_share']:.0%} | {r['vertical_share']:.2f} / "
                     f"{r['sideways_share']:.2f} | {r['frequency_hz']:.2f} |")
    return "\n".join(lines)


def plot(clips: list[Any], path: Path) -> None:
    """Per source, the waving wrist's height over the head (m, canonical body) against
    time for every clip."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups: dict[str, list[np.ndarray]] = defaultdict(list)
    for c in clips:
        if c.label == "wave":
            x = canonical_body(normalise_windows(c.positions))
            travel = {s: np.linalg.norm(np.diff(x[:, _J[f"{s}_wrist"]] - x[:, _J["spine"]],
                                                axis=0), axis=-1).sum()
                      for s in ("left", "right")}
            hand = max(travel, key=travel.__getitem__)
            groups[f"{c.dataset}: {c.source_label}"].append(
                x[:, _J[f"{hand}_wrist"], 2] - x[:, _J["head"], 2])
    fig, axes = plt.subplots(1, len(groups), figsize=(3.2 * len(groups), 3), sharey=True)
    for ax, (key, curves) in zip(np.atleast_1d(axes), groups.items(), strict=True):
        for h in curves:
            ax.plot(np.arange(len(h)) / GESTURE_FPS, h, lw=0.6, alpha=0.6)
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set_title(f"{key} ({len(curves)})", fontsize=8)
        ax.set_xlabel("s")
    np.atleast_1d(axes)[0].set_ylabel("waving wrist over head, m")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kindergator", help="Kinder-Gator folder (its waves are added)")
    parser.add_argument("--json", type=Path)
    parser.add_argument("--plot", type=Path)
    args = parser.parse_args()
    clips = load_gesture_clips(shared_data_root(None) / "gestures")
    if args.kindergator:
        clips += kinder_gator_clips(args.kindergator)
    result = diagnose(clips)
    print(table(result))
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))
    if args.plot:
        plot(clips, args.plot)


if __name__ == "__main__":
    main()
