"""The ROS wing: every module besides the nodes themselves that imports rospy, actionlib, genpy,
diagnostic_updater or message packages (the bridge's ROS backend and message classes, the device
command twin, the request worker, diagnostics, the inspection head's service clients, the
simulators' ROS inputs). Pure logic elsewhere in the package never imports from here.
"""
