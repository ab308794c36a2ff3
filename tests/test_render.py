"""Offscreen rendering and MP4 writing, on the bundled real CMU walk (02_01)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import cv2
import mujoco
import numpy as np
import pytest

from simenv.assets import WALK, asset_path
from simenv.body.render import (
    CAPTION_BAND_ALPHA,
    CAPTION_LINE_FRACTION,
    caption_frame,
    render_frames,
    write_video,
)
from simenv.core.errors import SimenvError
from simenv.io import bvh

N_FRAMES = 6  # rendering costs ~0.05-0.1 s a frame on a CPU: keep videos short


@pytest.fixture(scope="module")
def walk():
    """Canonical keypoints (T, K, 3) of the real walk and a one-body model riding its pelvis."""
    motion = bvh.read(asset_path(WALK)).to_canonical()
    spec = mujoco.MjSpec()
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[20, 20, 0.1])
    torso = spec.worldbody.add_body(name="pelvis")
    torso.add_freejoint()
    torso.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, fromto=[0, 0, -0.1, 0, 0, 0.5], size=[0.12])
    model = spec.compile()
    pelvis = motion.joint("pelvis").astype(np.float64)
    qpos = np.zeros((motion.num_frames, model.nq))
    qpos[:, :3] = pelvis
    qpos[:, 3] = 1.0
    edges = motion.skeleton.bones
    return model, qpos, motion.positions.astype(np.float64), edges, motion.fps


def _ghost_mask(frame: np.ndarray) -> np.ndarray:
    """Pixels of the default ghost colour of person 0 (orange: red high, blue low)."""
    r, g, b = (frame[..., i].astype(int) for i in range(3))
    return (r > 150) & (b < 90) & (r - b > 100) & (g < r)


def test_frames_shape_stride_and_ghost(walk):
    model, qpos, keypoints, edges, fps = walk
    frames = list(
        render_frames(model, qpos, ghost=keypoints, ghost_edges=edges, fps=fps,
                      stride=60, max_frames=N_FRAMES, width=160, height=120)
    )
    assert len(frames) == N_FRAMES
    for frame in frames:
        assert frame.shape == (120, 160, 3) and frame.dtype == np.uint8
        assert frame.std() > 5  # not a blank image
        assert _ghost_mask(frame).sum() > 20  # the source skeleton is drawn in its colour
    plain = next(render_frames(model, qpos, max_frames=1, width=160, height=120, overlay=False))
    assert _ghost_mask(plain).sum() == 0


def test_camera_follows_the_subject(walk):
    model, qpos, keypoints, edges, fps = walk
    travelled = np.linalg.norm(qpos[-1, :2] - qpos[0, :2])
    assert travelled > 1.5  # the real walk covers metres, so a fixed camera would lose it
    frames = list(
        render_frames(model, qpos, ghost=keypoints, ghost_edges=edges, stride=len(qpos) - 1,
                      width=160, height=120, overlay=False)
    )
    assert len(frames) == 2  # first and last frame of the clip, in one camera track
    for frame in frames:
        ys, xs = np.nonzero(_ghost_mask(frame))
        assert xs.size > 20
        assert abs(xs.mean() - 80) < 30 and abs(ys.mean() - 60) < 40


def test_write_video_roundtrip(walk, tmp_path: Path):
    model, qpos, keypoints, edges, fps = walk
    out = write_video(
        render_frames(model, qpos, ghost=keypoints, ghost_edges=edges, fps=fps,
                      stride=30, max_frames=N_FRAMES),
        tmp_path / "sub" / "walk.mp4",
        fps=fps / 30,
    )
    assert out.is_file() and out.stat().st_size > 1000
    cap = cv2.VideoCapture(str(out))
    try:
        assert cap.isOpened()
        assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == N_FRAMES
        assert int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)) == 320
        assert int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)) == 240
        assert cap.get(cv2.CAP_PROP_FPS) == pytest.approx(fps / 30, rel=1e-3)
        ok, image = cap.read()
        assert ok and image.std() > 5
    finally:
        cap.release()


@pytest.mark.parametrize("size", [(480, 360), (640, 480)])
def test_caption_draws_in_a_dark_band_at_the_bottom(walk, size):
    """White text on a darkened band as tall as the lines; the scene above is untouched;
    a line too long for the width is shrunk to fit."""
    model, qpos, *_ = walk
    width, height = size
    frame = next(render_frames(model, qpos, width=width, height=height, overlay=False))
    lines = ["t 3.24 s   labelled gesture: wave",
             "perceived (predicted): wave 0.82  clap 0.07  other 0.05",
             "window open 45%   curtain open 0%   hifi loud 80%   cigarette lit 0%   door "
             "closed 0%   (a line longer than the frame is wide at the base size)"]
    before = frame.copy()
    out = caption_frame(frame, lines)
    assert out.shape == frame.shape and out.dtype == np.uint8
    assert np.array_equal(frame, before)  # the input is not drawn on
    step = round(height * CAPTION_LINE_FRACTION)  # px a line
    top = height - len(lines) * step - 4
    assert np.array_equal(out[:top], frame[:top])
    band, scene = out[top:].astype(int), frame[top:].astype(int)
    text = band.min(axis=2) > 200  # white: brighter than any darkened scene pixel
    assert text.sum() > 20 * len(lines)
    darkened = band == (scene * (1 - CAPTION_BAND_ALPHA)).astype(int)
    assert darkened.all(axis=2).mean() > 0.8  # elsewhere the scene, darkened
    for i in range(len(lines)):  # each line in its own slot of the band
        assert text[2 + i * step:2 + (i + 1) * step].any(), i
    assert np.flatnonzero(text.any(axis=0)).max() < width - 1  # the long line fits
    assert np.array_equal(caption_frame(frame, []), frame)
    with pytest.raises(SimenvError, match=r"expected uint8 \(H, W, 3\)"):
        caption_frame(frame[..., 0], lines)


def test_bad_input_is_a_simenv_error(walk, tmp_path: Path):
    model, qpos, keypoints, edges, fps = walk
    with pytest.raises(SimenvError, match=r"expected \(T>=1, 7\)"):
        next(render_frames(model, qpos[:, :5]))
    broken = qpos.copy()
    broken[17, 2] = np.nan
    with pytest.raises(SimenvError, match="frame 17"):
        next(render_frames(model, broken))
    with pytest.raises(SimenvError, match="ghost 0"):
        next(render_frames(model, qpos, ghost=keypoints[:-1]))
    with pytest.raises(SimenvError, match="ghost edge"):
        next(render_frames(model, qpos, ghost=keypoints, ghost_edges=[(0, 99)]))
    with pytest.raises(SimenvError, match="no body 'nobody'"):
        next(render_frames(model, qpos, follow_body="nobody"))
    with pytest.raises(SimenvError, match="no frames"):
        write_video(iter(()), tmp_path / "empty.mp4", fps=30)
    frames = [np.zeros((40, 40, 3), np.uint8), np.zeros((40, 48, 3), np.uint8)]
    with pytest.raises(SimenvError, match="frame 1 is 48x40"):
        write_video(frames, tmp_path / "sizes.mp4", fps=30)
    with pytest.raises(SimenvError, match="positive"):
        write_video(frames, tmp_path / "fps.mp4", fps=0)


def test_missing_opengl_is_a_clear_error(tmp_path: Path):
    """With a backend that cannot work here (GLFW without a display) the error says what to do."""
    code = (
        "import simenv, mujoco\n"
        "from simenv.body.render import make_renderer\n"
        "model = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom size=\".1\"/>"
        "</worldbody></mujoco>')\n"
        "try:\n"
        "    make_renderer(model, 64, 64)\n"
        "except simenv.SimenvError as err:\n"
        "    print('SIMENV_ERROR', err)\n"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["MUJOCO_GL"] = "glfw"
    run = subprocess.run(
        [sys.executable, "-c", code], env=env, cwd=tmp_path, capture_output=True, text=True
    )
    assert "SIMENV_ERROR" in run.stdout, run.stderr
    assert "libosmesa6" in run.stdout and "MUJOCO_GL" in run.stdout


def test_import_simenv_picks_a_headless_backend(tmp_path: Path):
    """Without MUJOCO_GL and DISPLAY, `import simenv` chooses a backend whose library exists."""
    code = (
        "import ctypes.util, os, simenv, mujoco\n"
        "from simenv.body.render import make_renderer\n"
        "backend = os.environ.get('MUJOCO_GL')\n"
        "lib = {'osmesa': 'OSMesa', 'egl': 'EGL'}[backend]\n"
        "assert ctypes.util.find_library(lib), lib\n"
        "model = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom size=\".1\"/>"
        "</worldbody></mujoco>')\n"
        "make_renderer(model, 32, 32).close()\n"
        "print(backend)\n"
    )
    env = {k: v for k, v in os.environ.items()
           if k not in ("DISPLAY", "WAYLAND_DISPLAY", "MUJOCO_GL", "PYOPENGL_PLATFORM")}
    run = subprocess.run(
        [sys.executable, "-c", code], env=env, cwd=tmp_path, capture_output=True, text=True
    )
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() in ("osmesa", "egl")
    env["DISPLAY"] = ":99"
    run = subprocess.run(
        [sys.executable, "-c", "import os, simenv; print(os.environ.get('MUJOCO_GL'))"],
        env=env, cwd=tmp_path, capture_output=True, text=True,
    )
    assert run.stdout.strip() == "None"  # with a display MuJoCo's own default is kept


def test_choosing_the_encoders_prints_nothing(tmp_path: Path):
    """Rendering a real clip to MP4 + WebM writes nothing to the process's stderr (file
    descriptor 2, where FFmpeg and OpenCV print while OpenCV tries encoders), and the
    files play back with every frame."""
    code = (
        "import simenv\n"
        "from simenv.assets import WALK, asset_path\n"
        "from simenv.body.render import render_result\n"
        "from simenv.body.retarget import retarget\n"
        "clip = simenv.load(asset_path(WALK)).slice(0, 60)\n"
        "render_result(retarget(clip), 'walk.mp4', stride=20, width=160, height=120, web=True)\n"
    )
    run = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                         text=True, env={**os.environ, "MUJOCO_GL": "osmesa"})
    assert run.returncode == 0, run.stderr
    for noise in ("h264_v4l2m2m", "Could not find a valid device", "can't configure encoder",
                  "is not supported", "FFMPEG", "[ERROR"):
        assert noise not in run.stderr, run.stderr
    assert run.stderr.strip() == ""
    for name in ("walk.mp4", "walk.webm"):
        if name == "walk.webm" and not (tmp_path / name).exists():
            continue  # an H.264 MP4 needs no WebM copy
        cap = cv2.VideoCapture(str(tmp_path / name))
        try:
            frames = []
            while (frame := cap.read()[1]) is not None:
                frames.append(frame)
        finally:
            cap.release()
        assert len(frames) == 3 and frames[0].shape == (120, 160, 3), name
        assert frames[0].std() > 5, name
