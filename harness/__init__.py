"""harness: measures spq against exact references and external engines.

Submodules (imported on demand, so that ``import harness`` stays cheap):

- :mod:`harness.references.minkowski`: exact distance / penetration depth of two convex polytopes through the
  convex hull of their Minkowski difference (independent of any GJK).
- :mod:`harness.workloads.poses`: seeded pose suites, uniform rotations, distance-controlled buckets.
- :mod:`harness.engines`: adapters for the external engines (python-fcl, coal, pybullet, MuJoCo).

``harness`` may import ``spq`` and ``datasets``; ``spq`` never imports ``harness``.
"""
