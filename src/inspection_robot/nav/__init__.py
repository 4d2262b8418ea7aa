"""Navigation: map, costmap with virtual obstacles, global planner, path follower, localization checks."""
