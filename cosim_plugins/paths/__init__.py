"""Built-in reference paths (the paper's training and validation paths, plus helices).

All lengths are given in mm in scenario parameters (as the paper states
them) and returned in m. Sizes follow the paper: racetrack with 30 mm
straights and 40 mm radius curves; circles of radius 35 mm rotated about y
by a given angle; a circle whose plane rotates continuously about y.
"""

from cosim import hookimpl
from cosim_plugins.paths.shapes import Circle, Helix, HelixRacetrack, Racetrack, RotatingCircle


@hookimpl
def cosim_register_paths(register):
    register("racetrack", Racetrack)
    register("circle", Circle)
    register("rotating_circle", RotatingCircle)
    register("helix", Helix)
    register("helix_racetrack", HelixRacetrack)
