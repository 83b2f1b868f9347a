"""``cosim camera calibrate``: a camera's calibration from checkerboard images, into a calibration file."""

from __future__ import annotations

from pathlib import Path

from cosim_plugins.camera.calibration import VIEWS


def add_commands(sub) -> None:
    """Add ``cosim camera`` and its subcommands to the ``cosim`` parser's ``sub``."""
    camera = sub.add_parser("camera", help="the lab's cameras: calibration")
    camera_sub = camera.add_subparsers(dest="camera_command", metavar="SUBCOMMAND")
    camera_sub.required = True
    p = camera_sub.add_parser(
        "calibrate", help="calibrate one camera from checkerboard images into a calibration file",
        description="Intrinsics and distortion from IMAGES of the board at varied poses (10-20, tilted, "
                    "over the whole view), the camera's pose in the tank from --pose, an image of the board "
                    "at the pose --target gives. Run once per camera into the same --out file.")
    p.add_argument("images", nargs="+", type=Path, metavar="IMAGES", help="images of the board")
    p.add_argument("--camera", required=True, choices=VIEWS, help="which camera the images are from")
    p.add_argument("--target", required=True, type=Path, metavar="TARGET.yaml",
                   help="the board and its pose in the tank (see cosim_plugins.camera.board)")
    p.add_argument("--pose", required=True, type=Path, metavar="IMAGE",
                   help="an image of the board at the target's pose in the tank")
    p.add_argument("--out", required=True, type=Path, metavar="CAL.yaml",
                   help="calibration file; this camera is written into it, the other kept")
    p.set_defaults(func=cmd_calibrate)


def cmd_calibrate(args) -> int:
    """``cosim camera calibrate``: one camera's calibration from checkerboard images, into a file."""
    from cosim_plugins.camera.board import load_target
    from cosim_plugins.camera.calibrate import calibrate
    from cosim_plugins.camera.calibration import update_calibration

    report = calibrate(args.images, load_target(args.target), args.pose)
    cam = report.camera
    print(f"camera {args.camera}: board found in {len(report.used)} of {len(report.used) + len(report.skipped)} "
          f"images" + (f" (not in: {', '.join(map(str, report.skipped))})" if report.skipped else ""))
    k = cam.K
    print(f"intrinsics: fx {k[0, 0]:.1f}, fy {k[1, 1]:.1f}, cx {k[0, 2]:.1f}, cy {k[1, 2]:.1f} px; distortion "
          + ", ".join(f"{v:.3g}" for v in cam.dist) + f"; RMS reprojection {cam.rms_px:.3f} px")
    look = cam.R[2]  # the optical axis in the tank frame
    print(f"pose: camera at ({', '.join(f'{v * 1e3:.1f}' for v in cam.centre_m)}) mm in the tank frame, looking "
          f"along ({', '.join(f'{v:.3f}' for v in look)}); target reprojection RMS {report.pose_rms_px:.3f} px")
    cal = update_calibration(args.out, args.camera, cam)
    print(f"wrote {args.out} (cameras: {', '.join(cal.cameras)})")
    missing = [v for v in VIEWS if v not in cal.cameras]
    if missing:
        print(f"next: calibrate the {' and '.join(missing)} camera into the same file")
    return 0
