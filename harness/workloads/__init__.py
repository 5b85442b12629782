"""Workloads: what is measured on. Seeded pose suites, robot configurations and trajectories, robot
scene files (TOML) and the runs of a scene over many configurations."""
