"""ROS wiring: one module per node, each with a ``main()``. Only this package imports rospy."""
