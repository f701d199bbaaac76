"""Perception from the robot's own sensors (no simulator ground truth): the LiDAR pedestrian tracker."""

from mjnav.perception.tracker import Track, Tracker, TrackerConfig, TracksConfig, nearest_tracks

__all__ = ["Track", "Tracker", "TrackerConfig", "TracksConfig", "nearest_tracks"]
