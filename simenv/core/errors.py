"""Exceptions raised on bad user input or failed computations.

Every error raised by simenv for user data is a :class:`SimenvError`. The
message always names *where* (file, line, frame, joint, field) and *what was
expected*, so a user can fix the input without reading a traceback.
"""

from __future__ import annotations

from os import PathLike


class SimenvError(Exception):
    """Base class of all simenv errors.

    Args:
        message: what is wrong and what was expected.
        source: file the data came from, if any.
        line: 1-based line number in ``source``, if known.
        frame: 0-based frame index, if known.
        field: name of the field/joint/channel concerned, if known.
    """

    def __init__(
        self,
        message: str,
        *,
        source: str | PathLike[str] | None = None,
        line: int | None = None,
        frame: int | None = None,
        field: str | None = None,
    ) -> None:
        self.detail = message
        self.source = None if source is None else str(source)
        self.line = line
        self.frame = frame
        self.field = field
        super().__init__(self._format())

    def _format(self) -> str:
        where = []
        if self.source is not None:
            where.append(self.source)
        if self.line is not None:
            where.append(f"line {self.line}")
        if self.frame is not None:
            where.append(f"frame {self.frame}")
        if self.field is not None:
            where.append(f"field {self.field!r}")
        return f"{', '.join(where)}: {self.detail}" if where else self.detail


class ReaderOptionError(SimenvError, TypeError):
    """An option given for a file whose reader does not take it (e.g. ``units=`` for a
    Kinect recording); a ``TypeError`` too, as a call with an unknown keyword is."""


class FormatError(SimenvError):
    """A file is malformed: truncated, non-numeric, wrong channel count, ..."""


class UnknownFormatError(SimenvError):
    """No reader recognises the file (by extension or content)."""


class MotionError(SimenvError):
    """Motion data is invalid: NaN/inf, empty, wrong shape or joint count."""


class SkeletonError(SimenvError):
    """A skeleton definition is invalid: duplicate names, bad parents, cycles."""


class UnitsError(MotionError):
    """Positions are not in plausible metres (e.g. a 180 m tall person)."""


class RetargetError(SimenvError):
    """Retargeting could not be carried out (missing keypoints, bad model)."""


class ScenarioError(SimenvError):
    """A room scenario file is invalid: TOML syntax, unknown or missing field, wrong type,
    value out of range, furniture outside the room or overlapping openings."""


class PhysicsError(SimenvError):
    """The simulation diverged (NaN state, MuJoCo warnings, blow-up)."""


class GeometryError(SimenvError):
    """An SRVF/hypersphere operation got arguments outside its domain: not on the
    sphere, not tangent, antipodal points, mismatched shapes, zero-length curves."""


class ReferenceDataError(SimenvError):
    """Scoring relative to real data cannot be done: an empty or too small
    reference corpus, a metric without reference values, a generated clip at
    a frame rate the reference does not have, a non-finite metric value."""
