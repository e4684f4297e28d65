"""Simulation helpers of the tests and benchmarks (not part of the package).

:mod:`simlib.sessions` records whole sessions and guided moves as people record them;
:mod:`simlib.noisy_fits` fits seeded logs of the paper balancer under (coloured) noise;
:mod:`simlib.reference` integrates a model with ``scipy.integrate.solve_ivp``, the
reference the compiled kernel is checked against. The tests import them as ``simlib``
(pytest puts ``tests/`` on the path); the benchmarks add ``tests/`` to the path first.
"""
