"""simenv.models: the seed networks (motion predictor and baselines) and their checkpoints.

Shipped checkpoints live in ``simenv.assets`` under ``models/<name>.npz`` with a model
card ``models/<name>.md``; :func:`load` reads them by name, e.g.
``simenv.models.load("predictor-25-25")``. PyTorch is imported only when a model is
loaded.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any

from simenv.errors import SimenvError

__all__ = ["available", "load"]


def _folder() -> Path:
    return Path(str(resources.files("simenv.assets"))) / "models"


def available() -> list[str]:
    """Names of the shipped checkpoints (``predictor-<P>-<F>``)."""
    folder = _folder()
    return sorted(p.stem for p in folder.glob("*.npz")) if folder.is_dir() else []


def load(name: str) -> Any:
    """A shipped model by name, ready to ``predict``.

    ``predictor-<P>-<F>`` names give a
    :class:`simenv.models.predictor.PredictiveMAWGAN` (P observed -> F predicted frames
    at 25 fps); ``zero-velocity-<F>`` / ``constant-velocity-<F>`` give the baselines.

    Raises:
        SimenvError: unknown name (the message lists the available ones).
    """
    from simenv.models.baselines import ConstantVelocity, ZeroVelocity

    for prefix, cls in (("zero-velocity-", ZeroVelocity),
                        ("constant-velocity-", ConstantVelocity)):
        if name.startswith(prefix) and name[len(prefix):].isdigit():
            return cls(int(name[len(prefix):]))
    path = _folder() / f"{name}.npz"
    if not name.startswith("predictor-") or not path.is_file():
        names = ", ".join(available()) or "none shipped"
        raise SimenvError(
            f"unknown model {name!r}; available: {names} (and zero-velocity-<F>, "
            "constant-velocity-<F>)",
            field="name",
        )
    from simenv.models.predictor import PredictiveMAWGAN

    return PredictiveMAWGAN.load(path)
