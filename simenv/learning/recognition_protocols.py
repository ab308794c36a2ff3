"""Recognition measured the field's way: per-dataset benchmarks and the room's vocabulary on
people the network never saw.

Benchmarks (:func:`run_benchmark`), each dataset on its own classes with its standard
protocol, next to published figures (:data:`PUBLISHED`):

* **MSR Action3D, cross-subject**: the 20 classes, odd subjects train, even subjects test
  (Li et al. 2010; the sequences of ``files_used_in_cvpr12_paper.txt``, the common list of
  Wang et al. 2012). Subject 10 is held out of our corpus, so the test side has 4
  subjects instead of 5.
* **MSR Action3D, action sets** (``msr_action3d_sets``): the three subsets of 8 actions of
  Li et al. 2010 (:data:`MSR_ACTION_SETS`), each trained and tested cross-subject on its own
  classes; the accuracy published for it is the mean of the three (the mean of folds here).
  HBRNN's 94.49 % is this figure, not a 20-class one.
* **UTKinect-Action3D, leave-one-subject-out**: the 10 classes, 10 folds.
* **Florence 3D, leave-one-subject-out**: the 9 classes, 10 folds.

Whole sequences are classified (the network takes any length); training windows are
random crops of up to :data:`BENCHMARK_FRAMES` frames (``whole_sequences``: up to the
longest clip, i.e. whole sequences), never partial (the benchmarks classify segmented
actions); ``members`` networks of consecutive seeds can be averaged (logits). The simplest
baseline runs the same protocols with no network: each test sequence takes the label of its
nearest training sequence (``neighbour``: :mod:`simenv.learning.nearest_neighbour`).
A second model family, covariance descriptors with a ridge classifier
(:mod:`simenv.learning.covariance`, ``covariance``), runs alone or fused with the networks:
the product of the networks' softmax (of their mean logits) and its probabilities, equal
weights (``fused``), or ``weighted``: ``(1 - w) log p_net + w log p_cov`` with ``w``
(:data:`FUSION_WEIGHTS`) chosen per fold on its training subjects alone, each held out in
turn from one network and one covariance classifier trained on the others
(:func:`fusion_weight`; no test clip is seen, at the price of a network per training
subject). It chooses its descriptor (the ``gesture15`` or the native joints, with or
without velocities) and regulariser by leave-one-training-subject-out accuracy and
calibrates its probabilities on those held-out subjects. With ``lie_group`` its candidates
also hold the Lie-group descriptors of the same clips (:mod:`simenv.learning.lie_group`: the
relative geometry of every pair of bones in a Fourier temporal pyramid, the representation
of the Lie-group figures), alone and beside each covariance descriptor (the two as blocks
of equal weight), among which it chooses in the same way.

Joints (``joints``): ``gesture15`` (default; the room's joint set, measured by all three
datasets) or ``native``, each dataset's own skeleton as its reader gives it
(:func:`native_clips`: MSR Action3D and UTKinect the 20 Kinect v1 joints, hands, feet and
hip centre included; Florence its 15 OpenNI joints), the joints renamed to their canonical
keypoint names (so the normalisation finds spine, shoulders, elbows, wrists), the tree
kept, resampled to 25 fps like the gesture clips. The mirror augmentation of
:func:`simenv.learning.recognition.kinect_noise` swaps only the left/right pairs it knows (not the
Kinect hands and feet), so when a native skeleton has others the benchmark mirrors clips
instead: each training clip and its mirror image (:func:`mirror_clip`), half the epochs
(the same number of optimisation steps, half the windows mirrored, as with ``mirror``).

The room's vocabulary (:func:`run_room_protocol`): every subject of the gesture corpus,
leave-subjects-out in :data:`~simenv.data.gestures.SUBJECT_FOLDS` folds
(:func:`simenv.data.gestures.split_subject_folds`; idle clips included), one network per fold,
evaluated on the held-out subjects in the thesis's conditions (windows centre-cropped):
``real_3s``, ``real_1s`` (the first second of that window), ``real_1s_pred_2s`` (that
second continued by the fold's forecaster, trained without the held-out subjects), and
the zero- and constant-velocity continuations. The temperature of each fold is fitted on
the out-of-fold logits of the *other* folds (cross-fitting), so no held-out label
calibrates the probabilities it is judged with.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
from tqdm import tqdm

from simenv.core.errors import SimenvError
from simenv.core.skeletons import Skeleton
from simenv.data.gestures import (
    GESTURE_FPS,
    GESTURE_LABELS,
    IDLE_LABEL,
    WINDOW_FRAMES,
    GestureClip,
    cut_window,
    load_gesture_clips,
    make_windows,
    mirror_windows,
    normalise_windows,
    room_reaction,
    split_subject_folds,
)
from simenv.io.msr_action3d import MSR_CLASSES
from simenv.learning.covariance import CovarianceClassifier, Descriptor, descriptors
from simenv.learning.lie_group import lie_group_descriptors
from simenv.learning.nearest_neighbour import (
    NEIGHBOUR_DISTANCES,
    NeighbourDistance,
    nearest_neighbour,
    resample_sequences,
)
from simenv.learning.recognition import (
    SHORT_FRAMES,
    Forecaster,
    RecognitionConfig,
    clip_skeleton,
    continue_windows,
    logits_of,
    train_recogniser,
)
from simenv.models.skeleton_tcn import SkeletonTCN, fit_temperature

#: Published accuracies (%) of each benchmark: method -> figure, as the papers report them.
PUBLISHED: dict[str, dict[str, float]] = {
    "msr_action3d": {"Lie group (Vemulapalli et al. 2014)": 89.48},
    "msr_action3d_sets": {"HBRNN (Du et al. 2015)": 94.49},
    "utkinect": {"Lie group (Vemulapalli et al. 2014)": 97.08},
    "florence3d": {"Lie group (Vemulapalli et al. 2014)": 90.88},
}
#: The action sets of MSR Action3D (Li et al. 2010), by action number (1-20, the order of
#: :data:`simenv.io.msr_action3d.MSR_CLASSES`).
MSR_ACTION_SETS: dict[str, tuple[int, ...]] = {
    "AS1": (2, 3, 5, 6, 10, 13, 18, 20),
    "AS2": (1, 4, 7, 8, 9, 11, 12, 14),
    "AS3": (6, 14, 15, 16, 17, 18, 19, 20),
}
#: How each benchmark splits its clips (the leave-one-subject-out ones are not listed).
BENCHMARK_PROTOCOLS: dict[str, str] = {
    "msr_action3d": "cross-subject (odd train, even test)",
    "msr_action3d_sets": "cross-subject on each action set AS1-AS3 (mean of sets)",
}
#: Longest training crop of the benchmarks, frames at 25 fps (5 s).
BENCHMARK_FRAMES = 125
#: Training epochs of a benchmark's networks (the published protocols' runs).
BENCHMARK_EPOCHS = 60
#: Joint sets of the benchmarks (module docstring, *Joints*).
BENCHMARK_JOINTS: tuple[str, ...] = ("gesture15", "native")
BenchmarkJoints = Literal["gesture15", "native"]
#: Ways :func:`run_benchmark` uses the covariance classifier (module docstring).
COVARIANCE_MODES: tuple[str, ...] = ("alone", "fused", "weighted")
CovarianceMode = Literal["alone", "fused", "weighted"]
#: Weights of the covariance classifier's log-probabilities that the ``weighted`` fusion
#: tries (the networks' get one minus it): 0 is the networks alone, 0.5 the equal product.
FUSION_WEIGHTS: tuple[float, ...] = tuple(k / 10 for k in range(11))
#: Conditions of the room protocol, in table order.
ROOM_CONDITIONS: tuple[str, ...] = ("real_3s", "real_1s", "real_1s_pred_2s",
                                    "real_1s_pred_2s_zv", "real_1s_pred_2s_cv")


def classification_scores(y: np.ndarray, pred: np.ndarray, labels: Sequence[str],
            datasets: Sequence[str] | None = None) -> dict[str, Any]:
    """Accuracy, balanced accuracy (mean recall over present classes), per-class recall,
    confusion (rows true), and per-dataset accuracy."""
    c = len(labels)
    confusion = np.zeros((c, c), np.int64)
    np.add.at(confusion, (y, pred), 1)
    support = confusion.sum(1)
    recall = {labels[k]: round(float(confusion[k, k] / support[k]), 4)
              for k in range(c) if support[k]}
    out: dict[str, Any] = {
        "n": int(len(y)), "accuracy": round(float((y == pred).mean()), 4),
        "balanced_accuracy": round(float(np.mean(list(recall.values()))), 4),
        "per_class_recall": recall, "confusion": confusion.tolist()}
    if datasets is not None:
        ds = np.asarray(datasets)
        out["per_dataset_accuracy"] = {d: round(float((y[ds == d] == pred[ds == d]).mean()), 4)
                                       for d in sorted(set(datasets))}
    return out


# -- benchmarks -------------------------------------------------------------------------


def _msr_protocol_stems(root: Path) -> set[str] | None:
    listing = root / "msr_action3d" / "files_used_in_cvpr12_paper.txt"
    if not listing.is_file():
        return None
    return {line.strip() for line in listing.read_text().split() if line.strip()}


@dataclass(frozen=True, eq=False)
class NativeClip(GestureClip):
    """A gesture clip on its dataset's own skeleton (:func:`native_clips`), which it
    carries so that :func:`simenv.learning.recognition.clip_skeleton` finds it.

    Attributes:
        skeleton: the joints of ``positions`` (canonical keypoint names) and their tree.
    """

    skeleton: Skeleton = field(kw_only=True)


def native_skeleton(skeleton: Skeleton) -> Skeleton:
    """``skeleton`` with each joint renamed to its canonical keypoint name (joints without
    one keep their name); same order and parents."""
    key_of = {joint: key for key, joint in skeleton.canonical.items()}
    names = tuple(key_of.get(j, j) for j in skeleton.joint_names)
    return Skeleton(f"{skeleton.name}_native", names, skeleton.parents,
                    {key: key for key in key_of.values()})


def native_clips(clips: Sequence[GestureClip]) -> list[NativeClip]:
    """``clips`` on their recordings' own skeletons (:func:`native_skeleton` of
    ``clip.source``), resampled to :data:`~simenv.data.gestures.GESTURE_FPS` as the gesture
    clips are (same frames; the joints shared with ``gesture15`` equal the clip's).

    Raises:
        SimenvError: a clip without its source recording.
    """
    out = []
    for c in clips:
        if c.source is None:
            raise SimenvError(f"clip {c.name!r} has no source recording; cannot put it on "
                              "its native skeleton", field="joints")
        skel = native_skeleton(c.source.skeleton)
        m = c.source.on_layout(skel, "the native benchmark skeleton")
        if m.num_frames >= 2:
            m = m.resample(GESTURE_FPS)
        out.append(NativeClip(np.ascontiguousarray(m.positions, dtype=np.float32), c.label,
                              c.source_label, c.dataset, c.subject, c.name, c.source,
                              skeleton=skel))
    return out


def _mirror_perm(names: Sequence[str]) -> list[int]:
    """Joint order of the mirror image: every ``left_*`` / ``right_*`` pair swapped."""
    index = {n: k for k, n in enumerate(names)}
    perm = list(range(len(names)))
    for n, k in index.items():
        for a, b in (("left_", "right_"), ("right_", "left_")):
            if n.startswith(a) and b + n[len(a):] in index:
                perm[k] = index[b + n[len(a):]]
    return perm


def window_mirror_complete(skeleton: Skeleton) -> bool:
    """Whether :func:`simenv.data.gestures.mirror_windows` (the training mirror) swaps every
    left/right pair of ``skeleton`` (True for gesture15/gesture9 and Florence; False for
    the Kinect hands and feet)."""
    names = skeleton.joint_names
    probe = np.zeros((len(names), 3), np.float32)
    probe[:, 0] = np.arange(len(names))
    return mirror_windows(probe, names)[:, 0].astype(int).tolist() == _mirror_perm(names)


def mirror_clip(clip: GestureClip, skeleton: Skeleton) -> GestureClip:
    """The mirror image of ``clip`` (world Y negated, left/right joints of ``skeleton``
    swapped), named ``<name>_mirror``; normalised, it is the training mirror of the clip's
    normalised windows."""
    positions = np.array(clip.positions[:, _mirror_perm(skeleton.joint_names)], np.float32)
    positions[..., 1] *= -1
    return replace(clip, positions=positions, name=f"{clip.name}_mirror", source=None)


def benchmark_folds(dataset: str, clips: Sequence[GestureClip]
                    ) -> list[tuple[str, list[GestureClip], list[GestureClip]]]:
    """(fold name, train, test) of ``dataset``'s standard protocol (module docstring)."""
    if dataset == "msr_action3d":
        return [("cross-subject", [c for c in clips if c.subject % 2 == 1],
                 [c for c in clips if c.subject % 2 == 0])]
    if dataset == "msr_action3d_sets":
        folds = []
        for name, actions in MSR_ACTION_SETS.items():
            classes = {MSR_CLASSES[a - 1] for a in actions}
            subset = [c for c in clips if c.source_label in classes]
            folds += benchmark_folds("msr_action3d", subset)
            folds[-1] = (name, *folds[-1][1:])
        return folds
    subjects = sorted({c.subject for c in clips})
    return [(f"s{s:02d}", [c for c in clips if c.subject != s],
             [c for c in clips if c.subject == s]) for s in subjects]


def whole_windows(clips: Sequence[GestureClip]) -> tuple[np.ndarray, np.ndarray]:
    """Every clip whole, padded to the longest and normalised: ((N, T, J, 3), (N, T))."""
    length = max(c.num_frames for c in clips)
    cut = [cut_window(c.positions, length=length) for c in clips]
    valid = np.stack([v for _, v in cut])
    joints = clip_skeleton(clips).joint_names
    return normalise_windows(np.stack([w for w, _ in cut]), valid, joints=joints), valid


def _network_fold(train: Sequence[GestureClip], fold_labels: Sequence[str],
                  tests: Sequence[tuple[np.ndarray, np.ndarray]], config: RecognitionConfig,
                  seed: int, members: int, skeleton: Skeleton, mirror_copies: bool,
                  extra: dict[str, Any], progress: bool = False
                  ) -> tuple[list[np.ndarray], list[float]]:
    """One benchmark fold's networks: ``members`` of consecutive seeds trained on ``train``
    (plus its mirror images with ``mirror_copies``) on ``fold_labels``; returns, for each
    k = 1..members, the first k networks' logits averaged over the networks and over
    ``tests`` (views of the same test clips: (windows, valid) each), (N, classes) over
    ``fold_labels``, and each network's training CPU s; ``progress``: each network's
    epoch bar."""
    if mirror_copies:
        train = list(train) + [mirror_clip(c, skeleton) for c in train]
    total: np.ndarray | float = 0.0
    means, cpu = [], []
    for member in range(members):
        model, history = train_recogniser(
            train, fold_labels, lambda c: c.source_label, replace(config, seed=seed + member),
            progress=progress, extra=extra)
        total = total + sum(logits_of(model, x, valid) for x, valid in tests)
        means.append(np.asarray(total) / ((member + 1) * len(tests)))
        cpu.append(history["train_cpu_s"])
    return means, cpu


def _log_softmax(logits: np.ndarray) -> np.ndarray:
    """Row-wise log-softmax of (N, C) logits."""
    z = logits - logits.max(1, keepdims=True)
    return z - np.log(np.exp(z).sum(1, keepdims=True))


def _descriptor_variants(clips: Sequence[GestureClip], joints: str,
                         native: Sequence[GestureClip] | None, lie_group: bool = False
                         ) -> dict[str, Descriptor]:
    """The covariance classifier's candidate descriptors of ``clips`` (on the joint set
    ``joints``) and of the same clips on their native skeletons, when given: name -> (N, F)
    or, with ``lie_group``, also each Lie-group descriptor (``lie:<joints>@<fraction>``) and
    each covariance descriptor with it as blocks (``<covariance>&<lie>``; the blocks are the
    same arrays as the variants alone, module docstring)."""
    sets = {joints: clips} if native is None else {joints: clips, "native": native}
    covariance: dict[str, Descriptor] = {}
    lie: dict[str, Descriptor] = {}
    for joints, group in sets.items():
        cov_j, lie_j = _window_descriptors(*whole_windows(group), joints,
                                           clip_skeleton(group).parents, lie_group)
        covariance |= cov_j
        lie |= lie_j
    return _with_pairs(covariance, lie)


def _window_descriptors(x: np.ndarray, valid: np.ndarray, joints: str,
                        parents: Sequence[int], lie_group: bool
                        ) -> tuple[dict[str, Descriptor], dict[str, Descriptor]]:
    """The covariance descriptors (``<joints>[+velocity]``) and, with ``lie_group``, the
    Lie-group ones (``lie:<joints>@<fraction>``) of normalised windows ``x`` (N, T, J, 3)
    over their real frames ``valid`` (N, T)."""
    covariance: dict[str, Descriptor] = {
        f"{joints}{'+velocity' if v else ''}": descriptors(x, valid, v) for v in (False, True)}
    lie: dict[str, Descriptor] = {
        f"lie:{joints}@{f:g}": d
        for f, d in (lie_group_descriptors(x, valid, parents) if lie_group else {}).items()}
    return covariance, lie


def _with_pairs(covariance: dict[str, Descriptor], lie: dict[str, Descriptor]
                ) -> dict[str, Descriptor]:
    """Every variant alone and each covariance descriptor with each Lie-group one as blocks
    (``<covariance>&<lie>``, the same arrays)."""
    return covariance | lie | {f"{c}&{m}": (a, b) for c, a in covariance.items()
                               for m, b in lie.items()}


def _variant_rows(variants_all: dict[str, Descriptor], rows: np.ndarray
                  ) -> dict[str, Descriptor]:
    """``variants_all`` restricted to clips ``rows``, each array indexed once, so that
    variants sharing a block still share it (the classifier computes a block once)."""
    taken: dict[int, np.ndarray] = {}

    def take(a: np.ndarray) -> np.ndarray:
        if id(a) not in taken:
            taken[id(a)] = a[rows]
        return taken[id(a)]

    return {name: tuple(take(a) for a in d) if isinstance(d, tuple) else take(d)
            for name, d in variants_all.items()}


def _covariance_fold(train: Sequence[GestureClip], test: Sequence[GestureClip],
                     fold_labels: Sequence[str], variants_all: dict[str, Descriptor],
                     row: dict[int, int]) -> tuple[np.ndarray, dict[str, Any]]:
    """One benchmark fold's covariance classifier (module docstring): (N_test, classes)
    probabilities and what it chose. ``variants_all``: every clip's descriptors (a clip's
    do not depend on the fold), its row in them by the clip's ``id`` in ``row``."""
    def variants(group: Sequence[GestureClip]) -> dict[str, Descriptor]:
        return _variant_rows(variants_all, np.array([row[id(c)] for c in group]))

    clf = CovarianceClassifier(len(fold_labels)).fit(
        variants(train), np.array([fold_labels.index(c.source_label) for c in train]),
        np.array([c.subject for c in train]))
    chosen = {"variant": clf.variant, "lambda": clf.lam, "temperature": clf.temperature,
              "held_out_accuracy": clf.selection[clf.variant][clf.lam]}
    return clf.predict_proba(variants(test)), chosen


def fused_log_p(net_log_p: np.ndarray, cov_log_p: np.ndarray, weight: float) -> np.ndarray:
    """``(1 - weight) net_log_p + weight cov_log_p``: (N, C) fused class scores of two
    models' (N, C) log-probabilities (unnormalised; argmax is the fused decision)."""
    return (1.0 - weight) * net_log_p + weight * cov_log_p


def fusion_weight(net_log_p: np.ndarray, cov_log_p: np.ndarray, y: np.ndarray,
                  weights: Sequence[float] = FUSION_WEIGHTS) -> tuple[float, dict[str, float]]:
    """The weight of :func:`fused_log_p` that classifies held-out clips best.

    Args:
        net_log_p, cov_log_p: (N, C) the two models' log-probabilities of clips neither
            trained on.
        y: (N,) their class indices.
        weights: the weights tried.

    Returns:
        The weight with the highest accuracy (ties: the lowest negative log-likelihood of
        the fused scores' softmax) and each weight's accuracy, keyed by the weight.

    Raises:
        SimenvError: shapes that disagree or no clips.
    """
    if net_log_p.shape != cov_log_p.shape or net_log_p.ndim != 2 or len(y) != len(net_log_p):
        raise SimenvError(f"log-probabilities {net_log_p.shape} and {cov_log_p.shape} must "
                          f"both be (N, C) with N = {len(y)} labels", field="log_p")
    if len(y) == 0:
        raise SimenvError("no held-out clips to choose a fusion weight on", field="y")
    accuracy, ranking = {}, []
    for w in weights:
        z = fused_log_p(net_log_p, cov_log_p, w)
        acc = float((z.argmax(1) == y).mean())
        nll = float(-_log_softmax(z)[np.arange(len(y)), y].mean())
        accuracy[f"{w:g}"] = round(acc, 4)
        ranking.append((-acc, nll, w))
    return min(ranking)[2], accuracy


def _fusion_weight_fold(train: Sequence[GestureClip], fold_labels: Sequence[str],
                        config: RecognitionConfig, seed: int, skeleton: Skeleton,
                        mirror_copies: bool, extra: dict[str, Any],
                        variants_all: dict[str, Descriptor], row: dict[int, int]
                        ) -> tuple[float, dict[str, Any], float]:
    """One benchmark fold's fusion weight, chosen on its training subjects alone: each held
    out in turn, one network (seed ``seed``) and one covariance classifier trained on the
    others classify it, and :func:`fusion_weight` picks on all those held-out clips.
    Returns the weight, its record (the weight, the held-out accuracy of every weight tried:
    at 0 the network's alone, at 1 the covariance classifier's; the held-out clips and
    subjects) and the CPU s it took."""
    start = time.process_time()
    net, cov, y = [], [], []
    subjects = sorted({c.subject for c in train})
    for subject in tqdm(subjects, desc="fusion weight", leave=False):
        inner = [c for c in train if c.subject != subject]
        held = [c for c in train if c.subject == subject]
        logits, _ = _network_fold(inner, fold_labels, [whole_windows(held)], config, seed, 1,
                                  skeleton, mirror_copies, extra)
        p, _ = _covariance_fold(inner, held, fold_labels, variants_all, row)
        net.append(_log_softmax(logits[0]))
        cov.append(np.log(p + 1e-300))
        y.append([fold_labels.index(c.source_label) for c in held])
    net_lp, cov_lp, y_all = np.concatenate(net), np.concatenate(cov), np.concatenate(y)
    weight, accuracy = fusion_weight(net_lp, cov_lp, y_all)
    record = {"weight": weight, "held_out_accuracy": accuracy, "held_out_clips": len(y_all),
              "subjects": len(subjects)}
    return weight, record, time.process_time() - start


def _ensemble_sizes(members: int) -> list[int]:
    """Ensemble sizes a result reports besides its own: 1 and the odd sizes below it."""
    return [k for k in range(1, members) if k == 1 or k % 2]


def benchmark_config(epochs: int = BENCHMARK_EPOCHS) -> RecognitionConfig:
    """The benchmarks' networks: no partial windows, crops up to :data:`BENCHMARK_FRAMES`
    frames, ``epochs`` epochs (1: every step of a run, its numbers thrown away)."""
    return RecognitionConfig(partial_prob=0.0, max_frames=BENCHMARK_FRAMES, epochs=epochs)


def run_benchmark(dataset: str, root: str | Path, config: RecognitionConfig | None = None,
                  *, members: int = 1, whole_sequences: bool = False,
                  joints: BenchmarkJoints = "gesture15",
                  neighbour: NeighbourDistance | None = None, mirror_test: bool = False,
                  covariance: CovarianceMode | None = None, lie_group: bool = False,
                  progress: bool = True) -> dict[str, Any]:
    """Train and test ``dataset`` (``msr_action3d``, ``msr_action3d_sets``, ``utkinect`` or
    ``florence3d``) on its own classes with its standard protocol (each fold's network on
    the classes of its fold: an action set's 8), on ``joints`` (``gesture15`` or ``native``,
    module docstring); returns accuracy (pooled over folds), the mean of per-fold
    accuracies, per-fold numbers, training CPU time and the published figures; with
    ``members`` > 1 the same for the ensembles of its first k networks too
    (``smaller_ensembles``: k = 1 and the odd k below ``members``).

    ``neighbour`` (``euclidean`` or ``dtw``): the nearest-neighbour baseline instead of the
    networks, on the fold's training clips (no augmentation; ``members`` and the training
    windows do not apply, ``train_cpu_s`` is the CPU time of its distances).
    ``mirror_test``: a network's logits are averaged over each test clip and its mirror
    image (test-time augmentation; the networks train with mirrored windows).
    ``covariance``: ``alone``, the covariance classifier instead of the networks (like
    ``neighbour``); ``fused``, the networks' probabilities times its probabilities;
    ``weighted``, the two fused with a weight chosen on the fold's training subjects
    (module docstring); each fold's choices in ``folds[i]["covariance"]`` (the weight's in
    its ``"fusion"``). ``lie_group``: the covariance classifier's candidates include the
    Lie-group descriptors (module docstring; ``descriptors`` in the result names the
    families).

    Raises:
        SimenvError: unknown dataset, joint set, distance or covariance mode, both a
            neighbour and the covariance classifier alone, Lie-group descriptors without
            the covariance classifier, or no clips.
    """
    if dataset not in PUBLISHED:
        raise SimenvError(f"unknown benchmark {dataset!r}; expected one of "
                          f"{', '.join(PUBLISHED)}", field="dataset")
    if joints not in BENCHMARK_JOINTS:
        raise SimenvError(f"unknown joint set {joints!r}; expected one of "
                          f"{', '.join(BENCHMARK_JOINTS)}", field="joints")
    if members < 1:
        raise SimenvError(f"members must be >= 1; got {members}", field="members")
    if neighbour is not None and neighbour not in NEIGHBOUR_DISTANCES:
        raise SimenvError(f"unknown distance {neighbour!r}; expected one of "
                          f"{', '.join(NEIGHBOUR_DISTANCES)}", field="neighbour")
    if covariance is not None and covariance not in COVARIANCE_MODES:
        raise SimenvError(f"unknown covariance mode {covariance!r}; expected one of "
                          f"{', '.join(COVARIANCE_MODES)}", field="covariance")
    if neighbour is not None and covariance is not None:
        raise SimenvError("the nearest neighbour runs alone; drop covariance",
                          field="covariance")
    if lie_group and covariance is None:
        raise SimenvError("the Lie-group descriptors are candidates of the covariance "
                          "classifier; give a covariance mode", field="lie_group")
    alone = neighbour is not None or covariance == "alone"
    root = Path(root)
    config = config or benchmark_config()
    source = "msr_action3d" if dataset.startswith("msr_action3d") else dataset
    clips = load_gesture_clips(root, datasets=(source,))
    excluded: list[str] = []
    stems = _msr_protocol_stems(root) if source == "msr_action3d" else None
    if stems is not None:
        # Listed as "a01_s01_e01"; our clip names keep the file's "_skeleton3D".
        stem = {c.name: c.name.removesuffix("_skeleton3D") for c in clips}
        excluded = sorted(c.name for c in clips if stem[c.name] not in stems)
        clips = [c for c in clips if stem[c.name] in stems]
    # The covariance classifier may choose the native joints (the clips' own recordings).
    native = (native_clips(clips) if covariance is not None and joints == "gesture15"
              and all(c.source is not None for c in clips) else None)
    if joints == "native":
        clips = native_clips(clips)
    skeleton = clip_skeleton(clips)
    if covariance is not None:
        descriptor_variants = _descriptor_variants(clips, joints, native, lie_group)
        row = {id(c): i for i, c in enumerate(clips)}
    labels = sorted({c.source_label for c in clips})
    if whole_sequences:
        config = replace(config, max_frames=max(c.num_frames for c in clips))
    # The training mirror must swap every left/right pair; otherwise mirror the clips.
    mirror_copies = config.mirror and not window_mirror_complete(skeleton)
    train_config = (replace(config, mirror=False, epochs=max(1, round(config.epochs / 2)))
                    if mirror_copies else config)
    folds = benchmark_folds(dataset, clips)
    extra = {"benchmark": dataset, "joints": joints}  # recorded with each network
    # Per ensemble size k (the first k networks; one entry for a model run alone):
    # predictions pooled over folds, per-fold rows, CPU seconds.
    sizes = 1 if alone else members
    y_all: list[np.ndarray] = []
    p_all: list[list[np.ndarray]] = [[] for _ in range(sizes)]
    per_fold: list[list[dict[str, Any]]] = [[] for _ in range(sizes)]
    cpu = np.zeros(sizes)
    for name, train, test in tqdm(folds, desc=f"benchmark {dataset}", disable=not progress):
        x, valid = whole_windows(test)
        y = np.array([labels.index(c.source_label) for c in test])
        fold_labels = sorted({c.source_label for c in (*train, *test)})
        chosen: dict[str, Any] = {}
        if covariance is not None:
            start = time.process_time()
            cov_p, chosen = _covariance_fold(train, test, fold_labels, descriptor_variants,
                                             row)
            cov_cpu = time.process_time() - start
        if neighbour is not None:
            start = time.process_time()
            fold_preds = [nearest_neighbour(
                resample_sequences(x, valid), resample_sequences(*whole_windows(train)),
                np.array([fold_labels.index(c.source_label) for c in train]), neighbour)]
            fold_cpu = [time.process_time() - start]
        elif covariance == "alone":
            fold_preds, fold_cpu = [cov_p.argmax(1)], [cov_cpu]
        else:
            tests = [(x, valid)]
            if mirror_test:
                tests.append(whole_windows([mirror_clip(c, skeleton) for c in test]))
            fold_logits, fold_cpu = _network_fold(
                train, fold_labels, tests, train_config, config.seed, members, skeleton,
                mirror_copies, extra, progress)
            if covariance in ("fused", "weighted"):
                weight = 0.5
                if covariance == "weighted":
                    weight, chosen["fusion"], weight_cpu = _fusion_weight_fold(
                        train, fold_labels, train_config, config.seed, skeleton,
                        mirror_copies, extra, descriptor_variants, row)
                    cov_cpu += weight_cpu
                fold_preds = [fused_log_p(_log_softmax(lg), np.log(cov_p + 1e-300),
                                          weight).argmax(1) for lg in fold_logits]
                fold_cpu[0] += cov_cpu
            else:
                fold_preds = [lg.argmax(1) for lg in fold_logits]
        y_all.append(y)
        for k, fold_pred in enumerate(fold_preds):
            pred = np.array([labels.index(fold_labels[i]) for i in fold_pred])
            cpu[k:] += fold_cpu[k]
            per_fold[k].append({"fold": name, "n": len(test), "classes": len(fold_labels),
                                "accuracy": round(float((pred == y).mean()), 4),
                                "train_cpu_s": round(float(np.sum(fold_cpu[:k + 1])), 1)}
                               | ({"covariance": chosen} if chosen else {}))
            p_all[k].append(pred)
    y = np.concatenate(y_all)

    def summary(k: int) -> dict[str, Any]:
        return {"scores": classification_scores(y, np.concatenate(p_all[k]), labels),
                "mean_fold_accuracy": round(float(np.mean([f["accuracy"]
                                                           for f in per_fold[k]])), 4),
                "folds": per_fold[k], "train_cpu_s": round(float(cpu[k]), 1)}

    smaller = [] if alone else _ensemble_sizes(members)
    method = (f"nearest neighbour ({neighbour})" if neighbour is not None else
              "covariance" if covariance == "alone" else
              "network + covariance" if covariance == "fused" else
              "network + covariance, weighted" if covariance == "weighted" else "network")
    return {"dataset": dataset, "protocol": BENCHMARK_PROTOCOLS.get(dataset,
                                                                    "leave-one-subject-out"),
            "classes": labels, "clips": len(clips), "excluded": excluded,
            **summary(sizes - 1), "members": members,
            "smaller_ensembles": [{"members": k} | summary(k - 1) for k in smaller],
            "whole_sequences": whole_sequences, "joints": joints,
            "method": method, "mirror_test": mirror_test and not alone,
            "descriptors": ([] if covariance is None else
                            ["covariance", "lie group"] if lie_group else ["covariance"]),
            "skeleton": {"name": skeleton.name, "joint_names": list(skeleton.joint_names)},
            "mirror": ("none" if alone else
                       "clips (each training clip and its mirror image, half the epochs)"
                       if mirror_copies else "windows" if config.mirror else "none"),
            "config": asdict(config), "train_config": asdict(train_config),
            "published": PUBLISHED[dataset]}


# -- the room's vocabulary --------------------------------------------------------------


def real_windows(clips: Sequence[GestureClip]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The real conditions of the room protocol, ``real_3s`` and ``real_1s`` (module
    docstring), of ``clips``: name -> (normalised windows (N, 75, J, 3), valid (N, 75))."""
    joints = clip_skeleton(clips).joint_names
    full = make_windows(clips, crop="centre", joints=joints)
    short = make_windows(clips, crop="centre", real_frames=SHORT_FRAMES, joints=joints)
    return {"real_3s": (full.x, full.valid), "real_1s": (short.x, short.valid)}


def condition_windows(clips: Sequence[GestureClip], forecast: Forecaster | None
                      ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The room protocol's conditions (module docstring) of ``clips``:
    name -> (normalised windows (N, 75, J, 3), valid (N, 75))."""
    out = real_windows(clips)
    short_x, short_valid = out["real_1s"]
    rows = np.flatnonzero(short_valid.sum(1) < WINDOW_FRAMES)
    if forecast is not None:
        out["real_1s_pred_2s"] = continue_windows(short_x, short_valid, rows, forecast)
    out["real_1s_pred_2s_zv"] = continue_windows(
        short_x, short_valid, rows, lambda h: np.repeat(h[:, -1:], WINDOW_FRAMES, axis=1))
    out["real_1s_pred_2s_cv"] = continue_windows(
        short_x, short_valid, rows, lambda h: h[:, -1:] + (h[:, -1:] - h[:, -2:-1])
        * np.arange(1, WINDOW_FRAMES + 1, dtype=np.float32)[None, :, None, None])
    return out


def run_room_protocol(clips: Sequence[GestureClip], config: RecognitionConfig, *,
                      forecaster_for_fold: Callable[[int], Forecaster | None] | None = None,
                      folds: int | None = None, progress: bool = True,
                      keep_models: bool = False) -> dict[str, Any]:
    """The room vocabulary, leave-subjects-out (module docstring).

    Args:
        clips: the corpus' clips (labelled and idle), gesture15.
        config: training options (``forecast_prob`` only acts when the fold has a
            forecaster).
        forecaster_for_fold: fold index -> forecaster trained without that fold's
            subjects (None: no ``real_1s_pred_2s`` condition).
        folds: number of folds (default :data:`~simenv.data.gestures.SUBJECT_FOLDS`).
        progress: progress bar over folds.
        keep_models: also return the fold networks (``"models"``, not JSON).

    Returns:
        ``conditions``: per condition the pooled scores over every held-out clip
        (accuracy, balanced accuracy, per-class recall, confusion, per dataset, room-
        reaction accuracy); ``folds``: per fold its test subjects, clips, accuracies,
        temperature and CPU time; ``oof``: the out-of-fold logits per condition, labels,
        names, subjects, datasets (for calibration and the loop's threshold).
    """
    labels = list(GESTURE_LABELS)
    split = split_subject_folds(clips, **({} if folds is None else {"folds": folds}))
    logits: dict[str, list[np.ndarray]] = {}
    order: list[GestureClip] = []
    fold_of: list[int] = []
    per_fold, models = [], []
    for k, (train, test) in enumerate(tqdm(split, desc="room protocol folds",
                                           disable=not progress)):
        forecast = forecaster_for_fold(k) if forecaster_for_fold else None
        model, history = train_recogniser(
            train, labels, lambda c: c.label,
            config if forecast is not None else replace(config, forecast_prob=0.0),
            forecast=forecast, progress=progress, extra={"protocol": f"fold {k}"})
        models.append(model)
        conds = condition_windows(test, forecast)
        row: dict[str, Any] = {"fold": k, "test_subjects": sorted({c.subject_key for c in test}),
                               "clips": len(test), "train_cpu_s": history["train_cpu_s"]}
        y = np.array([labels.index(c.label) for c in test])
        for name, (x, valid) in conds.items():
            z = logits_of(model, x, valid)
            logits.setdefault(name, []).append(z)
            row[name] = round(float((z.argmax(1) == y).mean()), 4)
        per_fold.append(row)
        order += test
        fold_of += [k] * len(test)
    y = np.array([labels.index(c.label) for c in order])
    fold_arr = np.array(fold_of)
    datasets = [c.dataset for c in order]
    z_all = {name: np.concatenate(parts) for name, parts in logits.items()}
    # Cross-fitted temperature of each fold, from the other folds' held-out real windows.
    calib = np.concatenate([z_all["real_3s"], z_all["real_1s"]])
    calib_y, calib_f = np.concatenate([y, y]), np.concatenate([fold_arr, fold_arr])
    for row in per_fold:
        others = calib_f != row["fold"]
        row["temperature"] = fit_temperature(calib[others], calib_y[others])
    react = np.array([room_reaction(label) for label in labels])
    conditions = {}
    for name, z in z_all.items():
        pred = z.argmax(1)
        s = classification_scores(y, pred, labels, datasets)
        s["room_reaction_accuracy"] = round(float((react[y] == react[pred]).mean()), 4)
        labelled = y != labels.index(IDLE_LABEL)
        s["accuracy_labelled"] = round(float((y == pred)[labelled].mean()), 4)
        conditions[name] = s
    out = {"labels": labels, "clips": len(order), "conditions": conditions,
           "folds": per_fold,
           "temperature_all": fit_temperature(calib, calib_y),
           "oof": {"logits": {k: v.tolist() for k, v in z_all.items()}, "y": y.tolist(),
                   "fold": fold_arr.tolist(), "names": [c.name for c in order],
                   "subjects": [c.subject_key for c in order], "datasets": datasets}}
    if keep_models:
        out["models"] = models
    return out


#: Classifies the room protocol's held-out windows: (training windows, held-out windows,
#: training labels, training subjects) -> predicted labels; windows are
#: (normalised (N, 75, J, 3), valid (N, 75)).
RoomClassifier = Callable[[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray],
                           np.ndarray, np.ndarray], np.ndarray]


def _room_baseline(clips: Sequence[GestureClip], method: str, classify: RoomClassifier,
                   folds: int | None, progress: bool) -> dict[str, Any]:
    """A model with no network on the room vocabulary's leave-subjects-out folds of
    :func:`run_room_protocol`: ``classify`` labels each held-out clip's ``real_3s`` /
    ``real_1s`` window from the training clips' windows of the same condition. Returns what
    :func:`room_nearest_neighbour` documents."""
    labels = list(GESTURE_LABELS)
    split = split_subject_folds(clips, **({} if folds is None else {"folds": folds}))
    names = ("real_3s", "real_1s")  # the keys of real_windows
    preds: dict[str, list[np.ndarray]] = {n: [] for n in names}
    order: list[GestureClip] = []
    per_fold = []
    for k, (train, test) in enumerate(tqdm(split, desc=f"room {method}",
                                           disable=not progress)):
        bank, query = real_windows(train), real_windows(test)
        y_train = np.array([labels.index(c.label) for c in train])
        groups = np.array([c.subject_key for c in train])
        y = np.array([labels.index(c.label) for c in test])
        row: dict[str, Any] = {"fold": k, "test_subjects": sorted({c.subject_key for c in test}),
                               "clips": len(test)}
        for n in names:
            pred = classify(bank[n], query[n], y_train, groups)
            preds[n].append(pred)
            row[n] = round(float((pred == y).mean()), 4)
        per_fold.append(row)
        order += test
    y = np.array([labels.index(c.label) for c in order])
    react = np.array([room_reaction(label) for label in labels])
    conditions = {}
    for n in names:
        pred = np.concatenate(preds[n])
        conditions[n] = classification_scores(y, pred, labels, [c.dataset for c in order])
        conditions[n]["room_reaction_accuracy"] = round(float((react[y] == react[pred]).mean()), 4)
    return {"room": True, "method": method, "clips": len(order),
            "conditions": conditions, "folds": per_fold}


def room_nearest_neighbour(clips: Sequence[GestureClip], distance: NeighbourDistance,
                           *, folds: int | None = None, progress: bool = True
                           ) -> dict[str, Any]:
    """The nearest-neighbour baseline on the room vocabulary, leave-subjects-out on the folds
    of :func:`run_room_protocol`: each held-out clip's ``real_3s`` / ``real_1s`` window takes
    the label of the nearest training clip's window of the same condition
    (:mod:`simenv.learning.nearest_neighbour`, real frames only).

    Returns:
        ``method``, ``clips``, ``conditions`` (per condition the pooled scores of
        :func:`classification_scores`, room-reaction accuracy included) and ``folds``
        (per fold its test subjects and accuracies).

    Raises:
        SimenvError: an unknown distance.
    """
    if distance not in NEIGHBOUR_DISTANCES:
        raise SimenvError(f"unknown distance {distance!r}; expected one of "
                          f"{', '.join(NEIGHBOUR_DISTANCES)}", field="neighbour")

    def classify(bank: tuple[np.ndarray, np.ndarray], query: tuple[np.ndarray, np.ndarray],
                 y_train: np.ndarray, groups: np.ndarray) -> np.ndarray:
        return nearest_neighbour(resample_sequences(*query), resample_sequences(*bank),
                                 y_train, distance)

    return _room_baseline(clips, f"nearest neighbour ({distance})", classify, folds, progress)


def room_descriptors(clips: Sequence[GestureClip], *, lie_group: bool = False,
                     folds: int | None = None, progress: bool = True) -> dict[str, Any]:
    """The covariance classifier (:mod:`simenv.learning.covariance`; with ``lie_group``, the
    Lie-group descriptors among its candidates too) on the room vocabulary, leave-subjects-out
    on the folds of :func:`run_room_protocol`: per fold and condition (``real_3s``,
    ``real_1s``) it is fitted on the training clips' windows, choosing its descriptor and
    regulariser by leave-one-training-subject-out accuracy, and labels the held-out windows.
    ``gesture15`` descriptors only (the room's joints). Returns what
    :func:`room_nearest_neighbour` documents, each fold's choices under ``chosen``."""
    chosen: list[dict[str, Any]] = []

    parents = clip_skeleton(clips).parents

    def variants(window: tuple[np.ndarray, np.ndarray]) -> dict[str, Descriptor]:
        return _with_pairs(*_window_descriptors(*window, "gesture15", parents, lie_group))

    def classify(bank: tuple[np.ndarray, np.ndarray], query: tuple[np.ndarray, np.ndarray],
                 y_train: np.ndarray, groups: np.ndarray) -> np.ndarray:
        clf = CovarianceClassifier(len(GESTURE_LABELS)).fit(variants(bank), y_train, groups)
        chosen.append({"variant": clf.variant, "lambda": clf.lam,
                       "held_out_accuracy": clf.selection[clf.variant][clf.lam]})
        return clf.predict_proba(variants(query)).argmax(1)

    method = "covariance and Lie-group descriptors" if lie_group else "covariance descriptors"
    result = _room_baseline(clips, method, classify, folds, progress)
    for k, row in enumerate(result["folds"]):
        row["chosen"] = dict(zip(("real_3s", "real_1s"), chosen[2 * k:2 * k + 2], strict=True))
    return result | {"descriptors": ["covariance", "lie group"] if lie_group
                     else ["covariance"]}


def calibrated(model: SkeletonTCN, temperature: float) -> SkeletonTCN:
    """``model`` with its softmax temperature set (in place; returned for chaining)."""
    model.config.temperature = float(temperature)
    return model


__all__ = ["BENCHMARK_FRAMES", "BENCHMARK_JOINTS", "FUSION_WEIGHTS", "PUBLISHED",
           "ROOM_CONDITIONS", "BenchmarkJoints", "NativeClip", "benchmark_folds",
           "classification_scores", "calibrated", "condition_windows", "fused_log_p",
           "fusion_weight", "mirror_clip", "native_clips",
           "native_skeleton", "room_descriptors", "run_benchmark", "run_room_protocol",
           "whole_windows",
           "window_mirror_complete"]
