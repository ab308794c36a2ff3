"""Ray backend: run a function over many items on a Ray cluster.

``simenv score --backend ray`` sends each target to a Ray task; results come
back in completion order, so the caller can append them to its results file
as they arrive. With ``address=None`` a local Ray instance is started (and
shut down afterwards); otherwise ``ray.init(address=...)`` joins an existing
cluster, e.g. ``"auto"`` or ``"ray://head:10001"``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from typing import Any, TypeVar

from simenv.core.errors import SimenvError

T = TypeVar("T")
R = TypeVar("R")


def _ray() -> Any:
    try:
        import ray
    except ImportError:
        raise SimenvError("the ray backend needs Ray: pip install 'ray>=2.9'",
                          field="backend") from None
    return ray


def ray_map(fn: Callable[[T, Any], R], items: Sequence[T], arg: Any, *, concurrency: int = 1,
            address: str | None = None) -> Iterator[tuple[T, R]]:
    """Yield ``(item, fn(item, arg))`` for every item, computed as Ray tasks.

    At most ``concurrency`` tasks are in flight (each asks for one CPU), so a
    long batch does not flood the cluster's scheduler; results are yielded as
    they complete. Exceptions raised by ``fn`` are re-raised here.
    """
    if not items:
        return
    ray = _ray()
    started = not ray.is_initialized()
    if started:
        ray.init(address=address, num_cpus=None if address else max(concurrency, 1),
                 include_dashboard=False, log_to_driver=False, ignore_reinit_error=True)
    try:
        task = ray.remote(num_cpus=1)(fn)
        pending: dict[Any, T] = {}
        queue = list(items)
        while queue or pending:
            while queue and len(pending) < max(concurrency, 1):
                item = queue.pop(0)
                pending[task.remote(item, arg)] = item
            ready, _ = ray.wait(list(pending), num_returns=1)
            ref = ready[0]
            yield pending.pop(ref), ray.get(ref)
    finally:
        if started:
            ray.shutdown()
