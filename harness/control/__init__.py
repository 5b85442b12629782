"""The control benchmark (``spq bench control``): what each bounding volume does to the commands of a
collision-avoiding differential-IK controller.

- :mod:`harness.control.controller`: the QP at a fixed step (hand targets, damped joint limits, joint
  velocity limits, one velocity-damper row per pair closer than d_i), fed by a distance source.
- :mod:`harness.control.tasks`: seeded tasks that drive bodies near each other, per robot.
- :mod:`harness.control.metrics`: per run, the smallest distance on a common geometry, how far the
  active rows turn, the commands' jumps by cause, time per step.
- :mod:`harness.control.peers`: pink's SelfCollisionBarrier and mink's CollisionAvoidanceLimit in their
  own solvers, and the same damper QP fed by pinocchio's or MuJoCo's distances.
- :mod:`harness.control.scenes`: one robot read once, one scene per bounding-volume policy.
- :mod:`harness.control.runs`: every task of every robot with every method, and the runs' summary
  (the suite's entry, its config and tables, is :mod:`harness.suites.control`).
- :mod:`harness.control.speed`: what a control step costs, side by side in one process.
"""
