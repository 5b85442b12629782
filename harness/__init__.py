"""harness: measures spq against exact references and external engines, laid out by role.

- :mod:`harness.engines`: one adapter per external engine (python-fcl, coal, pybullet, MuJoCo, and
  pinocchio as the robot-scene peer), behind one interface, and the isolation of native ones.
- :mod:`harness.references`: what judges: the exact Minkowski-difference reference for polytopes
  (minkowski.py), the independent depth and STP-BV oracles, pybullet's forward kinematics.
- :mod:`harness.workloads`: what is measured on: pose suites, robot configurations, scene files and
  their runs.
- :mod:`harness.suites`: one entry per command (``run(Config) -> Output``); a command whose
  computation spans modules is a package, its entry in ``__init__.py`` and its computation beside it.
- :mod:`harness.parallel`: a suite's tasks on local processes or a Dask cluster.
- :mod:`harness.report`: rendering (tables, charts, pictures, the HTML page), ``spq report`` and ``spq view``.
- :mod:`harness.cli`: the ``spq`` command, a thin table over the suites.

Submodules are imported on demand, so that ``import harness`` stays cheap. No two modules share a
name (tests/test_layout.py). Imports run one way: ``harness`` → ``datasets`` → ``spq``; ``spq`` and
``datasets`` never import ``harness``.
"""
