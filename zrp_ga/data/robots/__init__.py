"""Preset robots as DH table files (format: zrp_ga.robot_files); read them with zrp_ga.robots.get."""
