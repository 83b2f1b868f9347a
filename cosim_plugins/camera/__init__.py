"""Camera plugins: the two-camera emulator, the frame cameras (hardware, recorded, rendered), ``cosim camera``."""

from cosim import hookimpl
from cosim_plugins.camera.emulator import CameraEmulator
from cosim_plugins.camera.frames import FrameCamera, RenderedCamera


@hookimpl
def cosim_register_components(register):
    register("camera.emulator", CameraEmulator)
    register("camera.frames", FrameCamera)
    register("camera.rendered", RenderedCamera)


@hookimpl
def cosim_register_commands(register):
    from cosim_plugins.camera.cli import add_commands

    register(add_commands)
