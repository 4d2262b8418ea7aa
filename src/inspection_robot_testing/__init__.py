"""The test harness: what tests, benchmarks, the soak and the demos drive the robot with, never shipped.

The chaos soak (soak.py its command line, soak_invariants.py its pure checkers, ros/soak.py its ROS
side), the inspection fixtures (fixtures.py), the simulated yard's patrol client (yard_patrol.py), the
raw websocket test clients (bridge_client.py) and the fake ISAPI camera the real camera and thermal
drivers are tested against (fake_isapi.py). setup.py does not name this package, so
`catkin_make install` leaves it out; the devel space finds it through a path shim that CMakeLists.txt
writes there (only there). The robot's package never imports from here.
"""
