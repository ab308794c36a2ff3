"""simenv.models: the seed networks (motion predictor, baselines, gesture classifier, the
two-person generators) and their checkpoints.

Shipped checkpoints live in ``simenv.assets`` under ``models/<name>.npz`` (arrays only,
no pickle) with a model card ``models/<name>.md``; :func:`load` reads them by name, e.g.
``simenv.models.load("predictor-25-25")``, ``simenv.models.load("gesture-classifier")`` or
``simenv.models.load("interformer")``. PyTorch is imported only when a model is loaded.
"""

from __future__ import annotations

from importlib import import_module, resources
from pathlib import Path
from typing import Any

from simenv.core.errors import SimenvError

__all__ = ["INTERACTION_MODELS", "available", "checkpoint_path", "interaction_model_class",
           "interaction_model_entry", "interaction_model_names", "load"]

#: The two-person models: registry name -> (module, class, kind). ``kind`` is
#: ``reaction`` (``generate(actor_window, reactor_first_frame)``, the protocol of
#: :mod:`simenv.models.reaction_baselines`), ``interaction`` (``sample(labels)``: both
#: people from a class label) or ``augmentation`` (``augment(actor, reactor, scales)``).
#: Each module also has ``train(windows, config, seed=, progress=) -> (model, history)``
#: and a ``<Class>Config`` dataclass (:mod:`simenv.learning.train_interaction` drives them).
INTERACTION_MODELS: dict[str, tuple[str, str, str]] = {
    "interformer": ("simenv.models.interformer", "InterFormer", "reaction"),
    "reactive-gan": ("simenv.models.reactive_gan", "ReactiveGAN", "reaction"),
    "bigraphdiff": ("simenv.models.bigraphdiff", "BiGraphDiff", "interaction"),
    "interaction-augment": ("simenv.models.interaction_augment", "InteractionAugmenter",
                            "augmentation"),
}

#: Name prefixes of shipped checkpoints and what they hold.
KINDS: tuple[str, ...] = ("predictor-", "gesture-classifier", "gesture-tcn",
                         "tracking-policy", *INTERACTION_MODELS)


def _folder() -> Path:
    return Path(str(resources.files("simenv.assets"))) / "models"


def available() -> list[str]:
    """Names of the shipped checkpoints (``predictor-<P>-<F>``, ``gesture-classifier`` and
    the :data:`INTERACTION_MODELS` that are shipped)."""
    folder = _folder()
    return sorted(p.stem for p in folder.glob("*.npz")) if folder.is_dir() else []


def checkpoint_path(name: str) -> Path:
    """The checkpoint file of a shipped model.

    Raises:
        SimenvError: unknown name (the message lists the available ones).
    """
    path = _folder() / f"{name}.npz"
    if not name.startswith(KINDS) or not path.is_file():
        names = ", ".join(available()) or "none shipped"
        raise SimenvError(
            f"unknown model {name!r}; available: {names} (and zero-velocity-<F>, "
            "constant-velocity-<F>)",
            field="name",
        )
    return path


def load(name: str) -> Any:
    """A shipped model by name.

    ``predictor-<P>-<F>`` names give a
    :class:`simenv.models.predictor.PredictiveMAWGAN` (P observed -> F predicted frames
    at 25 fps, ``predict(history)``), ``predictor-dctmlp-<P>-<F>`` the regression
    baseline :class:`simenv.models.predictor_regression.DCTRegressionPredictor` (same
    interface), ``predictor-gesture-<P>-<F>`` the gesture-domain forecaster
    :class:`simenv.models.gesture_predictor.GesturePredictor` (world-frame gesture15
    joints, not pred17); ``zero-velocity-<F>`` / ``constant-velocity-<F>``
    give the baselines; ``gesture-tcn`` one skeleton TCN
    :class:`simenv.models.skeleton_tcn.SkeletonTCN` (any window length, calibrated
    probabilities), ``gesture-tcn-ensemble`` the room's recogniser, TCNs run as one
    :class:`simenv.models.skeleton_tcn.SkeletonTCNEnsemble`; ``gesture-classifier`` gives a
    :class:`simenv.models.gesture_classifier.GestureClassifier` (``classify_world``,
    ``predict_proba``, ``features``); ``tracking-policy`` the learned tracking policy
    :class:`simenv.control.policy.TrackingPolicy` (an experiment, not used in scoring:
    docs/tracking_speed.md); an :data:`INTERACTION_MODELS` name gives that two-person model.

    Raises:
        SimenvError: unknown name (the message lists the available ones).
    """
    # Each model's module (PyTorch) is imported only when that model is loaded.
    from simenv.models.baselines import ConstantVelocity, ZeroVelocity

    for prefix, cls in (("zero-velocity-", ZeroVelocity),
                        ("constant-velocity-", ConstantVelocity)):
        if name.startswith(prefix) and name[len(prefix):].isdigit():
            return cls(int(name[len(prefix):]))
    path = checkpoint_path(name)
    if name.startswith("predictor-gesture-"):
        from simenv.models.gesture_predictor import GesturePredictor

        return GesturePredictor.load(path)
    if name.startswith("predictor-dctmlp-"):
        from simenv.models.predictor_regression import DCTRegressionPredictor

        return DCTRegressionPredictor.load(path)
    if name in INTERACTION_MODELS:
        return interaction_model_class(name).load(path)
    if name.startswith("gesture-tcn-ensemble"):
        from simenv.models.skeleton_tcn import SkeletonTCNEnsemble

        return SkeletonTCNEnsemble.load(path)
    if name.startswith("gesture-tcn"):
        from simenv.models.skeleton_tcn import SkeletonTCN

        return SkeletonTCN.load(path)
    if name.startswith("tracking-policy"):
        from simenv.control.policy import TrackingPolicy

        return TrackingPolicy.load(path)
    if name.startswith("gesture-classifier"):
        from simenv.models.gesture_classifier import GestureClassifier

        return GestureClassifier.load(path)
    from simenv.models.predictor import PredictiveMAWGAN

    return PredictiveMAWGAN.load(path)


def interaction_model_names(*kinds: str) -> list[str]:
    """Registry names of the :data:`INTERACTION_MODELS` of the given kinds (all without)."""
    return [n for n, (_, _, kind) in INTERACTION_MODELS.items() if not kinds or kind in kinds]


def interaction_model_entry(name: str, kinds: tuple[str, ...] = (), field: str = "model"
                            ) -> tuple[str, str, str]:
    """``(module, class, kind)`` of a two-person model, one of ``kinds`` if given.

    Raises:
        SimenvError: not a registered name, or not of those kinds (the message lists the
            names that are).
    """
    known = interaction_model_names(*kinds)
    if name not in known:
        what = (f"{name!r} is not a {' or '.join(kinds)} generator" if kinds else
                f"unknown two-person model {name!r}")
        raise SimenvError(f"{what}; known: {', '.join(known)}", field=field)
    return INTERACTION_MODELS[name]


def interaction_model_class(name: str) -> Any:
    """The class of an :data:`INTERACTION_MODELS` entry (its module imported on demand).

    Raises:
        SimenvError: not a two-person model name.
    """
    module, cls, _ = interaction_model_entry(name)
    return getattr(import_module(module), cls)
