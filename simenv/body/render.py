"""Offscreen rendering of joint trajectories to RGB frames and MP4 video.

A trajectory ``qpos`` (T, nq) of a MuJoCo model is drawn frame by frame with
:class:`mujoco.Renderer` (offscreen; ``MUJOCO_GL=osmesa`` on a CPU, chosen by
:mod:`simenv.body.gl` at package import). The source joints can be drawn on top as a *ghost*:
small spheres at the keypoints and thin capsules along the bones, added to the renderer's
``mjvScene`` after ``update_scene`` so they are not part of the model (no collisions, no mass).

Camera: a free camera looks at the *followed point*, the mean world position of the followed
bodies (default: every body attached to the world by a free joint, i.e. the pelvis of each
person). Its height is the clip's median, so the view does not bob with the gait; its azimuth is
perpendicular to the principal horizontal axis of the followed bodies' positions over the clip
(a walk is seen from the side, two people facing each other are both in view) or, when they stay
in place, a three-quarter front view; its distance grows with the people's separation.
"""

from __future__ import annotations

import logging
import os
import sys
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import cv2
import mujoco
import numpy as np
from tqdm import tqdm

from simenv.body import gl
from simenv.core.errors import SimenvError
from simenv.core.skeletons import CANONICAL_TREE

log = logging.getLogger(__name__)

#: RGBA of the ghost of person 0, 1, ... (cycled): orange, cyan, magenta, yellow.
GHOST_COLOURS = (
    (1.0, 0.55, 0.0, 0.85),
    (0.0, 0.8, 1.0, 0.85),
    (1.0, 0.2, 0.8, 0.85),
    (1.0, 0.95, 0.1, 0.85),
)
#: Radius (m) of a ghost keypoint sphere; bones are capsules of half this radius.
GHOST_RADIUS = 0.03
#: Emission of ghost geoms: they keep their colour whatever the lighting of the model.
GHOST_EMISSION = 0.7
#: RMS horizontal extent (m) of the followed bodies' positions below which the subject counts as
#: staying in place: the camera then faces them instead of looking across their path.
STILL_EXTENT = 0.25
#: Minimum camera distance (m) to the followed point.
MIN_DISTANCE = 3.0
#: Opacity of the body's geoms when a ghost is drawn, so the ghost inside the limbs shows.
BODY_ALPHA_WITH_GHOST = 0.55
#: MP4 codecs (FourCC) :func:`write_video` tries, in order: H.264, which every browser plays
#: (absent from OpenCV's pip wheels), then MPEG-4 part 2, which OpenCV always has.
VIDEO_CODECS = ("avc1", "mp4v")
#: Codec of the WebM copy of :class:`WebVideo`: VP8, which browsers play, unlike ``mp4v``
#: (VP8 costs ~20 ms a 480x360 frame on a CPU core; VP9, playable inside an MP4, ~140 ms).
WEBM_CODECS = ("VP80",)
#: Opacity of the dark band behind a caption (:func:`caption_frame`): the scene shows through.
CAPTION_BAND_ALPHA = 0.6
#: Height of one caption line as a fraction of the frame height (15 px at 360 rows).
CAPTION_LINE_FRACTION = 1 / 24


def _as_ghost_list(
    ghost: np.ndarray | Sequence[np.ndarray] | None, n_frames: int
) -> list[np.ndarray]:
    if ghost is None:
        return []
    ghosts = [ghost] if isinstance(ghost, np.ndarray) else list(ghost)
    out = []
    for i, g in enumerate(ghosts):
        arr = np.asarray(g, dtype=np.float64)
        if arr.ndim != 3 or arr.shape[0] != n_frames or arr.shape[2] != 3:
            raise SimenvError(
                f"ghost {i} has shape {arr.shape}; expected ({n_frames}, K, 3) keypoints in metres",
                field="ghost",
            )
        out.append(arr)
    return out


def _follow_body_ids(model: mujoco.MjModel, follow_body: str | Sequence[str] | None) -> list[int]:
    if follow_body is None:
        ids = [
            int(model.jnt_bodyid[j])
            for j in range(model.njnt)
            if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE
            and model.body_parentid[model.jnt_bodyid[j]] == 0
        ]
        return ids or [0]
    names = [follow_body] if isinstance(follow_body, str) else list(follow_body)
    ids = []
    for name in names:
        body_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
        if body_id < 0:
            raise SimenvError(f"model has no body {name!r} to follow", field="follow_body")
        ids.append(body_id)
    return ids


def _camera_track(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    body_ids: list[int],
    distance: float | None,
    azimuth: float | None,
) -> tuple[np.ndarray, float, float]:
    """Look-at points (T, 3), distance (m) and azimuth (degrees) for the frames of ``qpos``."""
    data = mujoco.MjData(model)
    body_pos = np.empty((len(qpos), len(body_ids), 3))
    forward = np.zeros(2)
    for t, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        body_pos[t] = data.xpos[body_ids]
        forward += data.xmat[body_ids][:, [0, 3]].sum(axis=0)  # bodies' x axes (forward), in xy
    lookat = body_pos.mean(axis=1)
    lookat[:, 2] = np.median(lookat[:, 2])
    if azimuth is None:
        xy = body_pos[..., :2].reshape(-1, 2)
        xy = xy - xy.mean(axis=0)
        _, sv, vt = np.linalg.svd(xy, full_matrices=False)
        if sv[0] / np.sqrt(len(xy)) > STILL_EXTENT:
            # Principal horizontal axis of where the followed bodies go; look across it.
            azimuth = float(np.degrees(np.arctan2(vt[0, 1], vt[0, 0]))) + 90.0
        else:
            # Nobody goes anywhere: look at the front, from 30 degrees to the side.
            azimuth = float(np.degrees(np.arctan2(forward[1], forward[0]))) + 150.0
    if distance is None:
        spread = np.linalg.norm(body_pos - body_pos.mean(axis=1, keepdims=True), axis=2).max()
        distance = max(MIN_DISTANCE, 2.5 + 2.0 * float(spread))
    return lookat, float(distance), float(azimuth)


def _add_ghost(
    scene: mujoco.MjvScene,
    points: np.ndarray,
    edges: Sequence[tuple[int, int]],
    rgba: tuple[float, float, float, float],
) -> None:
    """Append keypoint spheres and bone capsules to ``scene`` (as many as fit)."""
    eye = np.eye(3).ravel()
    rgba_arr = np.asarray(rgba, dtype=np.float32)
    for p in points:
        if scene.ngeom >= scene.maxgeom or not np.all(np.isfinite(p)):
            continue
        mujoco.mjv_initGeom(
            scene.geoms[scene.ngeom],
            mujoco.mjtGeom.mjGEOM_SPHERE,
            np.array([GHOST_RADIUS, 0.0, 0.0]),
            p,
            eye,
            rgba_arr,
        )
        scene.geoms[scene.ngeom].emission = GHOST_EMISSION
        scene.ngeom += 1
    for a, b in edges:
        if scene.ngeom >= scene.maxgeom:
            return
        if not (np.all(np.isfinite(points[a])) and np.all(np.isfinite(points[b]))):
            continue
        geom = scene.geoms[scene.ngeom]
        mujoco.mjv_initGeom(
            geom, mujoco.mjtGeom.mjGEOM_CAPSULE, np.zeros(3), np.zeros(3), eye, rgba_arr
        )
        mujoco.mjv_connector(
            geom, mujoco.mjtGeom.mjGEOM_CAPSULE, GHOST_RADIUS / 2, points[a], points[b]
        )
        geom.emission = GHOST_EMISSION
        scene.ngeom += 1


def _fade_bodies(scene: mujoco.MjvScene, alpha: float) -> None:
    """Make the model's non-plane geoms in ``scene`` translucent (floor and decor stay opaque)."""
    for i in range(scene.ngeom):
        geom = scene.geoms[i]
        if geom.objtype == mujoco.mjtObj.mjOBJ_GEOM and geom.type != mujoco.mjtGeom.mjGEOM_PLANE:
            geom.rgba[3] = min(geom.rgba[3], alpha)


def _overlay(frame: np.ndarray, text: str) -> np.ndarray:
    """Draw ``text`` top-left with a dark outline so it reads on any background."""
    frame = np.ascontiguousarray(frame)
    for colour, thickness in (((0, 0, 0), 3), ((255, 255, 255), 1)):
        cv2.putText(
            frame, text, (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, colour, thickness, cv2.LINE_AA
        )
    return frame


def caption_frame(frame: np.ndarray, lines: Sequence[str]) -> np.ndarray:
    """A copy of ``frame`` with ``lines`` written in a semi-transparent dark band at its bottom.

    Each line is :data:`CAPTION_LINE_FRACTION` of the frame height (at least 10 px), white
    anti-aliased Hershey text, scaled down if needed so that the longest line fits the width;
    the band (:data:`CAPTION_BAND_ALPHA`) is as tall as the lines.

    Args:
        frame: RGB image, uint8 (H, W, 3).
        lines: text, top to bottom; ASCII (OpenCV's Hershey fonts draw no other characters).

    Returns:
        The captioned image, uint8 (H, W, 3).

    Raises:
        SimenvError: ``frame`` is not a uint8 (H, W, 3) image.
    """
    out = np.array(frame, copy=True)
    if out.ndim != 3 or out.shape[2] != 3 or out.dtype != np.uint8:
        raise SimenvError(
            f"frame is {out.dtype} {out.shape}; expected uint8 (H, W, 3) RGB", field="frame"
        )
    if not lines:
        return out
    h, w = out.shape[:2]
    font, pad = cv2.FONT_HERSHEY_SIMPLEX, 4
    step = max(10, round(h * CAPTION_LINE_FRACTION))  # px per line
    ascent = cv2.getTextSize("A", font, 1.0, 1)[0][1]  # px at scale 1
    widest = max(cv2.getTextSize(line, font, 1.0, 1)[0][0] for line in lines)
    # Capitals take 70 % of a line, leaving room for descenders and the gap.
    scale = min(0.7 * step / ascent, (w - 2 * pad) / max(widest, 1))
    top = max(0, h - len(lines) * step - pad)
    out[top:] = (out[top:] * (1.0 - CAPTION_BAND_ALPHA)).astype(np.uint8)
    for i, line in enumerate(lines):
        baseline = top + pad // 2 + i * step + round(0.5 * step + 0.5 * ascent * scale)
        cv2.putText(out, line, (pad, baseline), font, scale, (255, 255, 255), 1, cv2.LINE_AA)
    return out


#: Shadow-map side per pixel of the image's larger side. MuJoCo's default map (4096 px) is most
#: of a frame's cost under OSMesa: at 320x240 a frame of the fitted walker cost 94 ms of CPU
#: with it, 26 ms with 1024 px (this scale), 9 ms without shadows; the 1024-px frames differ
#: from the 4096-px ones by 0.02 grey levels per pixel on average.
SHADOW_MAP_SCALE = 4


def make_renderer(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    """Create an offscreen renderer, turning a missing OpenGL into a clear :class:`SimenvError`.

    The model's offscreen framebuffer is enlarged in place when smaller than ``width`` x ``height``,
    and its shadow map shrunk in place to :data:`SHADOW_MAP_SCALE` times the image's larger side.
    """
    if width < 16 or height < 16:
        raise SimenvError(f"image size {width}x{height} too small; expected at least 16x16")
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    model.vis.quality.shadowsize = min(model.vis.quality.shadowsize,
                                       SHADOW_MAP_SCALE * max(width, height))
    try:
        return mujoco.Renderer(model, height=height, width=width)
    except Exception as err:  # any GL failure: missing library, no context, bad backend
        backend = os.environ.get("MUJOCO_GL", "<unset>")
        late = (
            " (mujoco was imported before simenv, so it did not see simenv's choice)"
            if gl.MUJOCO_IMPORTED_FIRST
            else ""
        )
        raise SimenvError(
            f"offscreen rendering is unavailable (MUJOCO_GL={backend}{late}): {err}. On a CPU "
            "install OSMesa (`apt-get install libosmesa6`) and set MUJOCO_GL=osmesa, or set "
            "MUJOCO_GL=egl where an EGL driver is present; set it before Python starts."
        ) from err


def _checked_qpos(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """``qpos`` as float64 (T, nq), T >= 1, finite; else the first bad frame is named."""
    qpos = np.asarray(qpos, dtype=np.float64)
    if qpos.ndim != 2 or qpos.shape[1] != model.nq or qpos.shape[0] == 0:
        raise SimenvError(
            f"qpos has shape {qpos.shape}; expected (T>=1, {model.nq}) for this model", field="qpos"
        )
    bad = np.flatnonzero(~np.all(np.isfinite(qpos), axis=1))
    if bad.size:
        raise SimenvError("qpos is not finite", frame=int(bad[0]), field="qpos")
    return qpos


def _checked_ghosts(ghost: np.ndarray | Sequence[np.ndarray] | None,
                    ghost_edges: Sequence[tuple[int, int]], length: int) -> list[np.ndarray]:
    """The ghosts as a list of (T, K, 3) arrays whose keypoints every edge indexes."""
    ghosts = _as_ghost_list(ghost, length)
    for a, b in ghost_edges:
        for g in ghosts:
            if not (0 <= a < g.shape[1] and 0 <= b < g.shape[1]):
                raise SimenvError(
                    f"ghost edge ({a}, {b}) outside the {g.shape[1]} keypoints", field="ghost_edges"
                )
    return ghosts


def render_frames(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    *,
    width: int = 320,
    height: int = 240,
    ghost: np.ndarray | Sequence[np.ndarray] | None = None,
    ghost_edges: Sequence[tuple[int, int]] = (),
    follow_body: str | Sequence[str] | None = None,
    distance: float | None = None,
    elevation: float = -15.0,
    azimuth: float | None = None,
    fps: float | None = None,
    stride: int = 1,
    max_frames: int | None = None,
    overlay: bool = True,
) -> Iterator[np.ndarray]:
    """Render the trajectory ``qpos`` offscreen, one RGB image per selected frame.

    Args:
        model: the MuJoCo model whose joint positions ``qpos`` describes.
        qpos: joint positions, shape (T, model.nq).
        width, height: image size in pixels.
        ghost: source keypoints (T, K, 3) in metres (world frame), or a list of such arrays
            (one per person), drawn as spheres; NaN keypoints are skipped.
        ghost_edges: pairs (i, j) of keypoint indices joined by a bone capsule in every ghost.
        follow_body: body name(s) the camera tracks (mean position); default every body
            attached to the world by a free joint (each person's pelvis).
        distance: camera distance (m); default from the people's spread, at least 3 m.
        elevation: camera elevation (degrees, negative looks down).
        azimuth: camera azimuth (degrees); default perpendicular to the direction of travel,
            or facing the subject when it stays in place.
        fps: frame rate of ``qpos``; when given the overlay shows the time in seconds.
        stride: render every ``stride``-th frame.
        max_frames: render at most this many frames (after the stride).
        overlay: draw "frame i  t=...s" on each image.

    Yields:
        RGB images, uint8 arrays of shape (height, width, 3), for frames 0, stride, 2*stride, ...

    Raises:
        SimenvError: bad shapes or non-finite ``qpos``, unknown body, or no OpenGL.
    """
    qpos = _checked_qpos(model, qpos)
    if stride < 1 or (max_frames is not None and max_frames < 1):
        raise SimenvError(f"stride={stride}, max_frames={max_frames}; expected both >= 1")
    ghosts = _checked_ghosts(ghost, ghost_edges, len(qpos))
    indices = np.arange(0, len(qpos), stride)[:max_frames]
    lookat, distance, azimuth = _camera_track(
        model, qpos[indices], _follow_body_ids(model, follow_body), distance, azimuth
    )
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.distance, camera.elevation, camera.azimuth = distance, elevation, azimuth
    data = mujoco.MjData(model)
    renderer = make_renderer(model, width, height)
    try:
        for k, t in enumerate(indices):
            data.qpos[:] = qpos[t]
            mujoco.mj_forward(model, data)
            camera.lookat[:] = lookat[k]
            renderer.update_scene(data, camera)
            if ghosts:
                _fade_bodies(renderer.scene, BODY_ALPHA_WITH_GHOST)
            for i, g in enumerate(ghosts):
                _add_ghost(renderer.scene, g[t], ghost_edges, GHOST_COLOURS[i % len(GHOST_COLOURS)])
            frame = renderer.render()
            if overlay:
                text = f"frame {t}" + (f"  t={t / fps:.2f}s" if fps else "")
                frame = _overlay(frame, text)
            yield frame
    finally:
        renderer.close()


@contextmanager
def _native_stderr_captured() -> Iterator[list[str]]:
    """Capture what native code writes to file descriptor 2 inside the block, and log it at
    DEBUG level instead; the list yielded holds those lines once the block ends.

    OpenCV opens an encoder by trying it: FFmpeg reports each encoder it cannot open
    (``[h264_v4l2m2m @ ...] Could not find a valid device``, ``can't configure encoder``
    when the OpenCV wheel has no H.264) and OpenCV reports the WebM container's tags
    (``tag 'VP80' is not supported``, yet it writes VP8), both straight to the C stderr,
    which neither OpenCV's log level nor Python's ``sys.stderr`` governs. The block lasts
    while OpenCV opens one file (milliseconds); what another thread prints meanwhile goes to
    the same DEBUG log. Without a descriptor 2 (or where it cannot be duplicated) nothing is
    captured.
    """
    said: list[str] = []
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):  # no stderr to capture
        yield said
        return
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield said
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            said += [line for line in sink.read().decode(errors="replace").splitlines()
                     if line.strip()]
            for line in said:
                log.debug("video encoder: %s", line)


class VideoFile:
    """A video file written one RGB frame at a time, so that no frame is kept in memory.

    The first frame fixes the size; the file opens with the first of ``codecs`` this OpenCV
    build can encode, chosen without printing: what FFmpeg says while OpenCV tries the
    encoders is logged at DEBUG level (:func:`_native_stderr_captured`), and is part of the
    error when none opens. Use it as a context manager (or call :meth:`close`).

    Args:
        path: output file; its folder is created. Use the ``.mp4`` suffix.
        fps: playback frame rate (frames per second), > 0.
        codecs: FourCC codes tried in order.

    Raises:
        SimenvError: bad fps.
    """

    def __init__(
        self, path: str | os.PathLike[str], fps: float, codecs: Sequence[str] = VIDEO_CODECS
    ) -> None:
        self.path = Path(path)
        if not (np.isfinite(fps) and fps > 0):
            raise SimenvError(f"video fps {fps}; expected a positive number", source=self.path)
        self.fps = float(fps)
        self.codecs = tuple(codecs)
        #: The FourCC the file is encoded with, once the first frame is written.
        self.codec: str | None = None
        self.count = 0
        self._writer: cv2.VideoWriter | None = None
        self._size: tuple[int, int] | None = None
        self.path.parent.mkdir(parents=True, exist_ok=True)

    def write(self, frame: np.ndarray) -> None:
        """Append an RGB frame, uint8 (H, W, 3) of the first frame's size.

        Raises:
            SimenvError: a frame of another type, shape or size, or no codec can write
                the file.
        """
        frame = np.asarray(frame)
        if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
            raise SimenvError(
                f"frame {self.count} is {frame.dtype} {frame.shape}; expected uint8 (H, W, 3) RGB",
                source=self.path,
            )
        size = (frame.shape[1], frame.shape[0])
        if self._writer is None:
            self._writer, self.codec = self._open(size)
            self._size = size
        elif size != self._size:
            raise SimenvError(
                f"frame {self.count} is {size[0]}x{size[1]}; expected {self._size[0]}x"
                f"{self._size[1]} like frame 0",
                source=self.path,
            )
        self._writer.write(cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
        self.count += 1

    def _open(self, size: tuple[int, int]) -> tuple[cv2.VideoWriter, str]:
        cv_log = cv2.utils.logging
        level = cv_log.getLogLevel()
        # A missing encoder is expected (pip wheels have no H.264): OpenCV need not log it.
        cv_log.setLogLevel(cv_log.LOG_LEVEL_SILENT)
        try:
            with _native_stderr_captured() as said:
                for codec in self.codecs:
                    writer = cv2.VideoWriter(
                        str(self.path), cv2.VideoWriter_fourcc(*codec), self.fps, size
                    )
                    if writer.isOpened():
                        return writer, codec
                    writer.release()
        finally:
            cv_log.setLogLevel(level)
        raise SimenvError(
            f"OpenCV cannot open the file for writing with any of the codecs {self.codecs}"
            + (f"; FFmpeg said: {' / '.join(said)}" if said else ""),
            source=self.path,
        )

    def close(self) -> Path:
        """Finish the file and return its path.

        Raises:
            SimenvError: no frame was written.
        """
        if self._writer is not None:
            self._writer.release()
            self._writer = None
        if self.count == 0:
            raise SimenvError("no frames to write", source=self.path)
        return self.path

    def __enter__(self) -> VideoFile:
        return self

    def __exit__(self, kind: type[BaseException] | None, *_: object) -> None:
        if kind is None:
            self.close()
        elif self._writer is not None:  # keep the error that stopped the writing
            self._writer.release()


class WebVideo:
    """A video for a web page, written frame by frame: ``path`` (MP4, :data:`VIDEO_CODECS`)
    and, unless that is H.264, the same frames in ``path`` with the ``.webm`` suffix
    (:data:`WEBM_CODECS`), since browsers do not decode ``mp4v``. A context manager.

    Args:
        path: the MP4 file; its folder is created.
        fps: playback frame rate (frames per second), > 0.

    Attributes:
        mp4: the MP4 :class:`VideoFile`.
        webm: the WebM :class:`VideoFile`, or None (H.264 MP4, or no VP8 encoder: a warning
            is logged).
    """

    def __init__(self, path: str | os.PathLike[str], fps: float) -> None:
        self.mp4 = VideoFile(path, fps)
        self.webm: VideoFile | None = None

    def write(self, frame: np.ndarray) -> None:
        """Append an RGB frame, uint8 (H, W, 3), to both files (:meth:`VideoFile.write`)."""
        self.mp4.write(frame)
        if self.mp4.count == 1 and self.mp4.codec != "avc1":
            webm = VideoFile(self.mp4.path.with_suffix(".webm"), self.mp4.fps, WEBM_CODECS)
            try:
                webm.write(frame)
            except SimenvError as err:
                log.warning("no WebM copy, browsers may not play %s: %s", self.mp4.path, err)
            else:
                self.webm = webm
        elif self.webm is not None:
            self.webm.write(frame)

    def __enter__(self) -> WebVideo:
        return self

    def __exit__(self, *exc: object) -> None:
        for video in (self.mp4, self.webm):
            if video is not None:
                video.__exit__(*exc)


def write_video(frames: Iterable[np.ndarray], path: str | os.PathLike[str], fps: float) -> Path:
    """Write RGB frames (H, W, 3) uint8 to an MP4 file (OpenCV, :class:`VideoFile`).

    Args:
        frames: images of equal size, e.g. from :func:`render_frames`.
        path: output file; its folder is created. Use the ``.mp4`` suffix.
        fps: playback frame rate (frames per second), > 0.

    Returns:
        The path written.

    Raises:
        SimenvError: no frames, frames of different sizes, bad fps, or the file cannot be opened.
    """
    with VideoFile(path, fps) as video:
        for frame in frames:
            video.write(frame)
    return video.path


def keypoint_edges(names: Sequence[str]) -> list[tuple[int, int]]:
    """Bones (parent index, child index) of the canonical tree among keypoints ``names``.

    A keypoint whose canonical parent is absent is joined to its nearest present ancestor.
    """
    index = {name: i for i, name in enumerate(names)}
    edges = []
    for name, i in index.items():
        parent = CANONICAL_TREE.get(name)
        while parent is not None and parent not in index:
            parent = CANONICAL_TREE.get(parent)
        if parent is not None:
            edges.append((index[parent], i))
    return edges


def _result_parts(result: Any) -> tuple[mujoco.MjModel, np.ndarray, list[np.ndarray], list[str]]:
    """Model, qpos, ghost keypoints per person and keypoint names of a retargeting result."""
    people = None
    for attr in ("people", "results", "persons"):
        people = getattr(result, attr, None)
        if people is not None:
            break
    if people is None:
        model = result.humanoid.model
        people = [result]
    else:
        scene = getattr(result, "scene", None)
        model = getattr(scene, "model", None) or result.model
    person = people[0]
    names = list(
        getattr(person, "keypoint_names", None)
        or getattr(getattr(person, "humanoid", None), "keypoint_names", None)
        or ()
    )
    return model, np.asarray(result.qpos), [np.asarray(p.targets) for p in people], names


def render_result(
    result: Any,
    path: str | os.PathLike[str],
    *,
    stride: int = 1,
    max_frames: int | None = None,
    width: int = 320,
    height: int = 240,
    progress: bool = False,
    web: bool = False,
) -> Path:
    """Render a retargeting result (one or two people) to MP4: humanoids plus source ghosts.

    Args:
        result: a :class:`simenv.body.retarget.RetargetResult` or its two-person counterpart
            (all people in one scene, camera on the centre of both).
        path: output ``.mp4``.
        stride: render every ``stride``-th frame; the video plays at ``fps / stride`` so it
            keeps real-time speed.
        max_frames: render at most this many frames.
        width, height: image size in pixels.
        progress: show a progress bar on stderr (when it is a terminal).
        web: also write the WebM copy browsers play (:class:`WebVideo`), next to ``path``.

    Returns:
        The path written (the MP4).
    """
    model, qpos, ghosts, names = _result_parts(result)
    edges = keypoint_edges(names) if names else []
    fps = float(result.fps)
    total = len(range(0, len(qpos), stride)[:max_frames])
    frames = render_frames(model, qpos, width=width, height=height, ghost=ghosts,
                           ghost_edges=edges, fps=fps, stride=stride, max_frames=max_frames)
    frames = tqdm(frames, total=total, desc=f"render {Path(path).name}", unit="frame",
                  disable=None if progress else True, leave=False)
    if not web:
        return write_video(frames, path, fps=fps / stride)
    with WebVideo(path, fps / stride) as video:
        for frame in frames:
            video.write(frame)
    return video.mp4.path
