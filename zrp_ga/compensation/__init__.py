"""A calibration used: a robot program corrected with the calibrated model
(:func:`zrp_ga.compensation.compensate.compensate`, ``zrp_ga.compensate``; the command
``zrp-ga-compensate``, :mod:`zrp_ga.cli.compensate`)."""
