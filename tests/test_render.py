"""``hexhil render``: a 5 s hexapod trace to a GIF whose frames differ, an MP4, and a PNG;
one line saying what to install when no OpenGL library is there."""
from __future__ import annotations

import ctypes.util
import functools
from pathlib import Path

import numpy as np
import pytest

from hexhil import render as render_mod
from hexhil.protocol.errors import UserError
from conftest import hexhil, hexhil_in_process

GL = ctypes.util.find_library("EGL") or ctypes.util.find_library("OSMesa")


def needs_gl(test):
    """A test that renders: without libEGL or libOSMesa it fails saying so (``make test``
    installs libegl1), never skips."""
    def run(*args, **kw):
        assert GL, "no libEGL or libOSMesa for offscreen rendering: apt-get install libegl1"
        return test(*args, **kw)
    return functools.wraps(test)(run)


@pytest.fixture(scope="module")
def trace(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("render") / "run.mcap"
    r = hexhil_in_process("run", "scenarios/obstacles-high-large.toml", "--duration", "5",
                          "--out", str(out))
    assert r.returncode == 0, r.stderr
    return out


@needs_gl
def test_gif_frames_differ(trace, tmp_path):
    from PIL import Image, ImageSequence

    gif = tmp_path / "run.gif"
    r = hexhil("render", str(trace), "--out", str(gif), "--fps", "4", "--width", "160",
               "--height", "120", "--camera", "side")
    assert r.returncode == 0, r.stderr
    frames = [np.asarray(f.convert("RGB"), dtype=float)
              for f in ImageSequence.Iterator(Image.open(gif))]
    assert len(frames) == 20  # 4 fps over the samples' 4.9 s span, both ends included
    assert frames[0].std() > 10  # not a blank image
    moved = [np.abs(a - b).mean() for a, b in zip(frames, frames[1:])]
    assert min(moved) > 0 and sum(m > 0.5 for m in moved) > len(moved) // 2


@needs_gl
def test_mp4_and_png(trace, tmp_path):
    import imageio_ffmpeg

    mp4, png = tmp_path / "run.mp4", tmp_path / "frame.png"
    r = hexhil("render", str(trace), "--out", str(mp4), "--fps", "5", "--width", "160",
               "--height", "120")
    assert r.returncode == 0, r.stderr
    n_frames, _secs = imageio_ffmpeg.count_frames_and_secs(str(mp4))
    assert n_frames == 25
    r = hexhil("render", str(trace), "--out", str(png), "--at", "2.5")
    assert r.returncode == 0, r.stderr
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("args, needle", [
    (["--out", "x.avi"], "must end in .gif, .mp4 or .png"),
    (["--out", "x.gif", "--fps", "0"], "--fps 0: a video has more than 0"),
    (["--out", "x.png", "--at", "999"], "--at 999.0: "),      # the trace is 5 s long
])
def test_bad_arguments_are_one_line(trace, args, needle):
    r = hexhil("render", str(trace), *args)
    assert r.returncode == 2 and needle in r.stderr and len(r.stderr.splitlines()) == 1


def test_missing_gl_library_says_what_to_install(monkeypatch):
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.setattr(render_mod.ctypes.util, "find_library", lambda name: None)
    with pytest.raises(UserError, match="install libegl1"):
        render_mod.choose_gl()
