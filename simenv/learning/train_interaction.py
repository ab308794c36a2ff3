"""Train a two-person model on the real recordings (``simenv train interaction``).

``python -m simenv.learning.train_interaction --model NAME [--config FILE] [--shared PATH]
[--out DIR] [--seed N] [--quiet]`` trains one of
:data:`simenv.models.INTERACTION_MODELS` (``interformer``, ``reactive-gan``,
``bigraphdiff``, ``interaction-augment``) on the training recordings and writes to
``--out`` (default ``out/train-interaction/NAME``):

* ``NAME.npz``: the checkpoint (arrays only; copy it to ``assets/models/`` to ship it,
  :func:`simenv.models.load` then finds it by name);
* ``NAME.md``: the model card (data, split, configuration, loss curve, held-out metrics);
* ``history.json`` and ``loss.png``: the per-epoch losses.

Data and split are those of the evaluation (:mod:`simenv.learning.eval_interaction`): CMU pairs
and NuiSI repetitions at 25 fps on 18 keypoints, 40-frame windows every 5 frames in the
actor's frame, :data:`~simenv.data.interaction_data.DEFAULT_TEST_RECORDINGS` held out by
recording. ``--config FILE`` (TOML or JSON) is a flat table of the model's configuration
fields (its ``<Class>Config`` dataclass), e.g. ``epochs = 40``; an unknown field is an
error that lists the known ones.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import json
import sys
import time
from collections import Counter
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from simenv.core.config import read_options
from simenv.core.errors import SimenvError
from simenv.data import interaction_data as idata
from simenv.data import interaction_metrics as im
from simenv.data.augment_targets import build_targets
from simenv.learning.eval_interaction import SHARED, reaction_metrics
from simenv.learning.interaction_features import default_feature_extractor
from simenv.models import INTERACTION_MODELS, interaction_model_entry
from simenv.models.reaction_baselines import ZeroVelocity

#: Held-out metrics reported on the card of a reaction generator: (key, label, format).
CARD_METRICS: tuple[tuple[str, str, str], ...] = (
    ("AFD", "AFD (m²)", "{:.3f}"), ("E_r_mm", "E_r (mm)", "{:.0f}"),
    ("E_b_mm", "E_b (mm)", "{:.1f}"), ("JPD_mm", "JPD (mm)", "{:.0f}"),
    ("contact_retention", "contact retention", "{:.2f}"), ("FVD", "FVD", "{:.3f}"),
)


def config_class(name: str) -> type:
    """The ``<Class>Config`` dataclass of a two-person model."""
    module, cls, _ = interaction_model_entry(name)
    return getattr(importlib.import_module(module), f"{cls}Config")


def make_config(name: str, options: Mapping[str, Any] | None = None,
                source: str | Path | None = None) -> Any:
    """The model's configuration: its defaults with ``options`` (field -> value) applied.

    Raises:
        SimenvError: an unknown field (the message lists the known ones and names
            ``source``) or a value the dataclass rejects.
    """
    cls = config_class(name)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    given = {k.replace("-", "_"): v for k, v in dict(options or {}).items()}
    unknown = sorted(set(given) - set(fields))
    if unknown:
        raise SimenvError(f"unknown {cls.__name__} field(s) {', '.join(unknown)}; known: "
                          f"{', '.join(fields)}", source=source)
    defaults = cls()
    for key, value in given.items():
        # TOML/JSON have no tuples: lists become the tuple fields they configure.
        if isinstance(getattr(defaults, key), tuple) and isinstance(value, list):
            given[key] = tuple(value)
    try:
        return dataclasses.replace(defaults, **given)
    except (TypeError, ValueError) as exc:
        raise SimenvError(f"bad {cls.__name__}: {exc}", source=source) from None


def data_split(shared: str | Path = SHARED
               ) -> tuple[idata.InteractionWindows, idata.InteractionWindows]:
    """(train, test) windows of the default split (module docstring)."""
    windows = idata.make_windows(idata.load_recordings(shared))
    split = idata.split_by_recording(windows)
    return windows.subset(split.train), windows.subset(split.test)


def held_out_metrics(name: str, model: Any, test: idata.InteractionWindows,
                     seed: int = 0) -> dict[str, Any]:
    """Held-out numbers of the card: for a reaction generator, the papers' metrics of the
    model and of zero-velocity on ``test``
    (:func:`simenv.learning.eval_interaction.reaction_metrics`);
    for an interaction generator, FID and diversity of samples of the test labels it
    knows against the real test windows (both people); for an augmentation model, its
    errors and the naive baseline's on targets built from the test windows
    (:func:`simenv.models.interaction_augment.evaluate`, 4 scale vectors per window)."""
    kind = interaction_model_entry(name)[2]
    extractor, _ = default_feature_extractor()
    if kind == "reaction":
        out = {}
        for key, gen in (("model", model), ("zero_velocity", ZeroVelocity())):
            generated = np.asarray(gen.generate(test.actor, test.reactor[:, 0]), np.float64)
            res = reaction_metrics(test, generated, extractor, seed)
            out[key] = {k: res[k] for k, _, _ in CARD_METRICS}
        return out
    if kind == "interaction":
        known = set(getattr(model, "labels", ()))
        keep = np.isin(test.window_labels.astype(str), sorted(known))
        if not keep.any():
            return {}
        sub = test.subset(np.flatnonzero(keep))
        actor, reactor = model.sample(list(sub.window_labels.astype(str)), seed=seed)
        out = {}
        for person, gen, real in (("actor", actor, sub.actor), ("reactor", reactor,
                                                                 sub.reactor)):
            gen, real = np.asarray(gen, np.float64), np.asarray(real, np.float64)
            out[person] = {
                "FID": im.frechet_feature_distance(im.pose_features(gen),
                                                   im.pose_features(real)),
                "diversity": im.diversity(extractor(gen), seed=seed),
                "diversity_real": im.diversity(extractor(real), seed=seed),
            }
        out["windows"] = len(sub)
        return out
    # The augmentation model's module imports torch; only this kind needs it.
    from simenv.models.interaction_augment import evaluate

    return evaluate(model, build_targets(test, 4, seed=seed + 1), seed=seed)


def render_card(name: str, config: Any, history: Mapping[str, Any],
                train: idata.InteractionWindows, test: idata.InteractionWindows,
                metrics: Mapping[str, Any], checkpoint: Path) -> str:
    """The model card (Markdown) of a trained two-person model."""
    module, cls, kind = interaction_model_entry(name)
    loss = [float(v) for v in history.get("loss", [])]
    lines = [
        f"# {name}", "",
        f"`{module}.{cls}` (two-person {kind} model), trained by `simenv train interaction "
        f"--model {name}`. How it works and every difference from the paper: the docstring "
        f"of `{module}`.", "",
        "## Data and split", "",
        f"* Real two-person recordings at {train.fps:g} fps on 18 keypoints, "
        f"{train.window}-frame windows every {train.stride} frames, actor frame "
        "(`simenv.data.interaction_data`); split by recording, never by window.",
        f"* Train ({len(train)} windows): {', '.join(sorted(set(train.window_recording_names)))}"
        f"; per class: {dict(Counter(train.window_labels.tolist()))}.",
        f"* Held-out test ({len(test)} windows): "
        f"{', '.join(sorted(set(test.window_recording_names)))}; per class: "
        f"{dict(Counter(test.window_labels.tolist()))}.", "",
        "## Configuration and training", "",
        f"```json\n{json.dumps(dataclasses.asdict(config), indent=1)}\n```", "",
    ]
    if loss:
        lines.append(f"* Loss: {loss[0]:.4g} (epoch 1) -> {loss[-1]:.4g} (epoch {len(loss)}),"
                     f" minimum {min(loss):.4g}.")
    if "cpu_seconds" in history:
        lines.append(f"* CPU time: {float(history['cpu_seconds']):.0f} s.")
    lines.append(f"* Checkpoint: {checkpoint.stat().st_size / 2**20:.2f} MB.")
    if metrics:
        lines += ["", "## Held-out metrics", ""]
        if kind == "reaction":
            lines += ["| method | " + " | ".join(h for _, h, _ in CARD_METRICS) + " |",
                      "|---|" + "---:|" * len(CARD_METRICS)]
            for method, row in metrics.items():
                cells = [("n/a" if row.get(k) is None else f.format(row[k]))
                         for k, _, f in CARD_METRICS]
                lines.append(f"| {method} | " + " | ".join(cells) + " |")
        else:
            lines.append(f"```json\n{json.dumps(metrics, indent=1)}\n```")
    return "\n".join(lines) + "\n"


def plot_history(history: Mapping[str, Any], path: Path) -> Path:
    """Per-epoch loss curves (every list-valued history entry) as a PNG."""
    import matplotlib  # heavy, and only the report's figure needs it

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.5))
    for key, values in history.items():
        if isinstance(values, list) and values and all(
                isinstance(v, (int, float)) for v in values):
            ax.plot(np.arange(1, len(values) + 1), values, label=key)
    ax.set_xlabel("epoch")
    ax.set_ylabel("loss")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def run(name: str, *, config: Any = None, shared: str | Path = SHARED,
        out: str | Path | None = None, seed: int = 0, progress: bool = True
        ) -> dict[str, Any]:
    """Train, save, evaluate on the held-out split and write the card.

    Returns:
        ``{"checkpoint", "card", "history", "metrics", "cpu_seconds"}`` (paths as str).
    """
    module, _, _ = interaction_model_entry(name)
    config = config if config is not None else make_config(name)
    out = Path(out) if out is not None else Path("out") / "train-interaction" / name
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.process_time()
    train, test = data_split(shared)
    model, history = importlib.import_module(module).train(
        train, config, seed=seed, progress=progress)
    checkpoint = model.save(out / f"{name}.npz", metadata={
        "train_recordings": sorted(set(train.window_recording_names)),
        "test_recordings": sorted(set(test.window_recording_names)), "seed": seed})
    metrics = held_out_metrics(name, model, test, seed)
    card = out / f"{name}.md"
    card.write_text(render_card(name, config, history, train, test, metrics,
                                Path(checkpoint)))
    (out / "history.json").write_text(json.dumps(history, indent=1, default=float) + "\n")
    plot_history(history, out / "loss.png")
    return {"checkpoint": str(checkpoint), "card": str(card), "history": history,
            "metrics": metrics, "cpu_seconds": time.process_time() - t0}


def add_arguments(ap: argparse.ArgumentParser) -> None:
    """The options of ``simenv train interaction``, on ``ap``."""
    ap.add_argument("--model", required=True, choices=list(INTERACTION_MODELS),
                    help="the two-person model to train")
    ap.add_argument("--config", help="TOML/JSON table of the model's configuration fields")
    ap.add_argument("--shared", default=str(SHARED), help="shared/data folder")
    ap.add_argument("--out", help="output folder (default out/train-interaction/MODEL)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the initialisation and "
                    "the batches")
    ap.add_argument("--epochs", type=int, help="training epochs (a quick run: 1; default "
                    "--config's, else the model's)")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")


def main(argv: Sequence[str] | None = None,
         parser: argparse.ArgumentParser | None = None) -> int:
    """Command line entry point (see the module docstring; options on ``parser`` when
    given); 2 on a user error."""
    ap = parser or argparse.ArgumentParser(prog="python -m simenv.learning.train_interaction",
                                           description=__doc__.split("\n\n")[0])
    add_arguments(ap)
    args = ap.parse_args(argv)
    import torch  # heavy; the model trained later imports it anyway, here it gets 1 thread

    torch.set_num_threads(1)
    try:
        options = read_options(args.config) if args.config else {}
        if args.epochs is not None:
            options["epochs"] = args.epochs
        config = make_config(args.model, options, source=args.config)
        res = run(args.model, config=config, shared=args.shared, out=args.out,
                  seed=args.seed, progress=not args.quiet)
    except SimenvError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(Path(res["card"]).read_text())
    print(f"wrote {res['checkpoint']} and {res['card']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
