"""The harness's ROS wing: its modules that import rospy or message packages (the soak's ROS side)."""
