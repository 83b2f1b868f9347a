"""Frame sources: recorded videos replay exactly; a missing camera, a calibration for another frame
size and a corrupted video each stop with one line naming the device or file; Basler cameras on
pylon's camera emulator."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import cv2
import numpy as np
import pytest

from cosim_plugins.camera.frame_video import FrameVideos
from cosim_plugins.camera.sources.render import Look, Renderer
from cosim_plugins.camera.sources.video import VideoSource
from cosim_plugins.resources import SCENARIOS_DIR, package_path

REPO = Path(__file__).parents[2]
SCENARIO = SCENARIOS_DIR / "camera_frames.yaml"
CALIBRATION = package_path("camera", "acA800_pair.yaml")


def rendered_pairs(cameras, n: int) -> list:
    renderer = Renderer(cameras, Look(drop_prob=0.1), np.random.default_rng(2))
    truth = {"position": np.array([0.01, -0.02, 0.03]), "axis": np.array([0.0, 1.0, 0.0])}
    return [renderer.grab(0.02 * k, truth).images for k in range(n)]


def test_recorded_frames_replay_bit_for_bit(tmp_path, cameras):
    pairs = rendered_pairs(cameras, 12)
    videos = FrameVideos(tmp_path, "camera", [c.size for c in cameras.cameras.values()], fps=50.0)
    for images in pairs:
        videos.write(images)
    videos.close()
    source = VideoSource(tuple(str(p) for p in videos.paths))
    assert source.sizes == ((800, 600), (800, 600))
    for images in pairs:
        replayed = source.grab(0.0, {}).images
        for original, copy in zip(images, replayed):
            assert np.array_equal(copy, np.zeros((600, 800), np.uint8) if original is None else original)
    with pytest.raises(Exception, match=r"video file .*frames_camera_top.mkv \(top\): ended after 12 frames"):
        source.grab(0.0, {})
    source.close()


def run_frames_camera(tmp_path, **params) -> tuple[int, str]:
    """`cosim run` of the racetrack scenario with camera.frames reading ``params``; (exit code, stderr)."""
    overrides = ["components.camera.plugin=camera.frames", "components.camera.inputs={}",
                 "components.camera.params=" + json.dumps({"calibration": str(CALIBRATION), **params}),
                 "duration_s=0.1"]
    proc = subprocess.run([sys.executable, "-m", "cosim.cli", "run", str(SCENARIO), "--quiet", "--out",
                           str(tmp_path / "run"), *[a for o in overrides for a in ("--set", o)]],
                          capture_output=True, text=True, timeout=120)
    return proc.returncode, proc.stderr.strip()


def test_a_missing_camera_is_one_line_naming_it(tmp_path):
    code, err = run_frames_camera(tmp_path, source="video", top="97", side="98")
    assert code == 2 and len(err.splitlines()) == 1, err
    assert "camera top (video device 97): not found or busy" in err


def test_a_calibration_for_another_frame_size_is_one_line_naming_both(tmp_path):
    for view in ("top", "side"):
        (tmp_path / view).mkdir()
        cv2.imwrite(str(tmp_path / view / "0000.png"), np.full((480, 640), 200, np.uint8))
    code, err = run_frames_camera(tmp_path, source="folder", top=str(tmp_path / "top"), side=str(tmp_path / "side"))
    assert code == 2 and len(err.splitlines()) == 1, err
    assert (f"calibration {CALIBRATION}: camera top is calibrated for 800x600 px but image folder "
            f"{tmp_path / 'top'} gives 640x480 px") in err


def test_a_corrupted_video_is_one_line_naming_it(tmp_path, cameras):
    videos = FrameVideos(tmp_path, "camera", [(800, 600), (800, 600)], fps=50.0)
    for images in rendered_pairs(cameras, 3):
        videos.write(images)
    videos.close()
    top = videos.paths[0]
    top.write_bytes(np.random.default_rng(0).integers(0, 256, top.stat().st_size, dtype=np.uint8).tobytes())
    code, err = run_frames_camera(tmp_path, source="video", top=str(top), side=str(videos.paths[1]))
    assert code == 2 and len(err.splitlines()) == 1, err
    assert f"video file {top} (top): cannot be opened (corrupted or not a video)" in err


BASLER = textwrap.dedent("""
    import json, sys
    import numpy as np
    from pypylon import pylon
    if len(pylon.TlFactory.GetInstance().EnumerateDevices()) < 2:
        print(json.dumps({"skip": "pylon's camera emulator offers no cameras here (PYLON_CAMEMU=2 set)"}))
        sys.exit(0)
    from cosim_plugins.camera.detect import BlobParams
    from cosim_plugins.camera.locate import PairLocator, PairParams
    from cosim_plugins.camera.sources.basler import BaslerSource
    from cosim_plugins.camera.sources.base import FrameSourceError
    from cosim_plugins.camera.sources.render import acA800_pair
    folders = json.loads(sys.argv[1])
    features = {view: {"Width": 800, "Height": 600, "TestImageSelector": "Off", "ImageFileMode": "On",
                       "ImageFilename": folders[view]} for view in ("top", "side")}
    out = {}
    try:
        BaslerSource(("0815-0000", "0815-0404"), features)
    except FrameSourceError as exc:
        out["missing"] = str(exc)
    source = BaslerSource(("0815-0000", "0815-0001"), features, trigger="Software", timeout_s=2.0)
    pair = source.grab(0.0, {})
    out["sizes"] = source.sizes
    out["devices"] = source.devices
    fix = PairLocator(acA800_pair(), BlobParams(), PairParams()).locate(pair.capture_time_s, pair.images)
    out["position_m"] = fix.position_m.tolist()
    source.close()
    print(json.dumps(out))
""")


def test_basler_cameras_on_pylons_emulator(tmp_path, cameras):
    pytest.importorskip("pypylon", reason="pypylon is not installed (pip install '.[lab]')")
    truth = np.array([0.02, 0.01, -0.015])
    images = Renderer(cameras, Look(), np.random.default_rng(3)).grab(0.0, {"position": truth,
                                                                            "axis": np.array([1.0, 0, 0])}).images
    folders = {}
    for view, image in zip(("top", "side"), images):
        folders[view] = str(tmp_path / view)
        (tmp_path / view).mkdir()
        cv2.imwrite(str(tmp_path / view / "frame.png"), image)
    env = {**os.environ, "PYLON_CAMEMU": "2"}
    proc = subprocess.run([sys.executable, "-c", BASLER, json.dumps(folders)], capture_output=True, text=True,
                          env=env, timeout=120)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    if "skip" in out:
        pytest.skip(out["skip"])
    assert out["missing"] == ("Basler camera side (serial 0815-0404): not connected; connected: "
                              "0815-0000 (Emulation), 0815-0001 (Emulation)")
    assert out["sizes"] == [[800, 600], [800, 600]]
    assert out["devices"] == ["Basler camera top (Emulation 0815-0000)", "Basler camera side (Emulation 0815-0001)"]
    assert np.linalg.norm(np.array(out["position_m"]) - truth) < 5e-5
