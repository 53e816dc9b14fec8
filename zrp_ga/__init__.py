"""zrp_ga: genetic-algorithm calibration of serial robot kinematics on the Zero Reference
Position model. Modules: so3, robot, robots, robot_files (with dh, urdf), kinematics, error_model,
problem, operators, ga, baselines, records, config, build, callbacks, app (see the README)."""

from importlib import metadata

try:
    __version__ = metadata.version("zrp_ga")
except metadata.PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0+unknown"
