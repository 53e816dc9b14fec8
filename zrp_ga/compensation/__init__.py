"""A calibration used: a robot program corrected with the calibrated model
(:func:`zrp_ga.compensation.compensate.compensate`, ``zrp_ga.compensate``; the command
``zrp-ga-compensate``, :mod:`zrp_ga.cli.compensate`).

One module a concept: :mod:`~zrp_ga.compensation.arms` (the calibrated and nominal arms of a
calibration), :mod:`~zrp_ga.compensation.program` (programs and work-object files read and
checked), :mod:`~zrp_ga.compensation.orientation` (orientation conventions and their column
names), :mod:`~zrp_ga.compensation.frames` (work objects, the base frame by convention, circles),
:mod:`~zrp_ga.compensation.setups` (base, tool and work-object setups applied, and what the data
leave open), :mod:`~zrp_ga.compensation.ik` (inverse kinematics),
:mod:`~zrp_ga.compensation.configuration` (branch numbers), :mod:`~zrp_ga.compensation.size`
(memory and time before the work), :mod:`~zrp_ga.compensation.result` and
:mod:`~zrp_ga.compensation.writing` (the compensated program and its files).
"""
