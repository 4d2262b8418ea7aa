"""Robot arm: driver interface, trajectory files and the robot_arm command logic."""
