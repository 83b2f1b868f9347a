"""`cosim camera calibrate` on checkerboard images the renderer's cameras see: it recovers them."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from cosim.cli import main
from cosim_plugins.camera.board import load_target, render_board
from cosim_plugins.camera.calibration import load_calibration
from cosim_plugins.camera.sources.render import acA800_pair
from cosim_plugins.resources import package_path

REPO = Path(__file__).parents[2]
# an 11 x 8 board of 10 mm squares, its printed face towards each camera: flat on the tank's floor
# plane for the top camera, upright in the y = 0 plane for the side camera
TARGETS = {
    "top": {"inner_corners": [11, 8], "square_mm": 10, "origin_mm": [-50, -35, 0],
            "x_axis": [1, 0, 0], "y_axis": [0, 1, 0], "origin_square": "dark"},
    "side": {"inner_corners": [11, 8], "square_mm": 10, "origin_mm": [-50, 0, -35],
             "x_axis": [1, 0, 0], "y_axis": [0, 0, 1], "origin_square": "dark"},
}


def board_views(camera, target, rng, n: int) -> list[np.ndarray]:
    """``n`` images of the board tilted up to ~30 degrees, at 420-560 mm, over the camera's view."""
    facing = np.diag([1.0, -1.0, -1.0])  # board x to the right, its face towards the camera
    middle = np.array([target.cols - 1, target.rows - 1, 0]) * target.square_m / 2
    images = []
    for _ in range(n):
        tilt = cv2.Rodrigues(np.array([*rng.uniform(-0.5, 0.5, 2), 0.0]))[0]
        R = tilt @ cv2.Rodrigues(np.array([0.0, 0.0, rng.uniform(-0.3, 0.3)]))[0] @ facing
        centre = np.array([*rng.uniform(-0.03, 0.03, 2), rng.uniform(0.42, 0.56)])
        images.append(render_board(camera, target, R, centre - R @ middle, rng))
    return images


def write_views(folder: Path, view: str, cameras, rng) -> tuple[list[Path], Path, Path]:
    target_file = folder / f"{view}_target.yaml"
    target_file.write_text(yaml.safe_dump(TARGETS[view]))
    target = load_target(target_file)
    files = []
    for k, image in enumerate(board_views(cameras[view], target, rng, 10)):
        files.append(folder / f"{view}_{k:02d}.png")
        cv2.imwrite(str(files[-1]), image)
    pose = folder / f"{view}_pose.png"
    cv2.imwrite(str(pose), render_board(cameras[view], target, *target.pose_in(cameras[view]), rng))
    return files, pose, target_file


def test_calibration_recovers_the_renderers_cameras(tmp_path, capsys):
    cameras = acA800_pair()
    out = tmp_path / "cal.yaml"
    rng = np.random.default_rng(7)
    for view in ("top", "side"):
        files, pose, target = write_views(tmp_path, view, cameras, rng)
        args = ["camera", "calibrate", *map(str, files), "--camera", view, "--target", str(target),
                "--pose", str(pose), "--out", str(out)]
        assert main(args) == 0
    printed = capsys.readouterr().out
    assert "board found in 11 of 11 images" in printed and "wrote" in printed
    found = load_calibration(out)
    assert list(found.cameras) == ["top", "side"]  # the second run kept the first camera
    grid = np.stack(np.meshgrid(*[np.linspace(-0.06, 0.06, 5)] * 3), axis=-1).reshape(-1, 3)  # the tank
    for view in ("top", "side"):
        error_px = np.linalg.norm(found[view].project(grid) - cameras[view].project(grid), axis=1)
        assert error_px.max() < 0.5, (view, error_px.max())
        assert np.linalg.norm(found[view].centre_m - cameras[view].centre_m) < 0.005


def test_the_scenarios_calibration_file_is_the_renderers_pair(cameras):
    named = load_calibration(package_path("camera", "acA800_pair.yaml"))
    grid = np.random.default_rng(0).uniform(-0.075, 0.075, (50, 3))
    for view in ("top", "side"):
        assert named[view].size == cameras[view].size
        assert np.abs(named[view].project(grid) - cameras[view].project(grid)).max() < 1e-9


def test_a_pose_image_without_the_board_is_one_line_naming_it(tmp_path, capsys, cameras):
    files, _, target = write_views(tmp_path, "top", cameras, np.random.default_rng(1))
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((600, 800), 120, np.uint8))
    code = main(["camera", "calibrate", *map(str, files), "--camera", "top", "--target", str(target),
                 "--pose", str(blank), "--out", str(tmp_path / "cal.yaml")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1
    assert f"pose image {blank}: no 11x8 checkerboard found" in err


@pytest.mark.parametrize("field, value, message", [
    ("inner_corners", [10, 8], "give one even and one odd count"),
    ("y_axis", [1, 1, 0], "not perpendicular"),
])
def test_a_bad_target_file_is_one_line_naming_it(tmp_path, capsys, field, value, message):
    target = tmp_path / "target.yaml"
    target.write_text(yaml.safe_dump({**TARGETS["top"], field: value}))
    image = tmp_path / "a.png"
    cv2.imwrite(str(image), np.full((600, 800), 120, np.uint8))
    code = main(["camera", "calibrate", str(image), "--camera", "top", "--target", str(target),
                 "--pose", str(image), "--out", str(tmp_path / "cal.yaml")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and str(target) in err and message in err
