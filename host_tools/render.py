"""A recorded hexapod run replayed into MuJoCo's offscreen renderer: a GIF, an MP4 or one
PNG frame (``hexhil render``).

The trace's ground truth (``/body`` pose and ``/joints`` angles, 10 Hz) is interpolated to
the video's frame rate and set on the world the trace's scenario and seed build (so the
obstacles are the ones the robot met); nothing is simulated. GIFs and PNGs are written
with Pillow (matplotlib's dependency), MP4 with the ffmpeg that imageio-ffmpeg ships.
The OpenGL backend is chosen before MuJoCo is imported (``choose_gl``).
"""
from __future__ import annotations

import ctypes.util
import os
from pathlib import Path
from typing import Any, Iterator

from hexhil.output import check_output, write_failed
from hexhil.progress import Progress, report
from hexhil.protocol.errors import BadFile, BadValue

GL_LIBRARIES = {"egl": ("EGL", "libegl1"), "osmesa": ("OSMesa", "libosmesa6")}
CAMERAS = ("follow", "side")
MAX_FPS = 100          # a GIF's frame delay is in hundredths of a second
MAX_SIDE = 4096        # pixels
MAX_GIF_FRAMES = 3000  # frames a GIF holds in memory before it is written (100 s at 30 fps)
FLOOR_XML = """<asset>
    <texture name="grid" type="2d" builtin="checker" rgb1="0.82 0.84 0.86" rgb2="0.72 0.74 0.76"
             width="512" height="512"/>
    <material name="grid" texture="grid" texrepeat="40 40"/>
    <texture type="skybox" builtin="gradient" rgb1="0.62 0.76 0.9" rgb2="0.95 0.97 1"
             width="256" height="256"/>
  </asset>
  <visual><headlight ambient="0.45 0.45 0.45" diffuse="0.5 0.5 0.5"/></visual>
  <worldbody>
    <light pos="0 0 3" dir="0 0 -1" directional="true"/>"""


def choose_gl() -> str:
    """Set ``MUJOCO_GL`` for headless rendering (EGL, else OSMesa) unless the user chose;
    one line saying what to install when neither library is there."""
    chosen = os.environ.get("MUJOCO_GL")
    if chosen:
        return chosen
    for backend, (lib, _pkg) in GL_LIBRARIES.items():
        if ctypes.util.find_library(lib):
            os.environ["MUJOCO_GL"] = backend
            return backend
    raise BadFile("hexhil render needs an OpenGL library for offscreen rendering: install "
                  "libegl1 (or libosmesa6), e.g. 'apt-get install libegl1'")


def _ground_truth(path: str) -> tuple[dict[str, str], list[tuple[float, list[float]]]]:
    """(metadata, [(t_s, qpos)]) from a trace's /body and /joints, joined by time."""
    from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
    from foxglove_schemas_protobuf.JointStates_pb2 import JointStates

    from hexhil.trace.reader import open_trace
    from hexhil.trace.topics import T_BODY, T_JOINTS

    bodies: dict[int, list[float]] = {}
    joints: dict[int, list[float]] = {}
    with open_trace(path) as tr:
        if not {T_BODY, T_JOINTS} <= set(tr.topics()):
            raise BadValue(f"{path}: no hexapod ground truth ({T_BODY}, {T_JOINTS}) to render")
        meta = tr.metadata()
        for m in tr.messages([T_BODY, T_JOINTS]):
            if m.topic == T_BODY:
                b = FrameTransform.FromString(m.data)
                r = b.rotation
                bodies[m.log_time_ns] = [b.translation.x, b.translation.y, b.translation.z,
                                         r.w, r.x, r.y, r.z]
            else:
                joints[m.log_time_ns] = [j.position for j in JointStates.FromString(m.data).joints]
    samples = [(t * 1e-9, bodies[t] + joints[t]) for t in sorted(bodies) if t in joints]
    if len(samples) < 2:
        raise BadValue(f"{path}: fewer than two ground-truth samples to render")
    return meta, samples


def _world(meta: dict[str, str], path: str) -> Any:
    """The run's world (its obstacles) from the trace's scenario and seed."""
    from hexhil.hil.run.rig import make_world
    from hexhil.trace.run_metadata import scenario_of_trace

    return make_world(*scenario_of_trace(meta, path))


def _frames_at(samples: list[tuple[float, list[float]]], fps: float,
               at_s: float | None) -> Iterator[list[float]]:
    """qpos at each frame time, interpolated linearly between samples (the quaternion
    renormalised), or only at ``at_s``."""
    t0, t_end = samples[0][0], samples[-1][0]
    times = [at_s] if at_s is not None else \
        [t0 + i / fps for i in range(int((t_end - t0) * fps) + 1)]
    k = 0
    for t in times:
        t = min(max(t, t0), t_end)
        while k + 2 < len(samples) and samples[k + 1][0] <= t:
            k += 1
        (ta, a), (tb, b) = samples[k], samples[k + 1]
        w = 0.0 if tb == ta else min(max((t - ta) / (tb - ta), 0.0), 1.0)
        q = [x + w * (y - x) for x, y in zip(a, b)]
        n = sum(v * v for v in q[3:7]) ** 0.5
        q[3:7] = [v / n for v in q[3:7]]
        yield q


def render(trace: str, out: str, camera: str = "follow", fps: float = 30.0,
           width: int = 480, height: int = 360, at_s: float | None = None,
           progress: Progress | None = None, overwrite: bool = False) -> int:
    """Write ``out`` (.gif, .mp4, or .png: the frame at ``at_s``, default the middle);
    returns the number of frames. Each frame drawn is reported to ``progress``. An
    existing ``out`` is refused unless ``overwrite``, as a trace is."""
    suffix = Path(out).suffix.lower()
    if suffix not in (".gif", ".mp4", ".png"):
        raise BadValue(f"out {out}: the video's name must end in .gif, .mp4 or .png",
                       params=("out",))
    check_output(out, "out", overwrite)
    if not 0 < fps <= MAX_FPS:
        raise BadValue(f"fps {fps:g}: a video has more than 0 and at most {MAX_FPS} frames a "
                       "second (the ground truth is sampled at 10 Hz)", params=("fps",))
    if not (16 <= width <= MAX_SIDE and 16 <= height <= MAX_SIDE):
        raise BadValue(f"size {width} x {height}: each side is 16-{MAX_SIDE} pixels",
                       params=("width", "height"))
    meta, samples = _ground_truth(trace)
    t0_s, t_end_s = samples[0][0], samples[-1][0]
    if at_s is not None and not t0_s <= at_s <= t_end_s:
        raise BadValue(f"at_s {at_s}: {trace} has ground truth from {t0_s:.3f} s to "
                       f"{t_end_s:.3f} s only", params=("at_s",))
    if suffix == ".png" and at_s is None:
        at_s = (samples[0][0] + samples[-1][0]) / 2
    n = 1 if at_s is not None else int((t_end_s - t0_s) * fps) + 1
    if suffix == ".gif" and n > MAX_GIF_FRAMES:
        raise BadValue(f"fps {fps:g}: {n:,} frames, and a GIF is held whole until it is "
                       f"written (at most {MAX_GIF_FRAMES:,}); lower fps, or write an .mp4",
                       params=("fps",))
    world = _world(meta, trace)
    import mujoco

    from hexhil.hil.world.scene import ROBOT_RGBA

    model = mujoco.MjModel.from_xml_string(world.xml.replace("<worldbody>", FLOOR_XML, 1)
                                           .replace('name="ground" type="plane"',
                                                    'name="ground" type="plane" material="grid"'))
    model.geom_rgba[model.geom_bodyid > 0] = ROBOT_RGBA  # the robot as the 3D scene draws it
    model.vis.global_.offwidth, model.vis.global_.offheight = max(width, 640), max(height, 480)
    data = mujoco.MjData(model)
    try:
        renderer = mujoco.Renderer(model, height, width)
    except Exception as exc:  # the GL backend's own error types
        backend = os.environ.get("MUJOCO_GL")
        raise BadFile(f"hexhil render: MuJoCo could not open an offscreen {backend} context "
                      f"({exc}); install libegl1 or libosmesa6, or set MUJOCO_GL") from None
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.distance, cam.elevation, cam.azimuth = (0.8, -28.0, 35.0) if camera == "follow" \
        else (0.75, -18.0, -90.0)
    desc = f"render {Path(out).name}"
    report(progress, desc, 0, n)

    def images() -> Iterator[Any]:
        for i, q in enumerate(_frames_at(samples, fps, at_s)):
            data.qpos[:25] = q
            mujoco.mj_kinematics(model, data)
            cam.lookat[:] = (q[0], q[1], 0.06) if camera == "follow" else (q[0], 0.0, 0.08)
            renderer.update_scene(data, camera=cam)
            yield renderer.render().copy()
            report(progress, desc, i + 1, n)

    try:
        return _write(out, suffix, images(), fps, (width, height))
    except OSError as exc:   # a full disk, /dev/full, ffmpeg gone
        raise write_failed(out, "out", exc) from None
    finally:
        renderer.close()


def _write(out: str, suffix: str, images: Iterator[Any], fps: float,
           size: tuple[int, int]) -> int:
    """The frames into ``out`` as they are drawn (an MP4 holds none in memory); their number."""
    if suffix == ".mp4":
        import imageio_ffmpeg

        writer = imageio_ffmpeg.write_frames(out, size, fps=fps, macro_block_size=8,
                                             ffmpeg_log_level="error")
        writer.send(None)
        count = 0
        try:
            for im in images:
                writer.send(im)
                count += 1
        finally:
            writer.close()
        return count
    from PIL import Image

    frames = [Image.fromarray(im) for im in images]
    if suffix == ".png":
        frames[0].save(out)
    else:
        frames[0].save(out, save_all=True, append_images=frames[1:], loop=0,
                       duration=round(1000 / fps))
    return len(frames)
