"""scenarios/camera_frames.yaml end to end: rendered frames through detection and triangulation close
the PI loop as well as the camera emulator does, the recording shows the cameras, and a run's recorded
frames replay it exactly through the video source."""

from __future__ import annotations

import json
from pathlib import Path

from recording_checks import recorded_entities

from cosim.cli import main
from cosim_plugins.resources import SCENARIOS_DIR, package_path

REPO = Path(__file__).parents[2]
SCENARIO = SCENARIOS_DIR / "camera_frames.yaml"
CALIBRATION = package_path("camera", "acA800_pair.yaml")
EMULATOR = ["--set", "components.camera.plugin=camera.emulator", "--set", "components.camera.params={}",
            "--set", "components.camera.inputs={position: plant.position}"]


def run(out: Path, *args: str) -> dict:
    assert main(["run", str(SCENARIO), "--out", str(out), "--quiet",
                 "--set", f"components.camera.params.calibration={CALIBRATION}", *args]) == 0
    return json.loads((out / "summary.json").read_text())


def run_emulated(out: Path, *args: str) -> dict:
    assert main(["run", str(SCENARIO), "--out", str(out), "--quiet", *EMULATOR, *args]) == 0
    return json.loads((out / "summary.json").read_text())


def test_rendered_frames_close_the_loop_as_well_as_the_emulator(tmp_path):
    short = ("--set", "duration_s=10")
    frames = run(tmp_path / "frames", *short)
    emulated = run_emulated(tmp_path / "emulator", *short)
    assert frames["status"] == "ok"
    assert frames["detection_error_mm"]["median"] <= 0.1 and frames["detection_error_mm"]["p99"] <= 0.5
    counts = frames["detections"]
    assert counts["frames"] == frames["steps"] == 500 and counts["lost"] + counts["rejected"] <= 10, counts
    ours, theirs = frames["tracking_error_mm"]["mean"], emulated["tracking_error_mm"]["mean"]
    assert abs(ours - theirs) <= 0.2 * theirs, (ours, theirs)
    # the camera's part of the recording was folded into recording.rrd: its images are there
    assert not list((tmp_path / "frames").glob("recording.*.rrd"))
    entities = recorded_entities(tmp_path / "frames" / "recording.rrd")
    assert {"/camera/top/image", "/camera/side/image", "/camera/top/blobs", "/camera/side/found",
            "/world/measured"} <= entities, entities


def test_frames_a_node_recorded_replay_the_run_exactly(tmp_path):
    short = ("--set", "duration_s=3")
    first = tmp_path / "rendered"  # the camera in a node process of its own, writing into the run folder
    run(first, *short, "--set", "components.camera.params.record_frames=true", "--processes")
    videos = [first / f"frames_camera_{view}.mkv" for view in ("top", "side")]
    assert all(v.stat().st_size > 0 for v in videos) and (first / "calibration_camera.yaml").is_file()
    replay = {"calibration": str(first / "calibration_camera.yaml"), "source": "video",
              "top": str(videos[0]), "side": str(videos[1])}
    again = tmp_path / "replayed"
    assert main(["run", str(SCENARIO), "--out", str(again), "--quiet", *short,
                 "--set", "components.camera.plugin=camera.frames", "--set", "components.camera.inputs={}",
                 "--set", "components.camera.params=" + json.dumps(replay)]) == 0
    assert (again / "log.csv").read_bytes() == (first / "log.csv").read_bytes()
    summaries = [json.loads((d / "summary.json").read_text()) for d in (first, again)]
    assert summaries[0]["detections"] == summaries[1]["detections"]
