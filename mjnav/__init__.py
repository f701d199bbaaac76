"""mjnav: MuJoCo crowd-navigation scenarios and learning-based convex MPC."""

__version__ = "0.1.0"
