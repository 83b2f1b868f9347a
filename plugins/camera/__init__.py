"""Camera plugins: the two-camera emulator."""

from cosim import hookimpl
from cosim_plugins.camera.emulator import CameraEmulator


@hookimpl
def cosim_register_components(register):
    register("camera.emulator", CameraEmulator)
