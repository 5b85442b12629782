"""References: what judges the engines. The exact Minkowski-difference reference for polytopes, the
independent depth and STP-BV oracles, and pybullet's forward kinematics."""
