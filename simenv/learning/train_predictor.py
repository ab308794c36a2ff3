"""Train and evaluate the PredictiveMA-WGAN predictor on real motion capture.

``simenv train predictor --past 25 --future 25 --minutes 6 --out out/p25`` (or
``python -m simenv.learning.train_predictor ...``); ``simenv eval predictor [NAME] [--data PATH...]
[--json]`` evaluates a shipped model.

Data and split
--------------
Every clip readable under the given paths (default: the CMU clips of the shared corpus,
``cmu/bvh``, ``cmu/asf_amc``, ``cmu/two_person``; both people of a two-person trial) is
resampled to 25 fps, mapped to the 17-joint layout and cut into sliding ``P -> F``
windows with stride 1 (:mod:`simenv.data.prediction_data`). Clips too short for a window are
skipped and listed. The split is by *group* of clips with
:func:`simenv.data.prediction_data.split_by_clip` (test fraction 0.25, seed 0 by default): a
group is one clip, except that the two people of one CMU two-person trial (18_01/19_01,
60_xx/61_xx salsa) form one group, since each partner's motion mirrors the other's, and
a trial read from BVH and from AMC (02_01) is one clip by name. No group has windows on
both sides. The Karcher means and scales are fitted on the training windows only.
``--extra-data msr utkinect nuisi`` adds Kinect-era clips to the *training* pool only
(:func:`extra_motions`; the held-out CMU clips stay the test set).

The DCT-residual MLP (``--model regression``, :func:`train_regression`) is trained on
the same windows; ``--members K`` makes it an ensemble cross-fitted on K folds of the
training clip groups (:func:`run`), ``--mirror-average`` (default) averages each
prediction with the mirrored prediction of the mirrored history.

Training (:func:`train`) is seeded (torch, numpy, batch order, noise), single-threaded
by default, runs for a number of iterations or a time budget (whichever ends first),
shows a tqdm bar and writes a checkpoint. Evaluation (:func:`evaluate`) compares the
model (predicted and carried amplitude) with zero- and constant-velocity on the held-out
windows: per-frame MPJPE and RMS-up-to-horizon MPJPE at 80/160/320/400/1000 ms (joints
without the pelvis, whose root-relative error is 0 for every method), MPJS and
bone-length drift, per action type and per clip, the pass rates of the kinematic
plausibility metrics (:func:`plausibility`), plus recursive prediction to 3 F frames.
Training writes ``metrics.json``, ``error_curve.png``, ``model.npz`` (with the critic) and
what ships in ``assets/models``: ``predictor-<P>-<F>.npz`` (no critic) and its card
``predictor-<P>-<F>.md``;
evaluation (:func:`run_evaluation`) writes ``metrics.json`` and ``error_curve.png``.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Iterable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm import tqdm

from simenv.core.config import read_options, shared_data_root
from simenv.core.errors import MotionError, SimenvError, SkeletonError, UnitsError
from simenv.core.motion import Interaction, Motion
from simenv.data import interaction_data as idata
from simenv.data import prediction_data as pdata
from simenv.data import prediction_metrics as pm
from simenv.io import load, msr_action3d, utkinect
from simenv.models import load as load_model
from simenv.models.baselines import ConstantVelocity, ZeroVelocity
from simenv.models.predictor import (
    AMPLITUDE_TARGETS,
    LOSS_WEIGHTS,
    PARENTS,
    PRIORS,
    PredictiveMAWGAN,
    PredictorConfig,
    amplitude_loss,
    critic_loss,
    fit_geometry,
    generator_loss,
    mirror,
    rollout,
)
from simenv.models.predictor_regression import (
    DCTRegressionPredictor,
    RegressionConfig,
    check_lengths,
    regression_loss,
    root_targets,
    targets,
)
from simenv.models.training import CpuBudget, cosine_lr

#: Default root of the shared corpus (``SIMENV_SHARED_DATA`` overrides).
SHARED = shared_data_root()

#: Joints counted in the metrics: all but the pelvis (root-relative, error 0 always).
EVAL_JOINTS: tuple[int, ...] = tuple(range(1, 17))

#: Action type of the CMU trials of the shared corpus (from the CMU descriptions).
ACTIONS: dict[str, str] = {
    "01_01": "jump", "02_01": "walk", "02_03": "run", "02_04": "jump", "02_05": "strike",
    "02_06": "bend/lift", "05_02": "dance", "09_06": "run", "12_01": "walk",
    "16_15": "walk", "35_17": "run", "49_02": "jump", "49_04": "run", "49_06": "cartwheel",
    "55_02": "dance", "103_charleston1": "dance", "131_01": "dance", "131_03": "dance",
    "131_04": "dance", "135_06": "strike", "18_01": "walk+handshake",
    "19_01": "walk+handshake", "60_05": "dance", "61_05": "dance", "60_10": "dance",
    "61_10": "dance",
}

#: Clips that must stay on one side of the split (partners of one two-person trial).
GROUPS: dict[str, str] = {
    "18_01": "18_19_01", "19_01": "18_19_01", "60_05": "60_61_05", "61_05": "60_61_05",
    "60_10": "60_61_10", "61_10": "60_61_10",
}


def _stem(name: str) -> str:
    return name.removesuffix("_scaled")


def action_of(clip: str) -> str:
    """Action type of a clip name (``"other"`` when unknown)."""
    return ACTIONS.get(_stem(clip), "other")


def group_of(clip: str) -> str:
    """Split group of a clip name (see the module docstring)."""
    return GROUPS.get(_stem(clip), _stem(clip))


def default_data(shared: Path) -> list[Path]:
    """The CMU folders of the shared corpus."""
    cmu = shared / "cmu"
    return [cmu / "bvh", cmu / "asf_amc", *sorted((cmu / "two_person").glob("*"))]


def collect_motions(paths: Iterable[str | Path], progress: bool = False
                    ) -> tuple[list[Motion], list[str]]:
    """Single-person motions in files/folders (both people of two-person trials); with
    ``progress``, a bar over the paths.

    Returns:
        ``(motions, notes)``: clips on a skeleton with the 17 pred17 keypoints and a note
        for every clip left out (and why).

    Raises:
        SimenvError: a path does not exist or holds no readable motion.
    """
    motions: list[Motion] = []
    notes: list[str] = []
    paths = list(paths)
    # Folders differ a lot in size: the bar counts them and the time, it estimates no end.
    bar = tqdm(paths, desc="load clips", unit="path", leave=False, disable=not progress,
               bar_format="{desc}: {n_fmt}/{total_fmt} paths [{elapsed}]{postfix}")
    for path in bar:
        bar.set_postfix_str(Path(path).name)
        loaded = load(Path(path))
        items = loaded if isinstance(loaded, list) else [loaded]
        for item in items:
            people = [item.actor, item.reactor] if isinstance(item, Interaction) else [item]
            for m in people:
                try:
                    pdata.to_pred17(m)
                except SkeletonError as exc:
                    notes.append(f"{m.name}: {exc.detail}")
                    continue
                motions.append(m)
    if not motions:
        raise MotionError(
            "no usable clip (a single-person motion with the 17 keypoints of the "
            f"prediction layout) in {', '.join(str(p) for p in paths)}"
        )
    return motions, notes


#: Real sources that can be added to the *training* pool (``--extra-data``); the
#: held-out CMU clips stay the only test set (see :func:`extra_motions`).
EXTRA_SOURCES: tuple[str, ...] = ("msr", "utkinect", "nuisi")


def extra_motions(shared: Path, sources: Sequence[str]) -> tuple[list[Motion], list[str]]:
    """Kinect-era training clips on the pred17 layout, none of them ever evaluated on.

    * ``msr``: MSR Action3D files of the odd subjects (the gesture classifier's training
      subjects, :func:`simenv.data.gestures.split_cross_subject`; the recognition evaluation
      feeds the even subjects' clips through the predictor), 15 fps.
    * ``utkinect``: the UTKinect continuous sessions of the odd subjects, whole (the
      labelled segments and the moves between them), 15 fps after the reader's re-timing.
    * ``nuisi``: both people of the NuiSI "Rocket" repetitions on the training side of
      :data:`simenv.data.interaction_data.DEFAULT_TEST_RECORDINGS`, 25 fps.

    Florence 3D is not offered: its longest video is 35 frames at 20 fps (1.75 s), shorter
    than any ``25 -> 25`` window (51 frames at 25 fps, 2.04 s). The chest (and, where
    absent, the pelvis) is a midpoint (``prediction_data.to_pred17(derive=True)``). Clip
    names are prefixed with the source (``msr/``, ``utkinect/``, ``nuisi/``), so every
    clip is its own group, none on the test side.

    Returns:
        ``(motions, notes)``: pred17 motions in metres, world frame (Z up), and one note
        per recording left out.

    Raises:
        SimenvError: an unknown source name.
    """
    unknown = sorted(set(sources) - set(EXTRA_SOURCES))
    if unknown:
        raise SimenvError(f"unknown extra data source(s) {', '.join(unknown)}; expected "
                          f"some of {', '.join(EXTRA_SOURCES)}", field="extra_data")
    gestures = shared / "gestures"
    motions: list[Motion] = []
    notes: list[str] = []

    def add(m: Motion, name: str) -> None:
        motions.append(replace(pdata.to_pred17(m, derive=True), name=name))

    if "msr" in sources:
        for path in sorted((gestures / "msr_action3d").glob("a*_s*_e*_skeleton3D.txt")):
            try:
                m = msr_action3d.read(path)
            except SimenvError as exc:
                notes.append(f"msr/{path.name}: {exc.detail}")
                continue
            if int(m.metadata["subject"]) % 2 == 1:
                add(m, f"msr/{m.name}")
    if "utkinect" in sources:
        for path in sorted((gestures / "utkinect" / "joints").glob("joints_s*_e*.txt")):
            m = utkinect.read(path)
            if int(m.metadata["subject"]) % 2 == 1:
                add(m, f"utkinect/{m.name}")
    if "nuisi" in sources:
        nuisi = shared / "other" / "nuisi"
        for rep in idata.nuisi_repetitions(nuisi / "Rocket_p1.txt", nuisi / "Rocket_p2.txt"):
            if rep.name in idata.DEFAULT_TEST_RECORDINGS:
                continue
            for tag, person in (("p1", rep.actor), ("p2", rep.reactor)):
                add(person, f"{rep.name}/{tag}")
    return motions, notes


def is_extra(clip: str) -> bool:
    """Whether a clip name is one of :func:`extra_motions` (a source prefix)."""
    return clip.split("/", 1)[0] in EXTRA_SOURCES


def source_weights(windows: pdata.PredictionWindows, extra_share: float) -> np.ndarray:
    """(N,) sampling weights that give the :func:`extra_motions` windows ``extra_share``
    of every batch in expectation, and the CMU windows the rest (each side uniform).

    Raises:
        MotionError: ``extra_share`` outside [0, 1), or extra windows asked for but none.
    """
    if not 0 <= extra_share < 1:
        raise MotionError(f"extra_share must be in [0, 1); got {extra_share!r}",
                          field="extra_share")
    extra = np.array([is_extra(c) for c in windows.clip_names], dtype=bool)[windows.clip]
    if extra_share and not extra.any():
        raise MotionError("extra_share > 0 but the windows hold no extra-source clip",
                          field="extra_share")
    w = np.where(extra, extra_share / max(extra.sum(), 1),
                 (1 - extra_share) / max((~extra).sum(), 1))
    return w


def speed_variants(motions: Sequence[Motion], speeds: Sequence[float],
                   fps: float = pdata.TARGET_FPS) -> list[Motion]:
    """Each clip played at each speed factor (1.25 = 25 % faster): resampled to
    ``fps / speed`` and relabelled ``fps``. Names are kept, so variants of a clip stay
    one clip for the split."""
    out = []
    for m in motions:
        for s in speeds:
            if s == 1.0:
                out.append(m)
            else:
                out.append(replace(m.resample(fps / s), fps=fps))
    return out


def mirrored(windows: pdata.PredictionWindows) -> pdata.PredictionWindows:
    """``windows`` followed by their left-right mirror images (same clip labels)."""
    return pdata.PredictionWindows(
        np.concatenate([windows.frames, mirror(windows.frames)]),
        np.concatenate([windows.root, windows.root * np.array([-1, 1, 1], np.float32)]),
        np.concatenate([windows.clip, windows.clip]),
        np.concatenate([windows.start, windows.start]),
        windows.clip_names, windows.past_len, windows.future_len, windows.fps,
        windows.skipped,
    )


def make_split(windows: pdata.PredictionWindows, test_fraction: float, seed: int
               ) -> pdata.ClipSplit:
    """Split windows by clip group (see the module docstring)."""
    groups = np.array([group_of(c) for c in windows.window_clip_names], dtype=object)
    return pdata.split_by_clip(groups, test_fraction, seed)


def train(
    model: PredictiveMAWGAN,
    windows: pdata.PredictionWindows,
    *,
    iterations: int = 20000,
    minutes: float | None = None,
    batch_size: int = 64,
    n_critic: int = 2,
    lr: float = 1e-4,
    adv_weight: float = 1.0,
    joint_amplitude: bool = False,
    amplitude_target: str = "positions",
    validation: pdata.PredictionWindows | None = None,
    validate_every: int = 100,
    seed: int = 0,
    progress: bool = True,
) -> list[dict[str, float]]:
    """Adversarial training of ``model`` on ``windows`` (WGAN-GP, Adam lr 1e-4, batch 64).

    Each iteration takes ``n_critic`` critic steps, one generator step and one
    amplitude-head step, each on a fresh random batch. With ``joint_amplitude`` the
    generator's position losses use the predicted amplitude and one optimiser step
    updates generator and head together
    (:func:`simenv.models.predictor.generator_loss`); otherwise the head's loss is
    :func:`simenv.models.predictor.amplitude_loss` with ``amplitude_target``. With
    ``validation`` windows
    (clips held out *inside* the training clips, never the test clips) the model is
    scored every ``validate_every`` iterations (:func:`validation_score`) and the best
    generator and head are kept. ``minutes`` budgets the
    process's CPU time (not wall time: the machine is shared, and CPU time makes the
    budget reproducible).

    Returns:
        A log: one dict of losses every 50 iterations (and the last).
    """
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    data = model.prepare(windows)
    if len(data) < 2:
        raise MotionError(f"training needs at least 2 windows; got {len(data)}")
    bs = min(batch_size, len(data))
    steps = _WganSteps(model, lr=lr, adv_weight=adv_weight, n_critic=n_critic,
                       joint_amplitude=joint_amplitude, amplitude_target=amplitude_target,
                       noise=torch.Generator().manual_seed(seed + 1), batch_size=bs)
    for net in (model.generator, model.critic, model.amplitude):
        net.train()
    log: list[dict[str, float]] = []
    best = _Best(validation, (model.generator, model.amplitude))
    budget = CpuBudget(minutes)
    bar = tqdm(range(iterations), disable=not progress, desc="train", unit="it")

    def sample():
        idx = torch.as_tensor(rng.choice(len(data), bs, replace=False))
        return data.take(idx)

    for it in bar:
        _fit_total(bar, it, iterations, budget)
        info_c, info_g, loss_a = steps.step(sample)
        done = budget.exceeded()
        if it % 50 == 0 or it == iterations - 1 or done:
            entry = {"iteration": it, **info_c, **info_g, "amplitude": loss_a.item(),
                     "seconds": budget.seconds()}
            if it % validate_every == 0 or it == iterations - 1 or done:
                entry |= best.check(model, it)
                for net in (model.generator, model.amplitude):
                    net.train()
            log.append(entry)
            bar.set_postfix(rec=f"{info_g['rec']:.3f}", W=f"{info_c.get('wasserstein', 0):.2f}")
        if done:
            break
    _close(bar)
    best.restore()
    return log


def _fit_total(bar: tqdm, done: int, iterations: int, budget: CpuBudget) -> None:
    """Set ``bar``'s total to the iterations training will run: ``iterations``, or fewer
    when the CPU budget will end it first at the CPU rate of the ``done`` iterations so far
    (every 10), so that the bar's ETA is the end of training, not of iterations the budget
    never reaches."""
    spent = budget.seconds()
    if budget.minutes is None or done == 0 or done % 10 or not spent > 0:
        return
    bar.total = min(iterations, max(done + 1, round(done * 60 * budget.minutes / spent)))


def _close(bar: tqdm) -> None:
    """Close a training bar at 100 %: training ended where it stopped."""
    bar.total = bar.n
    bar.close()


class _WganSteps:
    """The optimisers (Adam, betas 0.5 and 0.9) and loss settings of :func:`train`;
    :meth:`step` is one training iteration."""

    def __init__(self, model: PredictiveMAWGAN, *, lr: float, adv_weight: float,
                 n_critic: int, joint_amplitude: bool, amplitude_target: str,
                 noise: torch.Generator, batch_size: int) -> None:
        self.model, self.noise, self.batch_size = model, noise, batch_size
        self.adv_weight, self.n_critic = adv_weight, n_critic
        self.joint_amplitude, self.amplitude_target = joint_amplitude, amplitude_target
        self.weights = LOSS_WEIGHTS | {"adv": adv_weight}
        betas = (0.5, 0.9)
        gen_params = list(model.generator.parameters())
        if joint_amplitude:
            gen_params += list(model.amplitude.parameters())
        self.opt_g = torch.optim.Adam(gen_params, lr=lr, betas=betas)
        self.opt_c = torch.optim.Adam(model.critic.parameters(), lr=lr, betas=betas)
        self.opt_a = torch.optim.Adam(model.amplitude.parameters(), lr=lr, betas=betas)

    def step(self, sample: Callable[[], Any]) -> tuple[dict, dict, torch.Tensor]:
        """``n_critic`` critic steps (none without the adversarial term), one generator
        step and one amplitude-head step, each on a fresh batch from ``sample()``; returns
        the critic's and generator's loss terms and the head's loss."""
        model, bs = self.model, self.batch_size
        info_c: dict = {}
        if self.adv_weight:
            for _ in range(self.n_critic):
                batch = sample()
                loss_c, info_c = critic_loss(model, batch, model.sample_noise(bs, self.noise))
                self.opt_c.zero_grad()
                loss_c.backward()
                self.opt_c.step()
        batch = sample()
        loss_g, info_g, u = generator_loss(model, batch, model.sample_noise(bs, self.noise),
                                           self.weights, joint_amplitude=self.joint_amplitude)
        self.opt_g.zero_grad()
        loss_g.backward()
        self.opt_g.step()
        if self.joint_amplitude:
            return info_c, info_g, torch.as_tensor(info_g["rec"])
        loss_a = amplitude_loss(model, batch, u, self.amplitude_target)
        self.opt_a.zero_grad()
        loss_a.backward()
        self.opt_a.step()
        return info_c, info_g, loss_a


def validation_score(model: object, windows: pdata.PredictionWindows) -> float:
    """Mean of the per-frame MPJPE (mm, pelvis excluded) at the horizons of
    :data:`simenv.data.prediction_metrics.HORIZONS_MS` that ``model`` predicts, on
    ``windows``: the model-selection criterion (lower is better)."""
    history = windows.frames[:, : windows.past_len + 1]
    if getattr(model.config, "root_input", False):  # a DCT-MLP that sees the root
        pred = model.predict(history, root=windows.root[:, : windows.past_len + 1])
    else:
        pred = model.predict(history)
    errors = pm.mpjpe_at_horizons_mm(pred, windows.future, windows.fps, joints=EVAL_JOINTS)
    return float(np.mean(list(errors.values())))


class _Best:
    """Keeps the state of ``nets`` with the lowest :func:`validation_score` so far."""

    def __init__(self, windows: pdata.PredictionWindows | None,
                 nets: Sequence[torch.nn.Module]) -> None:
        self.windows, self.nets = windows, nets
        self.score, self.iteration, self.state = float("inf"), -1, None

    def check(self, model: object, iteration: int) -> dict[str, float]:
        """Score ``model`` (eval mode) and remember it if best; the log entries."""
        if self.windows is None:
            return {}
        score = validation_score(model, self.windows)
        if score < self.score:
            self.score, self.iteration = score, iteration
            self.state = [{k: v.detach().clone() for k, v in n.state_dict().items()}
                          for n in self.nets]
        return {"val_mpjpe_mm": score}

    def restore(self) -> None:
        if self.state is not None:
            for net, state in zip(self.nets, self.state, strict=True):
                net.load_state_dict(state)


def train_regression(
    model: DCTRegressionPredictor,
    windows: pdata.PredictionWindows,
    *,
    iterations: int = 20000,
    minutes: float | None = None,
    batch_size: int = 128,
    lr: float = 3e-4,
    weight_decay: float = 1e-4,
    validation: pdata.PredictionWindows | None = None,
    validate_every: int = 100,
    seed: int = 0,
    progress: bool = True,
    sample_weights: np.ndarray | None = None,
    horizon_weight: float = 0.0,
) -> list[dict[str, float]]:
    """Supervised training of the DCT-residual MLP (AdamW, cosine decay over
    ``iterations``; loss :func:`simenv.models.predictor_regression.regression_loss`
    with ``horizon_weight``). Budget and model selection on ``validation`` as in
    :func:`train`.

    ``sample_weights`` (N,) >= 0: batches draw window i with probability proportional to
    its weight (with replacement; e.g. :func:`source_weights`); None: uniformly without
    replacement.

    Returns:
        A log: one dict every 50 iterations (and the last).
    """
    check_lengths(model, windows.past_len, windows.future_len)
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    residual, last, future = targets(model.history_len, windows.frames)
    velocity = (root_targets(model.history_len, windows.frames, windows.root, windows.fps)
                if model.config.root_input else None)
    if len(residual) < 2:
        raise MotionError(f"training needs at least 2 windows; got {len(residual)}")
    opt = torch.optim.AdamW(model.net.parameters(), lr=lr, weight_decay=weight_decay)
    bs = min(batch_size, len(residual))
    p = None
    if sample_weights is not None:
        w = np.asarray(sample_weights, dtype=np.float64)
        if w.shape != (len(residual),) or not np.all(w >= 0) or w.sum() <= 0:
            raise MotionError(f"sample_weights must be ({len(residual)},) non-negative "
                              f"with a positive sum; got shape {w.shape}",
                              field="sample_weights")
        p = w / w.sum()
    log: list[dict[str, float]] = []
    best = _Best(validation, (model.net,))
    budget = CpuBudget(minutes)
    bar = tqdm(range(iterations), disable=not progress, desc="train", unit="it")
    for it in bar:
        _fit_total(bar, it, iterations, budget)
        for group in opt.param_groups:
            group["lr"] = cosine_lr(lr, it, iterations)
        idx = torch.as_tensor(rng.choice(len(residual), bs, replace=p is not None, p=p))
        model.net.train()
        v = None if velocity is None else velocity[idx]
        loss = regression_loss(model.forward(residual[idx], last[idx], v), future[idx],
                               horizon_weight)
        opt.zero_grad()
        loss.backward()
        opt.step()
        done = budget.exceeded()
        if it % 50 == 0 or it == iterations - 1 or done:
            entry = {"iteration": it, "loss": loss.item(), "seconds": budget.seconds()}
            if it % validate_every == 0 or it == iterations - 1 or done:
                entry |= best.check(model, it)
            log.append(entry)
        if done:
            break
    _close(bar)
    best.restore()
    return log


def _method_metrics(pred: np.ndarray, windows: pdata.PredictionWindows) -> dict:
    target = windows.future
    fps = windows.fps
    last = windows.past[:, -1]
    return {
        "mpjpe_mm": pm.mpjpe_at_horizons_mm(pred, target, fps, joints=EVAL_JOINTS),
        "rms_mpjpe_up_to_horizon_mm": pm.rms_mpjpe_up_to_horizons_mm(pred, target, fps,
                                                                     joints=EVAL_JOINTS),
        "mpjs_m_s": pm.mean_per_joint_speed(np.concatenate([last[:, None], pred], 1), fps,
                                            EVAL_JOINTS),
        "bone_drift_mm": pm.bone_length_drift_mm(pred, last, PARENTS),
        "curve_mm": pm.per_frame_mpjpe_mm(pred, target, EVAL_JOINTS).tolist(),
    }


def predictions(model: PredictiveMAWGAN, windows: pdata.PredictionWindows
                ) -> dict[str, np.ndarray]:
    """Predicted futures of every method for ``windows`` (histories = lead-in + past)."""
    history = windows.frames[:, : windows.past_len + 1]
    f = windows.future_len
    out = {"model": model.predict(history)}
    if isinstance(model, PredictiveMAWGAN):
        out["model_carried_amplitude"] = model.predict(history, amplitude="carried")
    return out | {"zero_velocity": ZeroVelocity(f).predict(history),
                  "constant_velocity": ConstantVelocity(f).predict(history)}


#: Every how many-th window the plausibility metrics are computed on (overlapping
#: stride-1 windows are nearly identical).
PLAUSIBILITY_STRIDE = 10


def plausibility(preds: dict[str, np.ndarray], windows: pdata.PredictionWindows,
                 stride: int = PLAUSIBILITY_STRIDE) -> dict:
    """Pass rates of the kinematic plausibility metrics (:mod:`simenv.plausibility`,
    default thresholds) of every method and of the ground truth.

    Each scored clip is a window's lead-in and observed frames followed by the (F, 17, 3)
    future of a method, put back on the window's *true* root trajectory (the predictors
    do not predict the root, so a held pose slides its feet along with the root).

    A clip so distorted that it is not a body in metres any more (a median extent beyond
    3.5 m, :class:`~simenv.core.errors.UnitsError`; constant velocity over 2 s does this)
    fails every metric and is counted in ``not_a_body``.

    Returns:
        ``{"windows": n, "stride": stride, "pass_rate": {method: {metric: fraction}},
        "not_a_body": {method: fraction}}``.
    """
    # The kinematic metrics load numba kernels; only this report needs them.
    from simenv.plausibility import KINEMATIC_METRICS, kinematic_metrics_batch

    sel = np.arange(0, len(windows), stride)
    skeleton = pdata.pred17_skeleton()
    head = windows.frames[sel, : windows.past_len + 1]
    rates, rejected = {}, {}
    for name, future in {"ground_truth": windows.future, **preds}.items():
        world = np.concatenate([head, future[sel]], axis=1) + windows.root[sel, :, None]
        motions = []
        for i, x in zip(sel, world, strict=True):
            try:
                motions.append(Motion(x, windows.fps, skeleton, f"window {i}"))
            except UnitsError:
                continue
        results = kinematic_metrics_batch(motions)
        rates[name] = {k: round(sum(r[k].passed for r in results) / len(sel), 4)
                       for k in KINEMATIC_METRICS}
        rejected[name] = round(1 - len(motions) / len(sel), 4)
    return {"windows": len(sel), "stride": stride, "pass_rate": rates,
            "not_a_body": rejected}


def evaluate(model: PredictiveMAWGAN, windows: pdata.PredictionWindows) -> dict:
    """Metrics of the model and the baselines on ``windows``: overall, per action, per
    clip, plausibility (see the module docstring)."""
    preds = predictions(model, windows)
    gt = windows.future
    out: dict = {"windows": len(windows), "fps": windows.fps,
                 "horizons_ms": list(pm.HORIZONS_MS),
                 "gt_mpjs_m_s": pm.mean_per_joint_speed(
                     np.concatenate([windows.past[:, -1:], gt], 1), windows.fps, EVAL_JOINTS),
                 "overall": {k: _method_metrics(v, windows) for k, v in preds.items()}}
    names = windows.window_clip_names
    for key, label in (("per_action", action_of), ("per_clip", str)):
        groups = np.array([label(n) for n in names], dtype=object)
        out[key] = {}
        for g in sorted(set(groups)):
            sel = np.flatnonzero(groups == g)
            sub = windows.subset(sel)
            out[key][g] = {"windows": len(sel)} | {
                k: pm.mpjpe_at_horizons_mm(v[sel], sub.future, sub.fps, joints=EVAL_JOINTS)
                for k, v in preds.items()
            }
    out["plausibility"] = plausibility(preds, windows)
    return out


def evaluate_recursive(model: PredictiveMAWGAN, motions: Sequence[Motion],
                       test_clips: Iterable[str], repeats: int = 3) -> dict:
    """Per-frame MPJPE curve of recursive prediction to ``repeats`` x F frames on the
    test clips (model fed its own predictions), with the baselines."""
    test = set(test_clips)
    clips = [m for m in motions if group_of(m.name) in test]
    horizon = repeats * model.future_len
    try:
        long = pdata.windows_from_motions(clips, model.past_len, horizon, stride=5)
    except MotionError as exc:
        return {"skipped": exc.detail}
    history = long.frames[:, : model.past_len + 1]
    methods = {"model": model, "zero_velocity": ZeroVelocity(model.future_len),
               "constant_velocity": ConstantVelocity(model.future_len)}
    return {"windows": len(long), "frames": horizon,
            **{k: pm.per_frame_mpjpe_mm(rollout(m, history, horizon), long.future,
                                        EVAL_JOINTS).tolist()
               for k, m in methods.items()}}


def plot_curves(metrics: dict, path: Path) -> None:
    """Error curves (per-frame MPJPE vs time) of every method, single-shot and recursive."""
    import matplotlib  # heavy, and only the report's figure needs it

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fps = metrics["fps"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for name, m in metrics["overall"].items():
        curve = m["curve_mm"]
        axes[0].plot(1000 * np.arange(1, len(curve) + 1) / fps, curve, label=name)
    axes[0].set_title(f"held-out, {metrics['config']['past_len']}->"
                      f"{metrics['config']['future_len']} frames")
    rec = metrics.get("recursive", {})
    for name in ("model", "zero_velocity", "constant_velocity"):
        if name in rec:
            curve = rec[name]
            axes[1].plot(1000 * np.arange(1, len(curve) + 1) / fps, curve, label=name)
    axes[1].set_title("recursive prediction (held-out)")
    for ax in axes:
        ax.set_xlabel("time after last observed frame [ms]")
        ax.set_ylabel("per-frame MPJPE [mm]")
        ax.grid(alpha=0.3)
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def training_windows(motions: Sequence[Motion], clips: set[str],
                     args: argparse.Namespace, extra: Sequence[Motion] = ()
                     ) -> pdata.PredictionWindows:
    """Training windows of the motions whose group is in ``clips``, with the speed
    variants and (``args.mirror``) the mirror images of ``args``, followed by those of
    the ``extra`` training clips (:func:`extra_motions`: every ``args.extra_stride``-th
    window, mirrored with ``args.mirror``, no speed variants: the Kinect clocks are
    themselves uncertain, see ``gestures/SOURCES.md``)."""
    train_motions = [m for m in motions if group_of(m.name) in clips]
    windows = pdata.windows_from_motions(speed_variants(train_motions, args.speeds),
                                         args.past, args.future, stride=1)
    if extra:
        more = pdata.windows_from_motions(extra, args.past, args.future,
                                          stride=getattr(args, "extra_stride", 1))
        windows = pdata.concat_windows(windows, more)
    return mirrored(windows) if args.mirror else windows


def _member_info(log: list[dict[str, float]], validation: pdata.PredictionWindows | None,
                 windows: int) -> dict:
    """What a model card records of one trained ensemble member."""
    info = {"iterations": log[-1]["iteration"] + 1,
            "train_seconds": round(log[-1]["seconds"], 1), "train_windows": windows}
    scored = [e for e in log if "val_mpjpe_mm" in e]
    if scored and validation is not None:
        pick = min(scored, key=lambda e: e["val_mpjpe_mm"])
        info |= {"validation_clips": sorted({group_of(c)
                                             for c in validation.window_clip_names}),
                 "selected_iteration": pick["iteration"],
                 "val_mpjpe_mm": round(pick["val_mpjpe_mm"], 2)}
    return info


def run(args: argparse.Namespace) -> dict:
    """Load data, split, fit geometry, train, evaluate, write outputs; returns metrics.

    With ``args.validation > 0`` that share of the *training* windows, by clip group
    (:func:`make_split` with the same seed), is held out as a validation set for model
    selection; the test clips are never seen before the final evaluation.

    A regression ensemble (``--members K > 1``) trains member ``i`` with seed
    ``seed + i``, on the same training and validation clips; with ``--cross-fit`` it is
    cross-fitted instead: the training clip groups are dealt into K folds
    (:func:`simenv.data.prediction_data.clip_folds`; ``args.validation`` is not used), member
    ``i`` is trained on the other folds and its iteration selected on fold ``i``, so that
    every training clip trains K - 1 members.
    """
    torch.set_num_threads(args.threads)
    paths = args.data or default_data(Path(args.shared))
    motions, notes = collect_motions(paths, progress=not args.quiet)
    _stage(args, f"{len(motions)} clips loaded; cutting {args.past} -> {args.future} windows "
           "and augmenting the training clips")
    windows = pdata.windows_from_motions(motions, args.past, args.future, stride=1)
    split = make_split(windows, args.test_fraction, args.seed)
    test_w = windows.subset(split.test)
    base = windows.subset(split.train)
    ensemble = args.model == "regression" and args.members > 1
    folds, fit_clips, val_w, val_clips = _validation(args, base, split, ensemble)
    extra: list[Motion] = []
    if getattr(args, "extra_data", None):
        extra, extra_notes = extra_motions(Path(args.shared), args.extra_data)
        notes = notes + extra_notes
    train_w = training_windows(motions, fit_clips, args, extra)
    budget = {"iterations": args.iterations, "minutes": args.minutes,
              "validation": val_w, "seed": args.seed, "progress": not args.quiet}
    _stage(args, f"training on {len(train_w)} windows: {args.iterations} iterations or "
           f"{args.minutes:g} CPU minutes, whichever ends first")
    if args.model == "regression":
        model, log, recipe, train_w = _train_regression_run(
            args, motions, base, folds, train_w, val_w, extra, budget)
    else:
        model, log, recipe = _train_gan_run(args, train_w, extra, budget)
    config = model.config
    # an ensemble's selections are per member (recipe["members"])
    selected = [] if ensemble else [e for e in log if "val_mpjpe_mm" in e]
    config.info.update({"train_clips": list(split.train_clips),
                        "test_clips": list(split.test_clips),
                        "validation_clips": val_clips,
                        "train_windows": len(train_w), "test_windows": len(test_w),
                        "speeds": list(args.speeds), "mirror": args.mirror,
                        "dropout": args.dropout,
                        "iterations": log[-1]["iteration"] + 1,
                        "train_seconds": round(log[-1]["seconds"], 1), "seed": args.seed,
                        **recipe})
    if selected:
        pick = min(selected, key=lambda e: e["val_mpjpe_mm"])
        config.info.update({"selected_iteration": pick["iteration"],
                            "val_mpjpe_mm": round(pick["val_mpjpe_mm"], 2)})
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    model.save(out / "model.npz")
    _stage(args, f"evaluating on {len(test_w)} held-out windows and writing {out}")
    metrics = evaluate(model, test_w)
    metrics["recursive"] = evaluate_recursive(model, motions, split.test_clips)
    metrics["train_set"] = evaluate(model, train_w.subset(np.arange(0, len(train_w), 7)))[
        "overall"]
    metrics |= {"config": {"past_len": args.past, "future_len": args.future,
                           **config.info},
                "skipped_clips": list(windows.skipped), "notes": notes, "train_log": log}
    _write_reports(args, model, metrics)
    return metrics


def _validation(args: argparse.Namespace, base: pdata.PredictionWindows, split: pdata.ClipSplit,
                ensemble: bool) -> tuple[list | None, set[str], pdata.PredictionWindows | None,
                                         list[str]]:
    """How :func:`run` holds out validation windows from the training ones ``base``:
    (cross-fitting folds or None, the clips the (first) model trains on, its validation
    windows or None, their clips)."""
    if ensemble and args.cross_fit:
        groups = [group_of(c) for c in base.window_clip_names]
        folds = pdata.clip_folds(groups, args.members, args.seed)
        return (folds, set(folds[0].train_clips), base.subset(folds[0].test),
                list(folds[0].test_clips))
    if args.validation:
        vsplit = make_split(base, args.validation, args.seed)
        return None, set(vsplit.train_clips), base.subset(vsplit.test), list(vsplit.test_clips)
    return None, set(split.train_clips), None, []


def _train_regression_run(args: argparse.Namespace, motions: Sequence[Motion],
                          base: pdata.PredictionWindows, folds: list | None,
                          train_w: pdata.PredictionWindows,
                          val_w: pdata.PredictionWindows | None, extra: Sequence[Motion],
                          budget: dict[str, Any]
                          ) -> tuple[DCTRegressionPredictor, list[dict], dict[str, Any],
                                     pdata.PredictionWindows]:
    """The regression ensemble of :func:`run`, member by member (cross-fitted members on
    their own folds); returns (model, training log, recipe for the config's info, the last
    member's training windows)."""
    lr = args.lr or 3e-4
    config = RegressionConfig(args.past, args.future, blocks=args.blocks,
                              dropout=args.dropout, members=args.members,
                              mirror_average=args.mirror_average)
    model = DCTRegressionPredictor(config, seed=args.seed)  # reproducible init
    members, logs = [], []
    for i in range(args.members):
        if i and args.cross_fit:  # every further member: its own validation fold
            val_w = base.subset(folds[i].test)
            train_w = training_windows(motions, set(folds[i].train_clips), args, extra)
        weights = (source_weights(train_w, args.extra_share)
                   if extra and args.extra_share is not None else None)
        log = train_regression(model.member(i), train_w, lr=lr,
                               weight_decay=args.weight_decay, sample_weights=weights,
                               horizon_weight=args.horizon_weight,
                               **budget | {"validation": val_w, "seed": args.seed + i})
        members.append(_member_info(log, val_w, len(train_w)))
        logs += [e | {"member": i} for e in log]
    recipe = {"lr": lr, "model": "dct-mlp", "blocks": args.blocks,
              "weight_decay": args.weight_decay, "members": members,
              "horizon_weight": args.horizon_weight,
              "mirror_average": args.mirror_average,
              "cross_fit": args.members > 1 and args.cross_fit,
              "extra_data": list(getattr(args, "extra_data", None) or []),
              "extra_share": args.extra_share if extra else None,
              "extra_stride": args.extra_stride if extra else None,
              "extra_windows": sum(1 for c in train_w.window_clip_names if is_extra(c)),
              "train_seconds_total": round(sum(m["train_seconds"] for m in members), 1)}
    return model, logs, recipe, train_w


def _train_gan_run(args: argparse.Namespace, train_w: pdata.PredictionWindows,
                   extra: Sequence[Motion], budget: dict[str, Any]
                   ) -> tuple[PredictiveMAWGAN, list[dict], dict[str, Any]]:
    """The PredictiveMA-WGAN of :func:`run`: geometry fitted, then trained; returns
    (model, training log, recipe for the config's info)."""
    lr = args.lr or 1e-4
    config = PredictorConfig(args.past, args.future, dropout=args.dropout,
                             prior=args.prior,
                             velocity_condition=args.velocity_condition,
                             mirror_average=args.mirror_average,
                             restore_bones=args.restore_bones)
    torch.manual_seed(args.seed)  # fit_geometry builds the networks before train() seeds
    _stage(args, "first the windows' SRVF geometry (Karcher means, tangent vectors); the "
           "CPU budget starts after it")
    model = fit_geometry(train_w, config)
    log = train(model, train_w, n_critic=args.n_critic, lr=lr,
                adv_weight=args.adv_weight, joint_amplitude=args.joint_amplitude,
                amplitude_target=args.amplitude_target,
                validate_every=args.validate_every, **budget)
    recipe = {"lr": lr, "model": "predictive-ma-wgan", "n_critic": args.n_critic,
              "adv_weight": args.adv_weight, "joint_amplitude": args.joint_amplitude,
              "prior": args.prior, "velocity_condition": args.velocity_condition,
              "mirror_average": args.mirror_average,
              "restore_bones": args.restore_bones,
              "amplitude_target": None if args.joint_amplitude else args.amplitude_target,
              "extra_data": list(getattr(args, "extra_data", None) or []),
              "extra_stride": args.extra_stride if extra else None,
              "extra_windows": sum(1 for c in train_w.window_clip_names if is_extra(c))}
    return model, log, recipe


def _write_reports(args: argparse.Namespace, model: Any, metrics: dict) -> None:
    """Into ``args.out``: metrics.json, the error-curve plot, and the shipped checkpoint
    (a GAN without its critic) with its model card."""
    out = Path(args.out)
    (out / "metrics.json").write_text(json.dumps(metrics, indent=1))
    plot_curves(metrics, out / "error_curve.png")
    if args.model == "gan":
        # What ships in assets/models: the networks without the critic, and the card.
        name = f"predictor-{args.past}-{args.future}"
        model.save(out / f"{name}.npz", with_critic=False)
    else:
        name = f"predictor-dctmlp-{args.past}-{args.future}"
        model.save(out / f"{name}.npz")
    (out / f"{name}.md").write_text(model_card(name, metrics))


def _table(rows: dict[str, dict], key: str) -> list[str]:
    head = "| method | " + " | ".join(f"{h} ms" for h in pm.HORIZONS_MS) + " |"
    lines = [head, "|" + "---|" * (len(pm.HORIZONS_MS) + 1)]
    for name, m in rows.items():
        vals = m[key] if key else m
        cells = [f"{vals[str(h)]:.1f}" if str(h) in vals else (
            f"{vals[h]:.1f}" if h in vals else "-") for h in pm.HORIZONS_MS]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return lines


def _at(values: dict, horizon: int) -> float | None:
    """``values[horizon]`` whether the keys are ints or (after JSON) strings."""
    return values.get(str(horizon), values.get(horizon))


def goal_lines(overall: dict) -> list[str]:
    """The issue's goal (per-frame MPJPE at 400 and 1000 ms at least 20 % below
    zero-velocity), checked on the given metrics at the horizons the model predicts."""
    lines = []
    for h in (400, 1000):
        model, zv = _at(overall["model"]["mpjpe_mm"], h), \
            _at(overall["zero_velocity"]["mpjpe_mm"], h)
        if model is None:
            continue
        gain = 100 * (1 - model / zv)
        lines.append(f"* {h} ms: model {model:.1f} mm vs zero-velocity {zv:.1f} mm = "
                     f"{gain:+.1f} % lower; goal (>= 20 % lower) "
                     f"{'met' if gain >= 20 else 'NOT met'}")
    return ["", "Goal check (per-frame MPJPE, held-out):", "", *lines]


def plausibility_lines(metrics: dict) -> list[str]:
    """Markdown table of the plausibility pass rates (when the metrics have them)."""
    if "plausibility" not in metrics:
        return []
    pl = metrics["plausibility"]
    rates = pl["pass_rate"]
    names = list(next(iter(rates.values())))
    lines = ["", f"Plausibility: share of clips passing each kinematic metric of "
             f"`simenv.plausibility` (default thresholds; every {pl['stride']}th held-out "
             f"window, {pl['windows']} clips of history + future on the true root "
             "trajectory):", "",
             "| method | " + " | ".join(names) + " |", "|" + "---|" * (len(names) + 1)]
    for method, r in rates.items():
        lines.append(f"| {method} | " + " | ".join(f"{r[k]:.2f}" for k in names) + " |")
    lost = {k: v for k, v in pl.get("not_a_body", {}).items() if v}
    if lost:
        lines += ["", "Clips no longer a body in metres (extent > 3.5 m; they fail every "
                  "metric): " + ", ".join(f"{k} {v:.2f}" for k, v in lost.items())]
    return lines


def recursive_lines(metrics: dict) -> list[str]:
    """Markdown table of recursive prediction (per-frame MPJPE at each multiple of F)."""
    rec = metrics.get("recursive", {})
    if "model" not in rec:
        return ["", f"Recursive prediction: skipped ({rec.get('skipped', 'no data')})."]
    f, fps = metrics["config"]["future_len"], metrics["fps"]
    frames = [k * f for k in range(1, rec["frames"] // f + 1)]
    lines = ["", f"Recursive prediction beyond the horizon ({rec['windows']} held-out "
             f"windows, the model fed its own output), per-frame MPJPE [mm]:", "",
             "| method | " + " | ".join(f"{1000 * k / fps:.0f} ms" for k in frames) + " |",
             "|" + "---|" * (len(frames) + 1)]
    for name in ("model", "zero_velocity", "constant_velocity"):
        lines.append(f"| {name} | " + " | ".join(f"{rec[name][k - 1]:.1f}" for k in frames)
                     + " |")
    return lines


def results_lines(metrics: dict) -> list[str]:
    """The held-out results of a model card (error tables, MPJS, bone drift, goal check,
    plausibility, per action type, recursive prediction) from ``metrics.json`` content;
    ``benchmarks/model_docs.py`` puts the same lines into docs/prediction.md."""
    ov = metrics["overall"]
    lines = [
        "Per-frame MPJPE at the horizon [mm] (16 joints, pelvis excluded; root-relative):",
        "",
        *_table(ov, "mpjpe_mm"),
        "",
        "RMS-up-to-horizon MPJPE [mm] (the thesis's form):",
        "",
        *_table(ov, "rms_mpjpe_up_to_horizon_mm"),
        "",
        f"MPJS [m/s] (ground truth {metrics['gt_mpjs_m_s']:.3f}): " + ", ".join(
            f"{k} {v['mpjs_m_s']:.3f}" for k, v in ov.items()),
        "",
        "Bone-length drift [mm] (mean |b - b_last observed|): " + ", ".join(
            f"{k} {v['bone_drift_mm']['mean']:.1f}" for k, v in ov.items()),
        "",
        *goal_lines(ov),
        *plausibility_lines(metrics),
        "",
        "Per action type, per-frame MPJPE [mm] (model / zero-velocity / constant-velocity):",
        "",
        "| action | windows | " + " | ".join(f"{h} ms" for h in pm.HORIZONS_MS) + " |",
        "|" + "---|" * (len(pm.HORIZONS_MS) + 2),
    ]
    for action, m in metrics["per_action"].items():
        cells = []
        for h in pm.HORIZONS_MS:
            vals = [m[k].get(str(h), m[k].get(h))
                    for k in ("model", "zero_velocity", "constant_velocity")]
            cells.append("-" if vals[0] is None else " / ".join(f"{v:.0f}" for v in vals))
        lines.append(f"| {action} | {m['windows']} | " + " | ".join(cells) + " |")
    lines += recursive_lines(metrics)
    return lines


def model_card(name: str, metrics: dict) -> str:
    """Markdown model card of a trained predictor from its ``metrics.json`` content."""
    cfg = metrics["config"]
    regression = cfg.get("model") == "dct-mlp"
    title, module = (("DCT-residual MLP regression baseline (siMLPe-style, not the thesis "
                      "model)", "simenv.models.predictor_regression") if regression else
                     ("PredictiveMA-WGAN motion predictor", "simenv.models.predictor"))
    training = _training_text(cfg, regression)
    lines = [
        f"# {name}: {title} "
        f"({cfg['past_len']} -> {cfg['future_len']} frames at 25 fps)",
        "",
        "Predicts the next "
        f"{cfg['future_len']} frames ({1000 * cfg['future_len'] / 25:.0f} ms) of a 17-joint "
        "root-relative skeleton (simenv.data.prediction_data pred17 layout, metres, Z-up) from "
        f"the last {cfg['past_len'] + 1} frames (lead-in + {cfg['past_len']} observed). "
        f"Method and every choice that differs from the papers: docstring of `{module}`. "
        f"Load with `simenv.models.load(\"{name}\")`, then `.predict(history)`.",
        "",
        "## Data and split",
        "",
        "Real CMU motion capture from the shared corpus (BVH, ASF/AMC and both people of "
        "the two-person trials), resampled to 25 fps, sliding windows with stride 1. "
        "Split by clip group with `prediction_data.split_by_clip` (test fraction 0.25, "
        f"seed {cfg['seed']}; partners of one two-person trial are one group).",
        "",
        f"* train clips ({len(cfg['train_clips'])}): {', '.join(cfg['train_clips'])}",
        f"* held-out clips ({len(cfg['test_clips'])}): {', '.join(cfg['test_clips'])}",
        f"* training windows: {cfg['train_windows']} (with speed variants "
        f"{cfg['speeds']} and left-right mirroring: {cfg['mirror']}); held-out windows: "
        f"{cfg['test_windows']}",
        *([f"* extra training data (training side only, never evaluated on): "
           f"{', '.join(cfg['extra_data'])} (`train_predictor.extra_motions`: MSR Action3D "
           "and UTKinect sessions of the odd subjects, the NuiSI Rocket training "
           "repetitions; chest = spine-neck midpoint), every "
           f"{cfg['extra_stride']}th window, mirrored: {cfg['extra_windows']} of the "
           "training windows; batch share "
           + ("their share of the windows" if cfg.get("extra_share") is None
              else f"{cfg['extra_share']}")] if cfg.get("extra_data") else []),
        training,
        "",
        "## Held-out results",
        "",
        *results_lines(metrics),
        "",
        "Licence of the training data: CMU Graphics Lab Motion Capture Database. The data "
        "used in this project was obtained from mocap.cs.cmu.edu. The database was created "
        "with funding from NSF EIA-0196217.",
        "",
    ]
    return "\n".join(lines)


def _training_text(cfg: dict[str, Any], regression: bool) -> str:
    """The model card's training paragraph: an ensemble's (with its members' table), a
    single regression network's, or the GAN's."""
    if regression and isinstance(cfg.get("members"), list):
        return _ensemble_training_text(cfg)
    if regression:
        return (f"* training: {cfg['iterations']} iterations in {cfg['train_seconds']} "
                f"CPU s on one thread, batch 128, AdamW lr {cfg['lr']}, weight decay "
                f"{cfg['weight_decay']}, {cfg['blocks']} blocks, dropout {cfg['dropout']};"
                f" checkpoint of iteration {cfg['selected_iteration']} chosen on the "
                f"validation clips {', '.join(cfg['validation_clips'])} (training clips "
                f"held out of training, never the test clips; validation MPJPE "
                f"{cfg['val_mpjpe_mm']} mm)")
    return _gan_training_text(cfg)


def _ensemble_training_text(cfg: dict[str, Any]) -> str:
    """The training paragraph and members' table of a regression ensemble."""
    selected = all("selected_iteration" in m for m in cfg["members"])
    how = (f"cross-fitted: the training clip groups are dealt into "
           f"{len(cfg['members'])} folds, member i is trained on the other folds (seed "
           "+ i) and its iteration selected on fold i" if cfg.get("cross_fit", True)
           else "member i trained with seed + i on the same clips, its iteration "
           "selected on the validation clips" if selected
           else "member i trained with seed + i on all training clips for a fixed "
           "schedule, its last iteration kept (no validation clips, no selection)")
    rows = (["| member | validation clips | selected iteration | validation MPJPE [mm] "
             "| training windows |", "|---|---|---|---|---|",
             *(f"| {i} | {', '.join(m['validation_clips'])} | "
               f"{m['selected_iteration']} | {m['val_mpjpe_mm']} | "
               f"{m['train_windows']} |" for i, m in enumerate(cfg["members"]))]
            if selected else
            ["| member | iterations | training windows |", "|---|---|---|",
             *(f"| {i} | {m['iterations']} | {m['train_windows']} |"
               for i, m in enumerate(cfg["members"]))])
    held_out = (" (training clips held out of that member's training, never the test "
                "clips)" if selected else "")
    return "\n".join([
        f"* training: an ensemble of {len(cfg['members'])} networks, {how}{held_out}. "
        f"{cfg['members'][0]['iterations']} iterations per member, "
        f"{cfg['train_seconds_total']} CPU s in all on one thread, batch 128, AdamW lr "
        f"{cfg['lr']}, weight decay {cfg['weight_decay']}, {cfg['blocks']} blocks, "
        f"dropout {cfg['dropout']}; prediction = mean of the members"
        + (", each averaged with its mirrored prediction of the mirrored history"
           if cfg.get("mirror_average") else ""),
        "", *rows])


def _gan_training_text(cfg: dict[str, Any]) -> str:
    """The training paragraph of the PredictiveMA-WGAN."""
    training = (f"* training: {cfg['iterations']} iterations in {cfg['train_seconds']} "
                f"CPU s on one thread, batch 64, Adam lr {cfg['lr']}, "
                f"{cfg['n_critic']} critic step(s) per generator step, adversarial "
                f"weight {cfg['adv_weight']}, dropout {cfg['dropout']}")
    if cfg.get("prior", "none") != "none":
        fit = cfg.get("prior_fit", {})
        detail = (f"damping {fit['damping']}" if "damping" in fit else
                  f"ridge {fit.get('ridge', 0):.3g}")
        training += (f"; residual to the {cfg['prior'].replace('_', ' ')} prior "
                     f"future ({detail}, fitted on the training windows)")
    flags = [name for key, name in (
        ("joint_amplitude", "generator and amplitude head trained together"),
        ("velocity_condition", "last velocity in the condition"),
        ("mirror_average", "test-time mirror averaging"),
        ("restore_bones", "bone lengths restored to the last observed pose's"))
        if cfg.get(key)]
    if flags:
        training += "; " + ", ".join(flags)
    if "selected_iteration" in cfg:
        training += (f"; iteration {cfg['selected_iteration']} selected on the "
                     f"validation clips {', '.join(cfg['validation_clips'])} (training "
                     f"clips held out of training, never the test clips; validation "
                     f"MPJPE {cfg['val_mpjpe_mm']} mm)")
    return training


def eval_motions(model: PredictiveMAWGAN, paths: Sequence[str | Path] | None = None,
                 shared: str | Path | None = None) -> list[Motion]:
    """The clips to evaluate ``model`` on: those in ``paths`` or, by default, the model's
    own held-out clips (its checkpoint's ``config.info["test_clips"]``) from the shared
    corpus under ``shared``.

    Raises:
        SimenvError: no usable clip, or no default because the model records no split.
    """
    if paths:
        return collect_motions(paths)[0]
    motions, _ = collect_motions(default_data(Path(shared or SHARED)))
    test = set(model.config.info.get("test_clips", []))
    motions = [m for m in motions if group_of(m.name) in test]
    if not motions:
        raise MotionError("the model records no held-out clips; pass clips to evaluate")
    return motions


def run_evaluation(model: PredictiveMAWGAN, motions: Sequence[Motion],
                   out: str | Path | None = None) -> dict:
    """Full metrics of ``model`` and the baselines on ``motions`` (as :func:`evaluate`,
    plus recursive prediction); with ``out``, also writes ``metrics.json`` and
    ``error_curve.png`` there."""
    windows = pdata.windows_from_motions(motions, model.past_len, model.future_len, stride=1)
    metrics = evaluate(model, windows)
    metrics["clips"] = len(windows.clip_names)
    metrics["recursive"] = evaluate_recursive(model, motions, {group_of(m.name) for m in motions})
    metrics["config"] = {"past_len": model.past_len, "future_len": model.future_len,
                         **model.config.info}
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "metrics.json").write_text(json.dumps(metrics, indent=1))
        plot_curves(metrics, out / "error_curve.png")
    return metrics


def summary_json(metrics: dict) -> dict:
    """The ``simenv eval predictor --json`` object of :func:`run_evaluation` metrics:
    ``{"fps", "horizons_ms", "clips", "windows", "mpjpe_mm": {"model": [...],
    "zero_velocity": [...], "constant_velocity": [...]}}``, per-frame MPJPE (mm, no pelvis)
    at each horizon, ``None`` for horizons beyond the model's F frames."""
    rows = {name: [metrics["overall"][name]["mpjpe_mm"].get(h) for h in pm.HORIZONS_MS]
            for name in ("model", "zero_velocity", "constant_velocity")}
    return {"fps": metrics["fps"], "horizons_ms": list(pm.HORIZONS_MS),
            "clips": metrics["clips"], "windows": metrics["windows"], "mpjpe_mm": rows}


def add_train_arguments(ap: argparse.ArgumentParser) -> None:
    """The training options (``simenv train predictor``), on ``ap``."""
    _data_options(ap)
    _model_options(ap)
    _run_options(ap)


def add_eval_arguments(ap: argparse.ArgumentParser) -> None:
    """The evaluation options (``simenv eval predictor [NAME]``), on ``ap``."""
    ap.add_argument("name", nargs="?", default="predictor-25-25", metavar="NAME",
                    help="shipped predictor (e.g. predictor-10-10, predictor-dctmlp-25-25)")
    ap.add_argument("--data", nargs="*", help="motion files/folders to evaluate on "
                    "(default: the model's own held-out CMU clips)")
    ap.add_argument("--shared", default=str(SHARED), help="shared corpus root")
    ap.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    ap.add_argument("--threads", type=int, default=1, help="PyTorch CPU threads")
    ap.add_argument("--out", help="output folder of metrics.json and error_curve.png "
                    "(default out/eval-NAME)")


def parse_args(argv: Sequence[str] | None = None,
               parser: argparse.ArgumentParser | None = None) -> argparse.Namespace:
    """Training options, parsed by ``parser`` (an empty one the caller names, e.g.
    ``simenv train predictor``; default ``python -m simenv.learning.train_predictor``);
    ``--config FILE`` (TOML/JSON, :mod:`simenv.core.config`) sets defaults that explicit
    command-line options override.

    Raises:
        SimenvError: unreadable config or an unknown key in it.
    """
    ap = parser or argparse.ArgumentParser(prog="python -m simenv.learning.train_predictor",
                                           description=__doc__.split("\n")[0])
    add_train_arguments(ap)
    args = ap.parse_args(argv)
    if args.config:
        options = {k.replace("-", "_"): v for k, v in read_options(args.config).items()}
        known = set(vars(args)) - {"config"}
        unknown = sorted(set(options) - known)
        if unknown:
            raise SimenvError(f"unknown option(s) {', '.join(unknown)}; known: "
                              f"{', '.join(sorted(known))}", source=args.config)
        ap.set_defaults(**options)
        args = ap.parse_args(argv)
    return args


def _stage(args: argparse.Namespace, text: str) -> None:
    """Say on stderr what training does next (unless ``--quiet``): the steps between the
    bars take seconds to minutes."""
    if not args.quiet:
        print(f"train predictor: {text}", file=sys.stderr, flush=True)


def _data_options(ap: argparse.ArgumentParser) -> None:
    """Window lengths, data, model kind and validation."""
    ap.add_argument("--config", help="TOML/JSON file of option values")
    ap.add_argument("--past", type=int, default=25, help="observed frames P (25 fps)")
    ap.add_argument("--future", type=int, default=25, help="predicted frames F")
    ap.add_argument("--data", nargs="*", help="motion files/folders (default: shared CMU)")
    ap.add_argument("--shared", default=str(SHARED), help="shared corpus root")
    ap.add_argument("--iterations", type=int, default=20000,
                    help="training iterations (the time budget may end training first)")
    ap.add_argument("--minutes", type=float, default=6.0, help="training CPU-time budget")
    ap.add_argument("--model", choices=("gan", "regression"), default="gan",
                    help="PredictiveMA-WGAN (gan) or the DCT-residual MLP regression "
                    "predictor (simenv.models.predictor_regression)")
    ap.add_argument("--validation", type=float, default=0.0,
                    help="share of the training windows held out by clip group for "
                    "model selection (0: none, the last iterate is kept)")


def _model_options(ap: argparse.ArgumentParser) -> None:
    """The regression ensemble's, the extra training data's and the GAN's options."""
    ap.add_argument("--blocks", type=int, default=4, help="regression: temporal blocks")
    ap.add_argument("--weight-decay", type=float, default=1e-4,
                    help="regression: AdamW weight decay")
    ap.add_argument("--horizon-weight", type=float, default=0.0,
                    help="regression: loss weight slope a, future frame t weighted "
                    "1 + a t / (F - 1) (0: the per-frame mean)")
    ap.add_argument("--members", type=int, default=1,
                    help="regression: networks of the ensemble (seeds seed, seed + 1, ...)")
    ap.add_argument("--cross-fit", action=argparse.BooleanOptionalAction, default=False,
                    help="regression ensemble: cross-fit the members on as many folds of "
                    "the training clips (each member selected on its fold)")
    ap.add_argument("--extra-data", nargs="*", choices=EXTRA_SOURCES, default=[],
                    help="add these Kinect-era sources to the training pool only "
                    "(extra_motions: MSR/UTKinect odd subjects, NuiSI training repetitions)")
    ap.add_argument("--extra-share", type=float, default=None,
                    help="regression: share of every batch drawn from the extra windows "
                    "(default: their share of the windows)")
    ap.add_argument("--extra-stride", type=int, default=2,
                    help="frames between the starts of consecutive extra windows")
    ap.add_argument("--mirror-average", action=argparse.BooleanOptionalAction,
                    default=True, help="average each prediction with the mirrored "
                    "prediction of the mirrored history (GAN and regression)")
    ap.add_argument("--n-critic", type=int, default=2, help="critic steps per G step")
    ap.add_argument("--lr", type=float, default=None,
                    help="learning rate (default 1e-4 for the GAN, 3e-4 for regression)")
    ap.add_argument("--adv-weight", type=float, default=1.0,
                    help="weight of the adversarial term (0: no critic, regression only)")
    ap.add_argument("--joint-amplitude", action=argparse.BooleanOptionalAction,
                    default=False, help="train generator and amplitude head together "
                    "on the position losses at the predicted amplitude")
    ap.add_argument("--prior", choices=PRIORS,
                    default="none", help="GAN: prior future whose tangent vector and "
                    "amplitude the generator and head correct (simenv.models.predictor."
                    "fit_prior; none: the paper's model)")
    ap.add_argument("--validate-every", type=int, default=100,
                    help="GAN: iterations between scores on the validation clips")
    ap.add_argument("--velocity-condition", action=argparse.BooleanOptionalAction,
                    default=False, help="GAN: add the last observed velocity to the "
                    "generator's condition")
    ap.add_argument("--amplitude-target", choices=AMPLITUDE_TARGETS,
                    default="positions", help="GAN without --joint-amplitude: train the "
                    "amplitude head on the position error at the generator's direction "
                    "or on the true log amplitude")
    ap.add_argument("--restore-bones", action=argparse.BooleanOptionalAction,
                    default=False, help="GAN: rebuild the prior future and every "
                    "predicted frame with the last observed pose's bone lengths")


def _run_options(ap: argparse.ArgumentParser) -> None:
    """Augmentation, split, seed, threads, output and progress."""
    ap.add_argument("--speeds", type=float, nargs="+", default=[0.8, 1.0, 1.25],
                    help="speed augmentation factors of the training clips")
    ap.add_argument("--mirror", action=argparse.BooleanOptionalAction, default=True,
                    help="add left-right mirrored training windows")
    ap.add_argument("--dropout", type=float, default=0.2, help="dropout of the networks")
    ap.add_argument("--test-fraction", type=float, default=0.25,
                    help="share of the clip groups held out for the test")
    ap.add_argument("--seed", type=int, default=0,
                    help="seed of the split, the initialisation and the batches")
    ap.add_argument("--threads", type=int, default=1, help="PyTorch CPU threads")
    ap.add_argument("--out", help="output folder of metrics.json, error_curve.png, model.npz "
                    "and the shipped checkpoint and card (default out/predictor)")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")


def main(argv: Sequence[str] | None = None,
         parser: argparse.ArgumentParser | None = None) -> int:
    """Train (options: :func:`parse_args`, on ``parser`` when given); returns the exit
    status (2 on a user error)."""
    try:
        args = parse_args(argv, parser)
        args.out = args.out or "out/predictor"
        metrics = run(args)
    except SimenvError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    _print_table(metrics["overall"])
    print(f"outputs in {args.out}")
    return 0


def evaluate_main(argv: Sequence[str] | None = None,
                  parser: argparse.ArgumentParser | None = None) -> int:
    """Evaluate a shipped model (options: :func:`add_eval_arguments`, on ``parser`` when
    given, e.g. ``simenv eval predictor``); returns the exit status (2 on a user error)."""
    ap = parser or argparse.ArgumentParser(prog="simenv eval predictor",
                                           description="Evaluate a shipped predictor.")
    add_eval_arguments(ap)
    args = ap.parse_args(argv)
    try:
        torch.set_num_threads(args.threads)
        model = load_model(args.name)
        args.out = args.out or f"out/eval-{args.name}"
        metrics = run_evaluation(model, eval_motions(model, args.data, args.shared), args.out)
    except SimenvError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    result = summary_json(metrics)
    if args.json:
        print(json.dumps(result))
        return 0
    print(f"{result['clips']} clips, {result['windows']} windows; per-frame MPJPE [mm] "
          f"(metrics.json and error_curve.png in {args.out})")
    _print_table({name: {"mpjpe_mm": dict(zip(result["horizons_ms"], row, strict=True))}
                  for name, row in result["mpjpe_mm"].items()})
    return 0


def _print_table(overall: dict[str, dict]) -> None:
    """The per-frame MPJPE table (mm; a row per method, a column per horizon, ``n/a`` beyond
    the model's future), with its header."""
    width = max(len(name) for name in overall)
    print(f"{'MPJPE [mm] at':>{width}s} " + " ".join(f"{h:>5d} ms" for h in pm.HORIZONS_MS))
    for name, m in overall.items():
        row = [m["mpjpe_mm"].get(h) for h in pm.HORIZONS_MS]
        print(f"{name:>{width}s} " + " ".join(
            "    n/a " if v is None or v != v else f"{v:8.1f}" for v in row))


if __name__ == "__main__":
    raise SystemExit(main())
