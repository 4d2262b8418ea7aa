"""On-board software of the substation inspection robot (ROS 1 package ``inspection_robot``)."""
