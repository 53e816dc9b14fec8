"""The ZRP model, from the bottom up (each module imports only those before it; the contract in
``pyproject.toml``): :mod:`~zrp_ga.model.so3` (rotations, Rodrigues' formula),
:mod:`~zrp_ga.model.robot` (the arm's description), :mod:`~zrp_ga.model.kinematics` and its
compiled kernels (:mod:`~zrp_ga.model._kernels`, imported when first compiled; their numpy
twins :mod:`~zrp_ga.model._numpy_kernels`), :mod:`~zrp_ga.model.dh` (DH and modified DH
tables both ways), :mod:`~zrp_ga.model.layout` (genome <-> model),
:mod:`~zrp_ga.model.error_model` (the error Jacobian, identifiability),
:mod:`~zrp_ga.model.registration` (the instrument's frame), :mod:`~zrp_ga.model.observability`
(indices of pose sets), :mod:`~zrp_ga.model.simulation` (simulated measurements),
:mod:`~zrp_ga.model.metrics` (validation errors) and :mod:`~zrp_ga.model.cost` (the vectorised
cost of a population)."""
